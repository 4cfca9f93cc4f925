"""The audit's detection limits: the weakest magnitude of each hidden effect the audit names.

For each of the seven effects, a geometric ladder of magnitudes (weak to strong) is hidden in
30 s paper-var records at noise "none" and "realistic", two seeds each (seed 0 at severity 0.1,
seed 1 at severity 0.5). The audit runs without the free run (the named cause does not depend
on it). The detection limit is the weakest step named right in both seeds, with every stronger
step named right too. "What it does" is the largest relative change of an identified nominal
parameter at the limit step (nominal fit of the noise-free record with the effect vs the same
record without it, mean of the two seeds; C_ep left out, its true value is 0), and the change
of f_c in N (its true value, 7 N, makes a percentage meaningless).

Last, one full audit (with free run) of a 60 s paper-var record at realistic noise with a
1000 N load offset is timed (after a warm-up audit so numba's compilation is not counted).

Run: python benchmarks/audit_sweep.py
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import time

import numpy as np

from monitor.audit import AuditOptions, audit
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.params import Effects
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

DURATION = 30.0  # [s]
PROFILE = "paper-var"
SEEDS = ((0, 0.1), (1, 0.5))  # (seed, severity)
NOISES = ("none", "realistic")

# effect name -> (unit shown, ladder weak -> strong, Effects kwargs from a ladder value)
# valve_saturation's magnitude is the fraction of samples the stop cuts: x_max is the (1 - f)
# quantile of |x5| of the same record without a stop, so it means the same at both severities
# (a stop below the peak of |x5| but above its rare spikes changes almost nothing). A sensor
# delay below one sample cannot be made; its ladder starts at the smallest there is.
LADDERS = {
    "stribeck_friction": ("N (v_s = 10 mm/s)", (20.0, 40.0, 80.0, 160.0, 320.0, 640.0),
                          lambda v, x5: dict(stribeck_F_s=v, stribeck_v_s=0.01)),
    "valve_saturation": ("fraction of samples cut", (0.0025, 0.005, 0.01, 0.02, 0.04, 0.08),
                         lambda v, x5: dict(x_max=float(np.quantile(x5, 1.0 - v)))),
    "valve_dead_band": ("um", (0.3, 0.6, 1.25, 2.5, 5.0, 10.0, 20.0),
                        lambda v, x5: dict(dead_band=v * 1e-6)),
    "supply_pressure_sag": ("Pa/(m^3/s)", (6.25e7, 1.25e8, 2.5e8, 5e8, 1e9, 2e9, 4e9),
                            lambda v, x5: dict(supply_sag=v)),
    "entrained_air": ("volume fraction", (0.00125, 0.0025, 0.005, 0.01, 0.02, 0.04, 0.08),
                      lambda v, x5: dict(air_fraction=v)),
    "sensor_delay": ("samples (recording only)", (1, 2, 3, 5),
                     lambda v, x5: dict(sensor_delay=int(v), sensor_delay_in_loop=False)),
    "load_offset": ("N", (50.0, 100.0, 200.0, 400.0, 800.0, 1600.0),
                    lambda v, x5: dict(load_offset=v)),
}
SKIP_PARAMS = ("C_ep", "f_c")  # C_ep: true value 0; f_c (7 N) is shown in N instead


def _record(seed, severity, noise, effects=None, duration=DURATION):
    return simulate(parse_profile(PROFILE), duration, params=degrade(severity), effects=effects or Effects(),
                    noise=noise_model(noise), seed=seed)


def _param_change(p, p0):
    """Relative change per identified parameter [-] (SKIP_PARAMS left out); f_c's change [N]."""
    rel = {k: (p[k] - p0[k]) / abs(p0[k]) for k in p0 if k not in SKIP_PARAMS and p0[k] != 0}
    return rel, p["f_c"] - p0["f_c"]


def _fmt(v):
    return f"{v:g}"


def sweep():
    opt = AuditOptions(free_run=False)
    clean, x5 = {}, {}
    for seed, sev in SEEDS:
        run = _record(seed, sev, "none")
        clean[seed] = audit(run.samples, run.config, opt).params_nominal
        x5[seed] = np.abs(run.states[:, 4])  # true spool travel [m]
    rows, detail = [], []
    for name, (unit, ladder, kw) in LADDERS.items():
        hits = {}  # (noise, step) -> [bool per seed]
        change = {}  # step -> ({param: mean relative change}, mean f_c change [N])
        for i, v in enumerate(ladder):
            per_seed = []
            for noise in NOISES:
                causes = []
                for seed, sev in SEEDS:
                    run = _record(seed, sev, noise, Effects(**kw(v, x5[seed])))
                    res = audit(run.samples, run.config, opt)
                    causes.append(res.cause)
                    if noise == "none":
                        per_seed.append(_param_change(res.params_nominal, clean[seed]))
                hits[noise, i] = [c == name for c in causes]
                detail.append((name, _fmt(v), noise, ", ".join(causes)))
            change[i] = ({k: float(np.mean([d[k] for d, _ in per_seed])) for k in per_seed[0][0]},
                         float(np.mean([f for _, f in per_seed])))
        limits = {}
        for noise in NOISES:
            lim = None
            for i in reversed(range(len(ladder))):
                if all(hits[noise, i]):
                    lim = i
                else:
                    break
            limits[noise] = lim
        cells = []
        for noise in NOISES:
            i = limits[noise]
            cells.append(f"> {_fmt(ladder[-1])} (not reached)" if i is None
                         else (f"<= {_fmt(ladder[0])}" if i == 0 else _fmt(ladder[i])))
        does = []
        for noise in NOISES:
            i = limits[noise]
            if i is None:
                does.append("-")
                continue
            rel, dfc = change[i]
            k = max(rel, key=lambda k: abs(rel[k]))
            does.append(f"{k} {100 * rel[k]:+.1f} %, f_c {round(dfc) or 0:+d} N")
        rows.append((name, unit, *cells, " / ".join(does)))
    return rows, detail


def time_60s():
    opt = AuditOptions()
    warm = _record(2, 0.3, "realistic", Effects(load_offset=1000.0), duration=10.0)
    audit(warm.samples, warm.config, opt)
    run = _record(3, 0.3, "realistic", Effects(load_offset=1000.0), duration=60.0)
    t0 = time.perf_counter()
    res = audit(run.samples, run.config, opt)
    return time.perf_counter() - t0, res.cause


def main():
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    t0 = time.perf_counter()
    rows, detail = sweep()
    print(f"Detection limits ({PROFILE}, {DURATION:g} s records, seeds {[s for s, _ in SEEDS]} at severity "
          f"{[v for _, v in SEEDS]}; named right in both seeds at that step and every stronger one):\n")
    print("| effect | unit | weakest named right, noise-free | at realistic noise "
          "| what it does to the nominal fit (noise-free fit; at the noise-free / the realistic limit) |")
    print("|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print("\nEvery step (cause named for seed 0, seed 1):\n")
    print("| effect | magnitude | noise | named |")
    print("|---|---|---|---|")
    for r in detail:
        print("| " + " | ".join(r) + " |")
    sweep_s = time.perf_counter() - t0
    secs, cause = time_60s()
    n = len(detail) * len(SEEDS) + len(SEEDS)
    print(f"\nSweep: {sweep_s:.0f} s wall for {n} audits without free run.")
    print(f"One full audit (free run on, numba already compiled by a warm-up audit) of a 60 s paper-var "
          f"record, realistic noise, load offset 1000 N: {secs:.1f} s wall (cause: {cause}).")


if __name__ == "__main__":
    main()
