"""The audit's sweep: every effect on every input profile, health band and noise level.

``python -m hydromon.tools.audit_sweep [--seeds tune|heldout] [--seed-base N] [--jobs N] [--quick] [--fixed]
[--duration S] [--round SPEC] [--screen] [--only NAME | --ladder NAME | --clean N [--noise LIST] | --pairs N |
--rigs N]``
prints the tables of ``docs/audit.md``. Every record is 20 s (``--duration``) at 100 Hz from ``plant_sim``; its seed is
``BASE[seeds] + its index`` in the fixed list (``hydromon.tools.audit_cases``; the ``tune`` seeds were used to set the
audit's thresholds, the ``heldout`` seeds were fixed before any result on them was seen). The seed
draws the record's noise and also its own input and health (``_drawn``): the profile's parameters
around their defaults (the sine's offset, amplitude and frequency; the variable input's period; the
steps' levels and period; the multisine's offset, amplitude and frequency scale) and the severity
within its band. A noise-free record on a default input is the same for every seed, so without the
draw a base held out would hold out only the noise; ``--fixed`` keeps every record on its profile's
defaults at its band's centre.

* one effect: each of the seven effects on each of the four profiles (the paper's sine
  ``paper-id``, its variable-condition input ``paper-var``, ``steps``, ``multisine``) at
  noise ``none`` and ``realistic``, at the claimed detection limit (``CLAIMS``), four times it,
  and a magnitude large enough to spoil the nominal fit (``CLAIMS``' third entry); the health band (severity
  0.1, 0.3, 0.5, 0.7, 0.9) cycles with the record's index;
* clean: each profile x band x noise ``none``, ``realistic``, ``stress``;
* two effects at once (``PAIRS``), realistic noise, each profile;
* an effect outside the library, realistic noise, each profile: a PI position loop the rig
  constants do not describe (the valve equation fails), a 3 % gain error of the cap-side
  pressure sensor (the force equation fails), and a piston seal friction loaded by the
  differential pressure, c_p |p1 - p2| sign(v) with c_p = 1e-4 m^2 (``Effects.seal_friction``:
  the force equation fails). The right answer is ``unexplained``.

``--round x1=1e-6,x5=5e-7,p=400,ug=1e-3`` writes every record's channels in whole steps of that size (SI; ``p`` is
both pressures) before the audit sees them, as a logger of that resolution would.

``--screen`` audits nothing: it prints how far the chosen records stand from the audit's refusals of a
glitch, of readings in other units and of a rig held at one command (``monitor.audit.auditable``): the
largest excursion ratio of each measured channel, the largest reading over its sensor's span and the
smallest pressures over p_s, and the smallest command of each part, each with its record, and the
records the outlier gate mends first.

A record counts as right when the audit names exactly its effect ("none" for clean records;
both effects, in any order, for a pair). The last line times one full audit of a 60 s record
with a load offset and of a clean one.

``--ladder NAME`` sweeps one effect instead, to find where it is detected on each input: 1, 2,
4 and 8 times its claimed limit at each noise level, on every profile, each at the five bands'
severities (160 records; seed ``BASE + 10000 + its index`` in that list). ``--clean N`` audits N
clean records for each profile, band and noise level ``none``, ``realistic``, ``stress`` (seed
``BASE + 20000 + its index``): how often a record without an effect is named one; ``--noise``
sets its noise levels (e.g. ``pct:0.01,pct:0.02``: 1e-4 and 2e-4 of each sensor's span, between
``realistic`` and ``stress``). ``--pairs N`` audits N records of each two-effect pair (``PAIRS``)
for each profile and band at realistic noise (seed ``BASE + 30000 + its index``): the main list
holds only one record of each pair and profile, each at one band. ``--rigs N`` audits, at each
noise level, N clean records and N of each effect at ``RIG_MULTIPLE`` (4) times its claimed limit
per profile and band, each on a rig of its own (seed ``BASE + 40000 + its index``): the rig's
constants and healthy plant drawn by ``plant_sim.rigs.random_rig`` (piston area 0.4-2.5 times the
reference's, supply 8-21 MPa, mass, stiffness, valve and friction each by its own factor) and
degraded from there, the effect's magnitude scaled to the rig (``audit_cases._scaled``).
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from .audit_cases import (BANDS, BASE, CLAIMS, CLEAN_NOISES, CLEAN_SEED, DURATION, LADDER, LADDER_SEED,  # noqa: F401
                          NOISES, OUTSIDE, PAIR_SEED, PAIRS, PROFILES, RIG_MULTIPLE, RIG_SEED, SEAL, SEV_JITTER,
                          STEPS, _cases, _clean_cases, _drawn, _ladder_cases, _pair_cases, _record, _rig_cases,
                          _truth)
from .audit_tables import _print_clean, _print_ladder, _print_pairs, _print_rigs, _print_tables


_COLUMNS = {"ug": (0,), "x1": (1,), "p": (2, 3), "x5": (4,)}  # --round's names -> sample columns


def _parse_round(spec: str) -> dict:
    """``--round``'s ``name=step,...`` (names ug, x1, p, x5; steps in SI, > 0) -> {name: step}."""
    steps = {}
    for item in filter(None, (p.strip() for p in spec.split(","))):
        name, _, value = item.partition("=")
        if name not in _COLUMNS:
            raise ValueError(f"{item!r}: round ug, x1, p (both pressures) or x5")
        try:
            steps[name] = float(value)
        except ValueError:
            raise ValueError(f"{item!r}: the step must be a number (SI units)") from None
        if not steps[name] > 0 or steps[name] == float("inf"):
            raise ValueError(f"{item!r}: the step must be finite and > 0")
    return steps


