"""PlantFleet: stepping in blocks of any size gives the samples of one simulate_fleet call."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import RigConfig
from plant_sim.degradation import degrade, table4_group
from plant_sim.live import PlantFleet, command_block
from plant_sim.noise import NoiseModel, noise_model
from plant_sim.params import Effects
from plant_sim.profiles import parse_profile
from plant_sim.simulate import command_grid, simulate, simulate_fleet

CFG = RigConfig()
PARAMS = [table4_group(g) for g in range(1, 6)]
PROFILES = [parse_profile(s) for s in ("paper-var", "paper-id", "chirp", "steps", "multisine")]
EFFECTS = [
    Effects(),
    Effects(sensor_delay=3),  # recording delay only
    Effects(sensor_delay=5, sensor_delay_in_loop=True),  # slow sensor in the loop
    Effects(stribeck_F_s=50.0, x_max=2e-4),
    Effects(dead_band=1e-5, sensor_delay=1, sensor_delay_in_loop=True, supply_sag=1e9),
]
SEEDS = [7, 8, 9, 10, 11]
DURATION = 1.5  # [s] -> 150 samples
N = 150


def _blocks(fleet: PlantFleet, sizes: list[int]):
    blocks = [fleet.step(k) for k in sizes]
    return (np.concatenate([b.samples for b in blocks], axis=1),
            np.concatenate([b.states for b in blocks], axis=1),
            np.concatenate([b.seq for b in blocks]), np.concatenate([b.t for b in blocks]))


def _reference(noise: NoiseModel):
    runs = simulate_fleet(CFG, PARAMS, PROFILES, DURATION, EFFECTS, noise, SEEDS)
    return runs, np.stack([r.samples for r in runs]), np.stack([r.states for r in runs])


REF_CLEAN = _reference(NoiseModel())
REF_NOISY = _reference(noise_model("realistic"))


@settings(max_examples=25, deadline=None)
@given(sizes=st.lists(st.integers(1, 60), min_size=1, max_size=30).filter(lambda s: sum(s) >= N),
       noisy=st.booleans())
def test_blocks_of_any_size_equal_simulate_fleet(sizes, noisy):
    runs, ref_samples, ref_states = REF_NOISY if noisy else REF_CLEAN
    fleet = PlantFleet(CFG, PARAMS, PROFILES, EFFECTS, runs[0].noise, SEEDS)
    samples, states, seq, t = _blocks(fleet, sizes)
    # bit for bit: same kernel, same command instants, same noise stream consumed in order
    np.testing.assert_array_equal(samples[:, :N], ref_samples)
    np.testing.assert_array_equal(states[:, :N], ref_states)
    np.testing.assert_array_equal(seq, np.arange(sum(sizes)))
    np.testing.assert_array_equal(t[:N], runs[0].t)
    assert fleet.k == sum(sizes)


def test_noise_is_really_there_and_the_delays_act():
    _, clean, states = REF_CLEAN
    _, noisy, _ = REF_NOISY
    assert np.std(noisy[:, :, 1] - clean[:, :, 1]) == pytest.approx(5e-6, rel=0.2)
    # recording delay: measured x1 is the true x1 three samples earlier, the first held
    np.testing.assert_array_equal(clean[1, 3:, 1], states[1, :-3, 0])
    np.testing.assert_array_equal(clean[1, :3, 1], np.full(3, states[1, 0, 0]))
    # in-loop delay changes the trajectory itself (vs the same plant with a recording delay)
    alone = simulate(PROFILES[2], DURATION, PARAMS[2], CFG, Effects(sensor_delay=5))
    assert np.max(np.abs(alone.states[:, 0] - states[2, :, 0])) > 1e-6


def test_one_rig_alone_equals_the_same_rig_in_a_fleet():
    fleet = PlantFleet(CFG, PARAMS, PROFILES, EFFECTS, noise_model("realistic"), SEEDS)
    one = PlantFleet(CFG, [PARAMS[2]], [PROFILES[2]], [EFFECTS[2]], noise_model("realistic"), [SEEDS[2]])
    a, b = fleet.step(40), one.step(40)
    np.testing.assert_array_equal(a.samples[2], b.samples[0])


def test_per_rig_noise_models_and_configs():
    cfgs = [CFG, CFG.model_copy(update={"p_s": 10e6})]
    noises = [noise_model("none"), noise_model("stress")]
    fleet = PlantFleet(cfgs, PARAMS[:2], PROFILES[:2], None, noises, [1, 2])
    got = fleet.step(N).samples
    for i in range(2):
        ref = simulate(PROFILES[i], DURATION, PARAMS[i], cfgs[i], None, noises[i], [1, 2][i])
        np.testing.assert_array_equal(got[i], ref.samples)


def test_command_block_matches_command_grid():
    grid = command_grid(PROFILES[0], 101, CFG.h, 10)
    np.testing.assert_array_equal(command_block(PROFILES[0], 37, 40, CFG.h, 10), grid[37:77])


def test_state_pickles_and_the_copy_continues_identically():
    fleet = PlantFleet(CFG, PARAMS, PROFILES, EFFECTS, noise_model("realistic"), SEEDS)
    fleet.step(33)
    twin = pickle.loads(pickle.dumps(fleet))
    np.testing.assert_array_equal(fleet.step(50).samples, twin.step(50).samples)


def test_set_rig_takes_effect_from_the_next_sample():
    base = PlantFleet(CFG, [degrade(0.1)], [PROFILES[0]])
    changed = PlantFleet(CFG, [degrade(0.1)], [PROFILES[0]])
    a0, b0 = base.step(50), changed.step(50)
    np.testing.assert_array_equal(a0.samples, b0.samples)
    changed.set_rig(0, params=degrade(0.9))
    a1, b1 = base.step(50), changed.step(50)
    np.testing.assert_array_equal(a1.samples[:, 0], b1.samples[:, 0])  # sample 50 was already reached
    assert np.max(np.abs(a1.samples[0, 10:, 1] - b1.samples[0, 10:, 1])) > 1e-5


def test_a_growing_sensor_delay_reads_the_history():
    fleet = PlantFleet(CFG, [PARAMS[0]], [PROFILES[0]], [Effects(sensor_delay=2)])
    b0 = fleet.step(100)
    fleet.set_rig(0, effects=Effects(sensor_delay=6))
    b1 = fleet.step(20)
    x1 = np.concatenate([b0.states[0, :, 0], b1.states[0, :, 0]])
    # the old ring held samples 97..99 only: older ones repeat sample 97
    expect = [x1[max(s - 6, 97)] for s in range(100, 120)]
    np.testing.assert_array_equal(b1.samples[0, :, 1], expect)


def test_config_change_bumps_the_revision():
    fleet = PlantFleet(CFG, PARAMS[:2], PROFILES[:2])
    fleet.set_rig(1, config=CFG)
    assert list(fleet.config_rev) == [0, 0]
    fleet.set_rig(1, config=CFG.model_copy(update={"F_L": 5000.0}))
    assert list(fleet.config_rev) == [0, 1]
    with pytest.raises(ValueError, match="sample_rate"):
        fleet.set_rig(0, config=CFG.model_copy(update={"sample_rate": 200.0}))


@pytest.mark.parametrize("kwargs, match", [
    (dict(params_list=[]), "at least one rig"),
    (dict(profiles=PROFILES[:2]), "profiles: 2 given for 5"),
    (dict(seeds=[1, 2]), "seeds: 2 given for 5"),
    (dict(config=[CFG] * 4 + [CFG.model_copy(update={"sample_rate": 50.0})]), "share a sample rate"),
    (dict(substeps=0), "substeps"),
])
def test_bad_fleet_arguments(kwargs, match):
    args = dict(config=CFG, params_list=PARAMS, profiles=PROFILES)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        PlantFleet(**args)


def test_step_needs_a_positive_count():
    with pytest.raises(ValueError, match="k >= 1"):
        PlantFleet(CFG, PARAMS[:1], PROFILES[:1]).step(0)
