"""Seeded random rigs are graded as their true parameters grade under the default ranges."""

import numpy as np

from hydromon.contract import RigConfig
from monitor.grading import grade_of_values
from monitor.pipeline import Fleet
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import Chirp, Multisine, PaperVariable
from plant_sim.simulate import simulate_fleet

N_RIGS = 60  # per noise model below: 180 runs


def _grade_random_rigs(n_rigs, noises, start=0):
    """(right, total, misses) for n_rigs seeded random rigs per noise model, 10 s each, the
    monitor joining ``start`` samples into the run."""
    rng = np.random.default_rng(7)
    severity = rng.uniform(0, 1, n_rigs)
    profiles = [PaperVariable(), Multisine(), Chirp()]
    right = total = 0
    misses = []
    for noise in noises:
        params = [degrade(s) for s in severity]
        prof = [profiles[i % 3] for i in range(n_rigs)]
        runs = simulate_fleet(RigConfig(), params, prof, 10.0 + start * RigConfig().h, noise=noise_model(noise),
                              seeds=list(range(n_rigs)))
        fleet = Fleet()
        for i in range(n_rigs):
            fleet.add_rig(f"r{i}")
        for i, run in enumerate(runs):
            fleet.update(np.full(len(run.samples) - start, i), run.samples[start:])
        for i, run in enumerate(runs):
            got = fleet.estimate(i).level
            true = grade_of_values(run.params.identified())
            total += 1
            right += got == true
            if got != true:
                misses.append((noise, round(float(severity[i]), 3), true, got))
    return right, total, misses


def test_random_rigs_get_the_grade_of_their_true_parameters():
    right, total, misses = _grade_random_rigs(N_RIGS, ("none", "realistic", "stress"))
    # measured: 178 / 180 = 98.9 % (target 95 %); the misses sit within ~0.015 severity
    # of a band edge (before the valve was graded on its static gain: 175 / 180)
    assert right / total >= 0.95, misses


def test_random_rigs_joined_mid_run_get_the_grade_of_their_true_parameters():
    """The same rigs, the monitor joining 3 s into the run: the start from rest, which is what
    excites the valve's dynamics, is not seen."""
    right, total, misses = _grade_random_rigs(30, ("realistic", "stress"), start=300)
    # measured: 60 / 60 (with 60 rigs per noise model 179 / 180; graded on K_sv omega^2 as
    # Table 3 prints it, 121 / 180)
    assert right / total >= 0.95, misses