def _rounded(s, steps: dict):
    """The samples with each named channel written in whole ``steps`` (a logger's resolution)."""
    if not steps:
        return s
    s = s.copy()
    for name, q in steps.items():
        for k in _COLUMNS[name]:
            s[:, k] = np.round(s[:, k] / q) * q
    return s


def _sample(args):
    """One task's record as the audit gets it (drawn, simulated, rounded): (samples, config, drawn)."""
    i, case, seed, fixed, duration, steps = args
    kind, effects, profile, severity, noise, step = case
    if not fixed:
        profile, severity = _drawn(profile, severity, seed)
    s, cfg = _record(kind, effects, profile, severity, noise, seed, duration)
    return _rounded(s, steps), cfg, f"{profile} severity {severity}"


def _audit_one(args):
    from monitor.audit import AuditOptions, audit

    i, (kind, effects, *_) = args[:2]
    s, cfg, drawn = _sample(args)
    if kind == "rig":
        drawn += f" on a rig of A1 {cfg.A1 * 1e4:.0f} cm^2, p_s {cfg.p_s / 1e6:.1f} MPa"
    try:
        res = audit(s, cfg, AuditOptions(free_run=False))
    except ValueError as e:  # a record the audit refuses (as the CLI would, exit 2) is a wrong answer
        return i, ["refused"], _truth(kind, effects), str(e), drawn
    named = sorted(res.causes) if res.causes else [res.cause]
    return i, named, _truth(kind, effects), res.note, drawn


def _screen_one(args):
    from monitor.audit.auditable import excitation_ratios, glitch_span, largest_excursion
    from monitor.readings import range_ratios, unit_slip
    from monitor.outlier_gate import gated
    from monitor.audit.result import AuditOptions

    s, cfg, drawn = _sample(args)
    s, mended = gated(s)  # as the audit sees it: lone glitches mended
    excursions = [largest_excursion(s[:, k], glitch_span(cfg.h)) for k in range(1, 5)]
    split = int(AuditOptions().train_fraction * len(s))
    return (args[0], [None if g is None else g[3] for g in excursions], excitation_ratios(s, cfg.K_f, split), drawn,
            int(mended.sum()), range_ratios(s, cfg), unit_slip(s, cfg) is not None)


