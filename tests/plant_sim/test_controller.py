"""The rig's position controller: the rig constants' proportional loop, or a digital PI loop
with feed-forward whose output (the valve drive u) the simulation reports and holds."""

import numpy as np
import pytest

from hydromon.contract import RigConfig
from plant_sim.live import PlantFleet
from plant_sim.params import Controller, PlantParams
from plant_sim.profiles import PaperVariable, Steps
from plant_sim.simulate import simulate


def test_the_proportional_loops_drive_is_its_law_at_each_sample():
    cfg = RigConfig()
    run = simulate(PaperVariable(), 2.0, config=cfg)
    np.testing.assert_allclose(run.u, cfg.K_p * (run.ug - cfg.K_f * run.states[:, 0]), rtol=0, atol=1e-12)


def test_a_pi_loop_removes_the_steady_position_error_a_p_loop_keeps():
    # a command held for 10 s: the P loop settles 7 mm short of the target (the load and the
    # leakage need a standing spool opening, hence a standing error), the integral removes it
    cfg = RigConfig()
    prof = Steps(low=2.0, high=2.0, period=100.0)
    p_run = simulate(prof, 10.0, config=cfg)
    pi_run = simulate(prof, 10.0, config=cfg, controller=Controller(K_i=5.0))
    target = 2.0 / cfg.K_f
    p_err = abs(p_run.states[-1, 0] - target)
    pi_err = abs(pi_run.states[-1, 0] - target)
    assert p_err > 5e-3 and pi_err < 0.01 * p_err, (p_err, pi_err)


def test_the_digital_drive_follows_its_law_and_is_held_over_each_period():
    cfg, ctl = RigConfig(), Controller(K_i=3.0, K_ff=0.02)
    run = simulate(PaperVariable(), 2.0, config=cfg, controller=ctl)
    e = run.ug - cfg.K_f * run.states[:, 0]
    integral = np.cumsum(ctl.K_i * cfg.h * e)
    rate = np.diff(run.ug, prepend=run.ug[0]) / cfg.h
    np.testing.assert_allclose(run.u, cfg.K_p * (e + integral) + ctl.K_ff * rate, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("block", [1, 7, 50])
def test_live_blocks_give_the_simulations_samples_and_drive_under_a_pi_loop(block):
    cfg, ctl = RigConfig(), Controller(K_i=3.0, K_ff=0.02)
    params, prof = PlantParams(f_c=12.0), PaperVariable()
    run = simulate(prof, 1.0, params=params, config=cfg, controller=ctl)
    fleet = PlantFleet(cfg, [params], [prof], controllers=[ctl])
    blocks = [fleet.step(min(block, 100 - k)) for k in range(0, 100, block)]
    np.testing.assert_array_equal(np.concatenate([b.samples[0] for b in blocks]), run.samples)
    np.testing.assert_array_equal(np.concatenate([b.u[0] for b in blocks]), run.u)
