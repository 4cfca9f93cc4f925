"""Issue 2 acceptance: seeded random rigs graded as their true parameters grade under Table 3."""

import numpy as np

from monitor.grading import grade_of_values
from monitor.pipeline import Fleet
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.params import RigConfig
from plant_sim.profiles import Chirp, Multisine, PaperVariable
from plant_sim.simulate import simulate_fleet

N_RIGS = 60  # per noise model below: 180 runs


def test_random_rigs_get_the_grade_of_their_true_parameters():
    rng = np.random.default_rng(7)
    severity = rng.uniform(0, 1, N_RIGS)
    profiles = [PaperVariable(), Multisine(), Chirp()]
    right = total = 0
    misses = []
    for noise in ("none", "realistic", "stress"):
        params = [degrade(s) for s in severity]
        prof = [profiles[i % 3] for i in range(N_RIGS)]
        runs = simulate_fleet(RigConfig(), params, prof, 10.0, noise=noise_model(noise),
                              seeds=list(range(N_RIGS)))
        fleet = Fleet()
        for i in range(N_RIGS):
            fleet.add_rig(f"r{i}")
        for i, run in enumerate(runs):
            fleet.update(np.full(len(run.samples), i), run.samples)
        for i, run in enumerate(runs):
            got = fleet.estimate(i).level
            true = grade_of_values(run.params.identified())
            total += 1
            right += got == true
            if got != true:
                misses.append((noise, round(float(severity[i]), 3), true, got))
    # measured: 175 / 180 = 97.2 % (issue target 95 %); the misses sit within ~0.03 severity of a band edge
    assert right / total >= 0.95, misses
