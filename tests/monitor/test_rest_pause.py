"""The chamber rows pause while the piston rests (IdentOptions.rest_pause).

Found by running a rig held still after its identification: at rest the chamber rows carry
sensor noise and constants only, and errors in variables pulled the chamber estimates along
for as long as the rest lasted (1000 s at realistic noise: 1/beta_e, C_d W/sqrt(rho) and C_ip
22-32 % low, C_ip's grade with them), with the covariance shrinking all the while.
"""

from __future__ import annotations

import numpy as np
import pytest

from monitor.ident_options import IdentOptions
from monitor.layout import O_ROWS
from monitor.pipeline import Pipeline
from plant_sim.noise import noise_model
from plant_sim.profiles import FromFile
from plant_sim.simulate import simulate

T_MOVE, T_REST = 10.0, 1000.0
CHAMBER = ("inv_beta_e", "CdW_sqrt_rho", "C_ip")


@pytest.fixture(scope="module")
def held_run():
    """The paper's identification input for T_MOVE s, then ug held at 2 V for T_REST s."""
    tt = np.arange(0.0, T_MOVE, 0.01)
    t = np.concatenate([tt, [T_MOVE + 0.01, T_MOVE + T_REST + 1.0]])
    u = np.concatenate([2.0 + np.sin(2 * np.pi * tt), [2.0, 2.0]])
    run = simulate(FromFile(path="", t_data=t, u_data=u), T_MOVE + T_REST, noise=noise_model("realistic"), seed=1)
    return np.column_stack([run.ug, run.measured])


def _moved_then_held(samples, options):
    p = Pipeline(options=options)
    n = int(T_MOVE * 100)
    _, moved = p.run(samples[:n])
    rows_moved = p.fleet.states[0, O_ROWS + 1]
    _, held = p.run(samples[n:])
    return moved, held, rows_moved, p.fleet.states[0, O_ROWS + 1]


def test_chamber_estimates_hold_while_the_piston_rests(held_run):
    moved, held, rows_moved, rows_held = _moved_then_held(held_run, IdentOptions())
    # the rows go on while the pressures settle (measured: 438 rows, 4.4 s), then stop for the
    # rest of the 100,000 samples at rest
    assert rows_held - rows_moved < 1000
    for k in CHAMBER:
        assert abs(held.params[k] - moved.params[k]) <= 0.5 * moved.std_errors[k], k
        assert held.std_errors[k] >= 0.9 * moved.std_errors[k], k  # no information from rest
    assert held.param_levels["C_ip"] == moved.param_levels["C_ip"] == 0


def test_without_the_pause_the_rest_pulls_them(held_run):
    # the failure the pause exists for, kept measurable: if this stops failing, the option is moot
    moved, held, _, _ = _moved_then_held(held_run, IdentOptions(rest_pause=0.0))
    drift = {k: (held.params[k] - moved.params[k]) / moved.params[k] for k in CHAMBER}
    z = {k: (held.params[k] - moved.params[k]) / moved.std_errors[k] for k in CHAMBER}
    # measured: 22-32 % low, 78-89 standard errors: confidently wrong
    assert all(d < -0.1 for d in drift.values()) and all(v < -10 for v in z.values()), (drift, z)
