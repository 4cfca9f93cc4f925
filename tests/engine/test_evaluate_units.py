"""``evaluate`` does not trust a record whose readings cannot be in its rig config's units
(``monitor.readings``): a spool in 0.01 mm or pressures with their sign turned fit the model with
the units in the parameters, and were graded as the correct record."""

from __future__ import annotations

import pytest

from hydromon.contract import RigConfig
from hydromon.engine.evaluate import evaluate
from hydromon.engine.record import Recording
from hydromon.report.evaluate import render, to_json
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate


@pytest.fixture(scope="module")
def healthy():
    return simulate(parse_profile("paper-var"), 20.0, params=degrade(0.05), noise=noise_model("realistic"), seed=1)


def _scaled(run, columns, factor):
    s = run.samples.copy()
    s[:, columns] *= factor
    return Recording("r", run.t, s, RigConfig(), "<test>")


def test_a_healthy_record_in_si_is_trusted(healthy):
    ev = evaluate(_scaled(healthy, [], 1.0))
    assert ev.units is None and ev.status == "ok" and to_json(ev)["units"] is None


@pytest.mark.parametrize("columns, factor, said", [
    ([4], 100.0, "x5 reaches"),
    ([2, 3], -1.0, "falls to -"),
    ([1], 100.0, "x1 reaches"),
    ([2, 3], 1e-5, "the pressures x3 and x4 never exceed"),
])
def test_a_record_in_other_units_is_bad_input_saying_which_reading(healthy, capsys, columns, factor, said):
    ev = evaluate(_scaled(healthy, columns, factor))
    doc = to_json(ev)
    assert ev.status == doc["status"] == "bad-input"
    assert said in doc["units"] and "hydromon reads " in doc["units"], doc["units"]
    render(ev)
    out = " ".join(capsys.readouterr().out.split())  # rich wraps at the terminal's width
    assert "not to be trusted: " + " ".join(doc["units"].split()) in out, out


def test_samples_beyond_that_the_live_monitor_takes_for_a_glitch_are_not_a_unit_slip(healthy):
    """Two spool samples beyond 10 mm (the outlier gate mends one on x5) are a glitch, as the live
    monitor takes them (``GLITCH_SAMPLES``); a third makes them a reading the config cannot hold."""
    from monitor.readings import GLITCH_SAMPLES

    s = healthy.samples.copy()
    s[700:700 + GLITCH_SAMPLES, 4] = 0.05
    assert evaluate(Recording("r", healthy.t, s, RigConfig(), "<test>")).units is None
    s[700 + GLITCH_SAMPLES, 4] = 0.05
    assert "x5 reaches 0.05 m" in evaluate(Recording("r", healthy.t, s, RigConfig(), "<test>")).units
