"""False alarms of the plausibility check (monitor.plausibility) on right input: every evaluation
of 60 seeded random rigs in SI, three noise models, from rest and joined 3 s into the run, 20 s
each, four profiles. Prints any implausible evaluation and the count.
Run: python benchmarks/plausibility_scan.py
"""
from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse

import numpy as np

from monitor.pipeline import Fleet
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from hydromon.contract import RigConfig
from plant_sim.profiles import Chirp, Multisine, PaperIdentification, PaperVariable
from plant_sim.simulate import simulate_fleet


def main() -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    rng = np.random.default_rng(11)
    n = 60
    sev = rng.uniform(0, 1, n)
    profiles = [PaperVariable(), Multisine(), Chirp(), PaperIdentification()]
    tot = bad = 0
    for noise in ("none", "realistic", "stress"):
        for start in (0, 300):
            params = [degrade(s) for s in sev]
            runs = simulate_fleet(RigConfig(), params, [profiles[i % 4] for i in range(n)], 20.0 + start * 0.01,
                                  noise=noise_model(noise), seeds=list(range(100, 100 + n)))
            fleet = Fleet()
            for i in range(n):
                fleet.add_rig(f"r{i}")
            for i, run in enumerate(runs):
                ev = fleet.update(np.full(len(run.samples) - start, i), run.samples[start:])
                tot += int(ev.converged.sum()); b = int(ev.implausible.sum()); bad += b
                if b:
                    a = ev.assessment(int(np.flatnonzero(ev.implausible)[0]), fleet.graded)
                    print(noise, start, i, round(sev[i], 3), b, a.implausible, {k: (a.params[k], a.std_errors[k]) for k in a.implausible})
    print("converged evaluations", tot, "implausible", bad)


if __name__ == "__main__":
    main()
