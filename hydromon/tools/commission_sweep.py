"""The commissioning sweep: rigs that are not the reference rig, commissioned from a healthy
record each, then graded at every grade.

Each rig (``plant_sim.rigs.random_rig``, seeded) runs one of four input profiles (the method's
identification sine, its variable-condition input, steps, a multisine) at one noise model; it is
commissioned from a healthy record (``monitor.commission``), then five records of it degraded to
the middle of each grade's band (``plant_sim.degradation.degrade_relative``) are graded with the
commissioned ranges. Every seed is fixed by the sweep's seed, so the table is reproducible.

``python -m hydromon.tools.commission_sweep [--rigs 20] [--noise realistic stress] [--json]``
prints the table of right grades by profile and noise.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from hydromon.contract import GRADES

__all__ = ["PROFILES", "SEVERITIES", "Outcome", "sweep_rig", "sweep", "main"]

PROFILES = ("paper-id", "paper-var", "steps", "multisine")
SEVERITIES = (0.1, 0.3, 0.5, 0.7, 0.9)  # the middle of each grade's band


@dataclass(frozen=True)
class Outcome:
    """One graded record: rig index, profile, noise, true and graded grade, its confidence and
    status, the parameters left ungraded at commissioning, commissioning wall time [s]."""

    rig: int
    profile: str
    noise: str
    truth: str
    grade: str
    confidence: float
    ungraded: tuple
    commission_s: float

    @property
    def right(self) -> bool:
        return self.grade == self.truth


def sweep_rig(i: int, noise: str, seed: int = 2026, seconds: float = 30.0, runs: int = 60,
              profiles=PROFILES) -> list[Outcome]:
    """Commission rig ``i`` of the sweep's seed at ``noise`` and grade it at the five grades."""
    from monitor.commission import commission
    from monitor.pipeline import Pipeline
    from plant_sim.degradation import degrade_relative
    from plant_sim.noise import noise_model
    from plant_sim.profiles import parse_profile
    from plant_sim.rigs import random_rig
    from plant_sim.simulate import simulate

    config, healthy = random_rig(np.random.default_rng([seed, i]))
    profile = profiles[i % len(profiles)]
    prof, nm = parse_profile(profile), noise_model(noise, config)
    rec = simulate(prof, seconds, params=healthy, config=config, noise=nm, seed=seed * 1000 + 10 * i)
    t0 = time.perf_counter()
    c = commission(rec.samples, config, runs=runs, seed=seed * 1000 + 10 * i + 5)
    took = time.perf_counter() - t0
    out = []
    for g, s in enumerate(SEVERITIES):
        plant = degrade_relative(s, healthy, config)
        r = simulate(prof, seconds, params=plant, config=config, noise=nm, seed=seed * 1000 + 10 * i + g + 1)
        _, a = Pipeline(config=config, ranges=c.ranges).run(r.samples)
        out.append(Outcome(i, profile, noise, GRADES[g], a.grade, float(a.confidence), tuple(sorted(c.ungraded)),
                           took))
    return out


def sweep(n_rigs: int = 20, noises=("realistic", "stress"), seed: int = 2026, seconds: float = 30.0,
          runs: int = 60, progress=None) -> list[Outcome]:
    """Every rig at every noise model (:func:`sweep_rig`)."""
    out = []
    for noise in noises:
        for i in range(n_rigs):
            out += sweep_rig(i, noise, seed, seconds, runs)
            if progress is not None:
                progress(out[-1])
    return out


def table(outcomes: list[Outcome]) -> str:
    """Right grades by profile and noise, and in all."""
    noises = sorted({o.noise for o in outcomes})
    lines = ["| profile | " + " | ".join(noises) + " |", "|---|" + "---|" * len(noises)]
    for p in PROFILES:
        cells = []
        for n in noises:
            sel = [o for o in outcomes if o.profile == p and o.noise == n]
            cells.append(f"{sum(o.right for o in sel)} / {len(sel)}" if sel else "-")
        lines.append(f"| {p} | " + " | ".join(cells) + " |")
    cells = []
    for n in noises:
        sel = [o for o in outcomes if o.noise == n]
        cells.append(f"{sum(o.right for o in sel)} / {len(sel)}")
    lines.append("| all | " + " | ".join(cells) + " |")
    right = sum(o.right for o in outcomes)
    lines.append(f"\n{right} of {len(outcomes)} records graded right ({100 * right / len(outcomes):.1f} %)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from hydromon.tools import jitcache

    jitcache.configure()
    ap = argparse.ArgumentParser(prog="python -m hydromon.tools.commission_sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--rigs", type=int, default=20)
    ap.add_argument("--noise", nargs="+", default=["realistic", "stress"])
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--runs", type=int, default=60, help="twin runs per commissioning")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    def progress(o: Outcome) -> None:
        print(f"rig {o.rig:2d} {o.profile:9s} {o.noise:9s} commissioned in {o.commission_s:.1f} s", file=sys.stderr)

    outcomes = sweep(args.rigs, args.noise, args.seed, args.seconds, args.runs, progress)
    if args.json:
        print(json.dumps([asdict(o) for o in outcomes]))
    else:
        print(table(outcomes))
        for o in outcomes:
            if not o.right:
                print(f"  rig {o.rig} {o.profile} {o.noise}: {o.truth} graded {o.grade} ({o.confidence:.2f}); "
                      f"ungraded {', '.join(o.ungraded) or '-'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
