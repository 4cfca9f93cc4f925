"""The valve-grading table of docs/method.md: seeded random rigs graded under three choices of ranges.

60 random rigs per noise model (none, realistic, stress; severity uniform, the seeds of
tests/monitor/test_grading_random_rigs.py), the variable-condition, multisine and chirp profiles,
10 s each, the monitor starting with the run or 3 s into it. Prints right grades out of 180
for Table 3 as printed (the valve on K_sv omega^2), both valve parameters, and the default
(the valve on its static gain K_sv), and how often each valve parameter's truth lies outside
its +-3 SE. Run: python benchmarks/valve_grading.py
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse

import numpy as np

from monitor.grading import Ranges, grade_of_values
from monitor.pipeline import Fleet
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from hydromon.contract import RigConfig
from plant_sim.profiles import Chirp, Multisine, PaperVariable
from plant_sim.simulate import simulate_fleet

N = 60


def choices() -> dict[str, Ranges]:
    paper, default = Ranges.paper(), Ranges.default()
    both = Ranges(params={**paper.params, "K_sv": default.params["K_sv"]}, source="both")
    return {"Table 3 as printed": paper, "both": both, "K_sv (default)": default}


def main() -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    severity = np.random.default_rng(7).uniform(0, 1, N)
    profiles = [PaperVariable(), Multisine(), Chirp()]
    for start in (0, 300):
        right = dict.fromkeys(choices(), 0)
        outside = {"K_sv_omega_sv2": {}, "K_sv": {}}
        for noise in ("none", "realistic", "stress"):
            params = [degrade(s) for s in severity]
            runs = simulate_fleet(RigConfig(), params, [profiles[i % 3] for i in range(N)],
                                  10.0 + start * RigConfig().h, noise=noise_model(noise), seeds=list(range(N)))
            for name, ranges in choices().items():
                fleet = Fleet(ranges=ranges)
                for i in range(N):
                    fleet.add_rig(f"r{i}")
                for i, r in enumerate(runs):
                    fleet.update(np.full(len(r.samples) - start, i), r.samples[start:])
                for i, r in enumerate(runs):
                    right[name] += fleet.estimate(i).level == grade_of_values(r.params.identified())
                if name == "both":
                    for k in outside:
                        est = [fleet.estimate(i) for i in range(N)]
                        outside[k][noise] = sum(abs(a.params[k] - r.params.identified()[k]) > 3 * a.std_errors[k]
                                                for a, r in zip(est, runs))
        when = "with the run" if start == 0 else f"{start * RigConfig().h:g} s into the run"
        print(f"monitor starts {when}: right grades of {3 * N}: "
              + ", ".join(f"{k} {v}" for k, v in right.items()))
        for k, v in outside.items():
            print(f"  {k}: truth outside +-3 SE in " + ", ".join(f"{n} {c}/{N}" for n, c in v.items()))


if __name__ == "__main__":
    main()
