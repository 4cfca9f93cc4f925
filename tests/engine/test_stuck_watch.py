"""The live monitor says ``bad-input`` for a rig whose chamber pressure stopped changing while
its spool moves (``hydromon.engine.stuck_watch``): a dead or stuck pressure sensor, which the
estimates would otherwise fit as they can; ``evaluate`` says the same of a record."""

from __future__ import annotations

import numpy as np
import pytest

from hydromon.contract import RigConfig
from hydromon.engine.evaluate import evaluate
from hydromon.engine.record import Recording
from hydromon.engine.stuck_watch import STUCK_S, stuck_words
from helpers import core_messages, health_however_batched, run_core
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

NS = "hydro"
NEED = int(STUCK_S * 100)


@pytest.fixture(scope="module", params=["realistic", "none"])
def run(request):
    return simulate(parse_profile("paper-var"), 30.0, params=degrade(0.3), noise=noise_model(request.param), seed=2)


def _stuck(run, column, a, b):
    """The record with pressure ``column`` (2: x3, 3: x4) holding sample a's reading until b."""
    s = run.samples.copy()
    s[a:b, column] = s[a, column]
    return s


def _messages(run, samples, frame=None, rig="a"):
    return core_messages(run, samples, frame, rig, NS)


def _run(msgs, batch=None):
    health, warnings = run_core(msgs, batch, NS)
    return health, [w for w in warnings if "dead or stuck pressure sensor" in w[1]]


@pytest.mark.parametrize("column", [2, 3])
def test_a_stuck_pressure_says_bad_input_after_stuck_s_and_is_warned_once(run, column):
    health, warned = _run(_messages(run, _stuck(run, column, 500, 2200)), batch=50)
    status = {h["seq"]: h["status"] for h in health}
    stuck = [s for s in status if 500 + NEED <= s < 2200]
    assert len(stuck) > 50 and {status[s] for s in stuck} == {"bad-input"}, sorted(set(status.values()))
    assert "bad-input" not in {status[s] for s in status if s < 500 + NEED - 1}  # a held reading, not yet stuck
    assert [w[0] for w in warned] == ["a"] and f"x{column + 1} has read" in warned[0][1], warned


def test_a_held_pressure_is_stuck_only_while_the_spool_moves():
    """A rig at rest with a pressure reading held exactly for 15 s (a coarse transducer): no call
    while the spool holds still within its noise; the same reading under a spool that moves
    50 um is stuck."""
    held = simulate(parse_profile("steps:low=2,high=2"), 30.0, params=degrade(0.3), noise=noise_model("realistic"),
                    seed=2)
    s = held.samples.copy()
    s[1000:2500, 2] = s[1000, 2]
    assert np.ptp(s[1000:2500, 4]) < 0.01 * RigConfig().x5_span  # the held spool's noise
    health, warned = _run(_messages(held, s), batch=50)
    assert health and "bad-input" not in {h["status"] for h in health} and not warned
    assert stuck_words(s, 100.0, RigConfig().x5_span) is None
    s[1000:2500, 4] += 5e-5 * np.sin(np.linspace(0.0, 6.0, 1500))
    health, warned = _run(_messages(held, s), batch=50)
    assert "bad-input" in {h["status"] for h in health} and len(warned) == 1
    assert stuck_words(s, 100.0, RigConfig().x5_span).startswith("x3 reads")


def test_each_channel_s_stuck_stretch_is_warned_of_once(run):
    """x3 sticking inside x4's stuck stretch: one warning each, not x4, x3, x4 again."""
    s = _stuck(run, 3, 500, 2800)
    s[1000:2300, 2] = s[1000, 2]
    _, warned = _run(_messages(run, s), batch=50)
    assert sorted(w[1][:2] for w in warned) == ["x3", "x4"], warned


def test_a_dead_pressure_leaves_the_other_s_stuck_stretch_named(run):
    """x3 dead throughout is the wiring check's to name; x4 stuck for 16 s is still said."""
    s = _stuck(run, 3, 700, 2300)
    s[:, 2] = 5e6
    assert stuck_words(s, 100.0, RigConfig().x5_span).startswith("x4 reads")


@pytest.mark.parametrize("profile", ["paper-var", "paper-id", "steps", "multisine"])
@pytest.mark.parametrize("noise", ["none", "realistic", "stress"])
def test_a_right_record_is_never_flagged_even_on_a_coarse_grid(profile, noise):
    """Every input shape and noise model, the pressures on a 12-bit transducer's 10 kPa grid and
    the spool on a 0.5 um one."""
    r = simulate(parse_profile(profile), 30.0, params=degrade(0.5), noise=noise_model(noise), seed=3)
    s = r.samples.copy()
    s[:, 2:4] = np.round(s[:, 2:4] / 1e4) * 1e4
    s[:, 4] = np.round(s[:, 4] / 5e-7) * 5e-7
    assert stuck_words(s, 100.0, RigConfig().x5_span) is None
    health, warned = _run(_messages(r, s), batch=100)
    assert not warned


def test_the_health_does_not_depend_on_how_the_messages_were_batched_or_framed(run):
    s = _stuck(run, 2, 400, 1900)
    assert any(h["status"] == "bad-input" for h in health_however_batched(run, s, NS))


def test_evaluate_names_the_stuck_pressure_and_where(run):
    s = _stuck(run, 3, 700, 2300)
    ev = evaluate(Recording("r", run.t, s, RigConfig(), "test"))
    assert ev.status == "bad-input" and ev.frozen.startswith(f"x4 reads {s[700, 3]:.6g} Pa for 16 s from sample 700")
    assert evaluate(Recording("r", run.t, run.samples, RigConfig(), "test")).frozen is None
    short = _stuck(run, 3, 700, 700 + NEED - 1)  # a reading held just short of STUCK_S
    assert stuck_words(short, 100.0, RigConfig().x5_span) is None
