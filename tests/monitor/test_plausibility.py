"""Physically impossible estimates are not graded (monitor.plausibility): input in wrong units,
of the wrong sign or under a wrong zero gets status bad-input, grade unknown, and says why."""

import json

import numpy as np
import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.cli.main import main
from hydromon.contract import PARAM_NAMES, sample_key
from hydromon.engine.core import MonitorCore
from hydromon.store.csvfile import csv_text
from monitor.plausibility import POSITIVE, Z_IMPLAUSIBLE, any_impossible, implausible_names
from plant_sim.degradation import table4_group
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate

BAR = 1e5  # [Pa]


@pytest.fixture(scope="module")
def g1_run():
    return simulate(PaperVariable(), 10.0, params=table4_group(1))


@settings(max_examples=200, deadline=None)
@given(v=st.lists(st.floats(-1e6, 1e6), min_size=len(PARAM_NAMES), max_size=len(PARAM_NAMES)),
       s=st.lists(st.floats(0, 1e6) | st.just(float("inf")), min_size=len(PARAM_NAMES), max_size=len(PARAM_NAMES)))
def test_a_positive_parameter_below_minus_z_standard_errors_and_nothing_else_is_implausible(v, s):
    p, se = np.array([v]), np.array([s])
    expect = any(np.isfinite(se[0, PARAM_NAMES.index(n)]) and p[0, PARAM_NAMES.index(n)]
                 < -Z_IMPLAUSIBLE * se[0, PARAM_NAMES.index(n)] for n in POSITIVE)
    assert bool(any_impossible(p[0], se[0])) == expect  # the kernel's form
    names = implausible_names(dict(zip(PARAM_NAMES, v)), dict(zip(PARAM_NAMES, s)))
    assert bool(names) == expect and set(names) <= set(POSITIVE)


