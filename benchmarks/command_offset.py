"""What an offset in the logged command ug does to the grade: a healthy rig (severity 0.1,
realistic noise, 30 s) on each input shape, evaluated with ug shifted by each offset. The valve
equation has no null term, so an offset between the command and the position's zero (or a valve
null shift) reads as a change of the valve gain K_sv. Prints K_sv against the same record
without the offset, and the grade.
Run: python benchmarks/command_offset.py [--seed 5]
"""
from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse


from hydromon.contract import RigConfig
from hydromon.engine.evaluate import evaluate
from hydromon.engine.record import Recording
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

PROFILES = ("paper-id", "paper-var", "steps", "multisine")
OFFSETS = (0.0, 0.05, 0.1, 0.3, 1.0)  # [V]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args()
    cfg = RigConfig()
    print(f"{'profile':10s} " + " ".join(f"{f'ug {o:+g} V':>24s}" for o in OFFSETS))
    for profile in PROFILES:
        run = simulate(parse_profile(profile), 30.0, params=degrade(0.1), noise=noise_model("realistic", cfg),
                       seed=a.seed)
        cells, k0 = [], None
        for off in OFFSETS:
            s = run.samples.copy()
            s[:, 0] += off
            ev = evaluate(Recording("r", run.t, s, cfg, profile))
            k = ev.assessment.params["K_sv"]
            k0 = k if k0 is None else k0
            cells.append(f"K_sv {100 * (k / k0 - 1):+5.0f} % {ev.assessment.grade:>12s}")
        print(f"{profile:10s} " + " ".join(f"{c:>24s}" for c in cells), flush=True)


if __name__ == "__main__":
    main()