def _print_screen(cases, screened, wall):
    """The largest excursion ratio per channel, the readings farthest toward a unit slip and the
    smallest command per part over ``screened`` (index -> (excursions, excitation ratios per part,
    drawn, samples the outlier gate mended, range ratios, refused as in other units)), each with its
    record, and the records the gate mended."""
    from monitor.audit.auditable import EXCITATION, GLITCH, STILL, held
    from monitor.readings import PRESSURE_LOW, PRESSURE_NEGATIVE, RANGE

    def rec(i):
        kind, effects, _, _, noise, _ = cases[i]
        return f"record {i} ({kind} {effects or ''} {screened[i][2]}, noise {noise})".replace("  ", " ")

    print(f"{len(screened)} records screened in {wall:.0f} s (nothing audited)")
    for k, name in enumerate(("x1", "x3", "x4", "x5")):
        measured = [j for j in screened if screened[j][0][k] is not None]
        if not measured:  # no large step of the channel is met by an opposite one within a glitch's span
            print(f"  {name}: no excursion in any record (refused above {GLITCH:g})")
            continue
        i = max(measured, key=lambda j: screened[j][0][k])
        print(f"  {name}: largest excursion {screened[i][0][k]:.1f} times its 99th-percentile step (refused above "
              f"{GLITCH:g}): {rec(i)}")
    ranges = {i: v[4] for i, v in screened.items()}
    for key, what in (("x1", "x1 peaks at {:.2f} times x1_span"), ("x5", "x5 peaks at {:.2f} times x5_span"),
                      ("p", "the pressures peak at {:.2f} times p_span")):
        i = max(ranges, key=lambda j: ranges[j][key])
        print(f"  {what.format(ranges[i][key])} (refused above {RANGE:g}): {rec(i)}")
    i = min(ranges, key=lambda j: ranges[j]["p_peak"])
    print(f"  the lower pressure peaks at {ranges[i]['p_peak']:.2f} times p_s at least (refused below "
          f"{PRESSURE_LOW:g}): {rec(i)}")
    i = min(ranges, key=lambda j: ranges[j]["p_low"])
    print(f"  the lowest pressure reading is {ranges[i]['p_low']:.3f} times p_s (refused below "
          f"-{PRESSURE_NEGATIVE:g}): {rec(i)}")
    for k, part in enumerate(("fitting", "held-out")):
        i = min(screened, key=lambda j: screened[j][1][k][0])
        asked, moved = screened[i][1][k]
        print(f"  {part} part: smallest command {asked:.1f} times the position noise, x1 moving {moved:.1f} times it "
              f"(held, so refused, at a command of at most {STILL:g}, or of at most {EXCITATION:g} with x1 at most "
              f"{EXCITATION:g}): {rec(i)}")
    mended = [i for i in sorted(screened) if screened[i][3]]
    print(f"  mended by the outlier gate first: {sum(screened[i][3] for i in mended)} sample(s) in {len(mended)} "
          f"record(s)" + "".join(f"; {rec(i)}" for i in mended[:5]) + ("; ..." if len(mended) > 5 else ""))
    refused = sum(max((e for e in g if e is not None), default=0.0) > GLITCH or any(held(r) for r in c) or slip
                  for g, c, _, _, _, slip in screened.values())
    print(f"  refused: {refused} of {len(screened)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", choices=tuple(BASE), default="heldout")
    ap.add_argument("--seed-base", type=int, default=None,
                    help="a record's seed is this plus its index (default: the --seeds set's base); choose "
                         "a fresh one before looking to prove on records nothing was tuned on")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--quick", action="store_true", help="every 7th record only (a smoke run)")
    ap.add_argument("--verbose", action="store_true", help="print every record as it is audited")
    ap.add_argument("--only", default=None,
                    help="only the records of this effect, or of this kind (clean, pair, outside)")
    ap.add_argument("--ladder", default=None, choices=tuple(CLAIMS),
                    help="sweep this effect at 1, 2, 4 and 8 times its claimed limit on every profile and band")
    ap.add_argument("--clean", type=int, default=None, metavar="N",
                    help="audit N clean records per profile, band and noise level instead")
    ap.add_argument("--pairs", type=int, default=None, metavar="N",
                    help="audit N records of each two-effect pair per profile and band instead")
    ap.add_argument("--rigs", type=int, default=None, metavar="N",
                    help=f"audit N records of each effect (at {RIG_MULTIPLE} times its claimed limit, scaled to the "
                         "rig) and N clean ones per profile, band and noise level, each on a rig of its own, instead")
    ap.add_argument("--noise", default=",".join(CLEAN_NOISES), metavar="LIST",
                    help="with --clean: comma-separated noise models (none, realistic, stress, or pct:F, F %% of "
                         f"each sensor's span; default {','.join(CLEAN_NOISES)})")
    ap.add_argument("--fixed", action="store_true",
                    help="every record on its profile's default parameters at its band's centre (no draw)")
    ap.add_argument("--screen", action="store_true",
                    help="audit nothing: print how far the records stand from the refusals of a glitch, of readings "
                         "in other units and of a rig held at one command")
    ap.add_argument("--round", default="", metavar="SPEC",
                    help="write each record's channels in whole steps first, as a logger of that resolution would: "
                         "e.g. x1=1e-6,x5=5e-7,p=400,ug=1e-3 (SI; p is both pressures)")
    ap.add_argument("--duration", type=float, default=DURATION, metavar="S",
                    help=f"each record's length [s] (default {DURATION:g}; at least 5)")
    args = ap.parse_args(argv)
    if args.clean is not None and (args.clean < 1 or args.ladder):
        ap.error("--clean takes N >= 1, and not with --ladder")
    if args.pairs is not None and (args.pairs < 1 or args.ladder or args.clean):
        ap.error("--pairs takes N >= 1, and not with --ladder or --clean")
    if args.rigs is not None and (args.rigs < 1 or args.ladder or args.clean or args.pairs):
        ap.error("--rigs takes N >= 1, and not with --ladder, --clean or --pairs")
    from plant_sim.noise import noise_model

    noises = tuple(n.strip() for n in args.noise.split(","))
    try:
        for n in noises:
            noise_model(n)
    except ValueError as e:
        ap.error(f"--noise: {e}")
    if args.noise != ap.get_default("noise") and not args.clean:
        ap.error("--noise goes with --clean")
    if not args.duration >= 5.0:  # also refuses nan
        ap.error(f"--duration must be at least 5 s (got {args.duration:g})")
    base = BASE[args.seeds] if args.seed_base is None else args.seed_base
    if args.ladder:
        cases, first, only = _ladder_cases(args.ladder), base + LADDER_SEED, None
    elif args.clean:
        cases, first, only = _clean_cases(args.clean, noises), base + CLEAN_SEED, None
    elif args.pairs:
        cases, first, only = _pair_cases(args.pairs), base + PAIR_SEED, None
    elif args.rigs:
        cases, first, only = _rig_cases(args.rigs), base + RIG_SEED, None
    else:
        cases, first, only = _cases(), base, args.only  # --only selects among the main list's records
    try:
        steps = _parse_round(args.round)
    except ValueError as e:
        ap.error(f"--round: {e}")
    todo = [(i, c, first + i, args.fixed, args.duration, steps) for i, c in enumerate(cases)
            if (not args.quick or i % 7 == 0) and (only is None or only == c[0] or only in c[1])]
    t0 = time.perf_counter()
    results = {}
    pool = ProcessPoolExecutor(args.jobs) if args.jobs > 1 else None
    if args.screen:
        try:
            screened = {i: rest for i, *rest in (pool.map(_screen_one, todo) if pool else map(_screen_one, todo))}
        finally:
            if pool is not None:
                pool.shutdown()
        _print_screen(cases, screened, time.perf_counter() - t0)
        return
    try:
        it = pool.map(_audit_one, todo) if pool else map(_audit_one, todo)
        for i, named, truth, note, drawn in it:
            results[i] = (named, truth, note, drawn)
            if args.verbose:
                kind, effects, profile, severity, noise, step = cases[i]
                mark = "ok " if named == truth else "BAD"
                print(f"{mark} {i:3d} {kind:7s} {effects} {drawn} {noise} {step}: {named}"
                      + ("" if named == truth else f"  ({note[:160]})"), flush=True)
    finally:
        if pool is not None:  # its workers stop before the interpreter does (else a stray OSError at exit)
            pool.shutdown()
    wall = time.perf_counter() - t0
    if args.ladder:
        _print_ladder(args.ladder, cases, results, base, wall, args.duration)
        return
    if args.clean:
        _print_clean(cases, results, base, wall, args.duration, noises)
        return
    if args.pairs:
        _print_pairs(cases, results, base, wall, args.duration)
        return
    if args.rigs:
        _print_rigs(cases, results, base, wall, args.duration)
        return
    _print_tables(cases, results, args.seeds, base, wall, args.duration)
    (secs, cause), (secs_clean, cause_clean) = _time_60s({"load_offset": 1000.0}), _time_60s({})
    print(f"\nOne full audit (free run on, after a warm-up audit) of a 60 s paper-var record, realistic noise, "
          f"load offset 1000 N: {secs:.1f} s wall (cause: {cause}); of a clean one, where the hump's free run "
          f"and the Stribeck reach are computed too: {secs_clean:.1f} s wall (cause: {cause_clean}).")


def _time_60s(effects: dict):
    """Seconds of one full audit of a 60 s paper-var record at realistic noise with ``effects``
    (none: clean), after a warm-up audit; and its cause."""
    from monitor.audit import AuditOptions, audit

    kind = "one" if effects else "clean"
    warm, cfg = _record(kind, effects, "paper-var", 0.3, "realistic", 2, duration=10.0)
    audit(warm, cfg, AuditOptions())
    s, cfg = _record(kind, effects, "paper-var", 0.3, "realistic", 3, duration=60.0)
    t0 = time.perf_counter()
    res = audit(s, cfg, AuditOptions())
    return time.perf_counter() - t0, res.cause


if __name__ == "__main__":
    main()