def _evaluate_json(run, tmp_path, capsys, scale=(1.0, 1.0, 1.0, 1.0, 1.0), offset=(0, 0, 0, 0, 0)):
    samples = run.samples * np.array(scale) + np.array(offset)
    path = tmp_path / "rec.csv"
    path.write_text(csv_text(run.t, samples))
    code = main(["evaluate", str(path), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == (0 if doc["status"] == "ok" else 1)  # bad input is not a pass (hydromon.cli.exits)
    return doc


def test_si_input_is_graded(g1_run, tmp_path, capsys):
    doc = _evaluate_json(g1_run, tmp_path, capsys)
    assert doc["status"] == "ok" and doc["grade"] != "unknown" and doc["implausible"] == []


@pytest.mark.parametrize("what, scale, offset", [
    ("x1 in cm", (1, 100, 1, 1, 1), (0, 0, 0, 0, 0)),
    ("x1 negated", (1, -1, 1, 1, 1), (0, 0, 0, 0, 0)),
    ("pressures in psi", (1, 1, 1 / 6894.76, 1 / 6894.76, 1), (0, 0, 0, 0, 0)),
    ("pressures in bar", (1, 1, 1 / BAR, 1 / BAR, 1), (0, 0, 0, 0, 0)),
])
def test_input_in_wrong_units_sign_or_zero_is_not_graded(g1_run, tmp_path, capsys, what, scale, offset):
    # each was graded `fault` with confidence 0.8-1.0 and status ok before
    doc = _evaluate_json(g1_run, tmp_path, capsys, scale, offset)
    assert doc["status"] == "bad-input" and doc["grade"] == "unknown" and doc["level"] is None, what
    assert doc["confidence"] == 0.0 and doc["implausible"], what
    assert all(doc["params"][k] < 0 for k in doc["implausible"]), what
    assert main(["evaluate", str(tmp_path / "rec.csv")]) == 1
    assert "physically impossible" in capsys.readouterr().out


def test_the_live_monitor_says_bad_input_for_pressures_in_bar(g1_run):
    core = MonitorCore()
    msgs = [(sample_key("r1"), orjson.dumps({"seq": k, "t": float(t), "ug": row[0], "x1": row[1],
                                              "x3": row[2] / BAR, "x4": row[3] / BAR, "x5": row[4]}))
            for k, (t, row) in enumerate(zip(g1_run.t.tolist(), g1_run.samples.tolist()))]
    health = [orjson.loads(p) for _, p in core.process(msgs)]
    assert health[-1]["status"] == "bad-input" and health[-1]["grade"] == "unknown"
    assert health[-1]["level"] is None and health[-1]["param_grades"] == {k: "unknown" for k in health[-1]["param_grades"]}
    # the same rig in SI is graded
    ok = [(k, orjson.dumps({**orjson.loads(p), "x3": orjson.loads(p)["x3"] * BAR, "x4": orjson.loads(p)["x4"] * BAR}))
          for k, p in msgs]
    health = [orjson.loads(p) for _, p in MonitorCore().process(ok)]
    assert health[-1]["status"] == "ok" and health[-1]["grade"] != "unknown"


def test_a_rig_whose_x1_went_beyond_a_chamber_end_reports_bad_input():
    from hydromon.contract import RigConfig, config_key

    core = MonitorCore()
    # rig "bad": chamber 1 empties at x1 = -V10 / A1 = -0.05 m, and its x1 reads -0.06 m
    msgs = [(config_key("bad"), orjson.dumps(RigConfig(V10=0.0004).model_dump(mode="json")))]
    for k in range(40):
        for rig, x1 in (("bad", -0.06), ("good", 0.01)):
            msgs.append((sample_key(rig), orjson.dumps({"seq": k, "t": k * 0.01, "ug": 2.0, "x1": x1, "x3": 6e6,
                                                        "x4": 4e6, "x5": 1e-5})))
    status = {}
    for key, payload in core.process(msgs):
        status.setdefault(key.split("/")[2], set()).add(orjson.loads(payload)["status"])
    assert status["bad"] >= {"bad-input"} and "bad-input" not in status["good"], status


def _clamp_stream(n=40):
    """Rig "bad" (chamber 1 empties at x1 = -0.05 m) reads x1 = 0.01 m, then -0.06 m from seq 25."""
    from hydromon.contract import RigConfig, config_key

    msgs = [(config_key("bad"), orjson.dumps(RigConfig(V10=0.0004).model_dump(mode="json")))]
    for k in range(n):
        msgs.append((sample_key("bad"), orjson.dumps({"seq": k, "t": k * 0.01, "ug": 2.0, "x1": 0.01 if k < 25 else -0.06,
                                                      "x3": 6e6, "x4": 4e6, "x5": 1e-5})))
    return msgs


def test_the_chamber_end_status_does_not_depend_on_batching():
    # the status comes from the clamp count of each health's own window, not of the whole batch:
    # a window that ends before the first clamped sample says the same in one batch and message by message
    msgs = _clamp_stream()
    whole = MonitorCore().process(msgs)
    core = MonitorCore()
    one_by_one = [h for m in msgs for h in core.process([m])]
    assert whole == one_by_one
    statuses = [orjson.loads(p)["status"] for _, p in whole]
    assert statuses[0] != "bad-input" and statuses[-1] == "bad-input", statuses


def test_bad_input_takes_precedence_over_stale():
    msgs = _clamp_stream(60)
    # a gap of 5 samples (seq 41-45) after x1 went beyond the chamber's end: the next health is stale
    # by the gap and bad-input by the clamp; bad-input wins
    msgs = msgs[:42] + msgs[47:]
    health = [orjson.loads(p) for _, p in MonitorCore().process(msgs)]
    after = [h["status"] for h in health if h["seq"] > 45]
    assert after and set(after) == {"bad-input"}, [(h["seq"], h["status"]) for h in health]


def test_impossible_estimates_leave_the_hysteresis_state_as_it_was(g1_run):
    """A rig graded from SI input, then fed pressures in bar: while its estimates are impossible
    it is not graded, and the band each parameter is held in (the hysteresis state) does not move,
    so the grade after the input is fixed is not pulled by what was graded from garbage."""
    from monitor.pipeline import Fleet

    fleet = Fleet()
    r = fleet.add_rig("r1")
    n = len(g1_run.t)
    fleet.update(np.zeros(n, np.int64), g1_run.samples)
    held = fleet.bands[r].copy()
    assert (held >= 0).any()  # graded, bands held
    bad = g1_run.samples / np.array([1, 1, BAR, BAR, 1])
    seen = 0
    for k in range(0, n, 10):
        before = fleet.bands[r].copy()
        ev = fleet.update(np.zeros(10, np.int64), bad[k:k + 10])
        assert len(ev) == 1
        if ev.implausible[0]:
            seen += 1
            assert ev.level[0] == -1 and ev.confidence[0] == 0.0 and (ev.grades[0] == -1).all()
            np.testing.assert_array_equal(fleet.bands[r], before)
        assert ev.converged[0]  # converged as before: the status says bad-input, not converging
    assert seen > n // 20, seen  # most of the bad stretch is judged impossible
