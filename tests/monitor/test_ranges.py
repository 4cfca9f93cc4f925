"""Health ranges files: round trips, and a bad file refused naming the problem."""

from __future__ import annotations

import json

import pytest

from hydromon.contract import PARAM_NAMES
from monitor.grading import ParamRange, Ranges, grade_of_values
from plant_sim.params import PlantParams

TRUE = PlantParams().identified()  # a healthy rig: every graded parameter in grade 0


def test_ranges_json_round_trip(tmp_path):
    r = Ranges.default()
    r.save(tmp_path / "a.json")
    assert Ranges.load(tmp_path / "a.json") == r
    custom = Ranges(params={**r.params, "CdW_sqrt_rho": ParamRange(
        direction="falling", edges=(5.5e-4, 5.0e-4, 4.5e-4, 4.0e-4))}, source="calibration")
    custom.save(tmp_path / "b.json")
    back = Ranges.load(tmp_path / "b.json")
    assert back == custom
    assert grade_of_values({**TRUE, "CdW_sqrt_rho": 4.7e-4}, back) == 2
    a = back.to_arrays()
    assert a.names == tuple(n for n in PARAM_NAMES if n in back.params)
    assert a.edges.shape == (len(r.params) + 1, 4) and a.sign[a.names.index("CdW_sqrt_rho")] == -1.0


@pytest.mark.parametrize("entry, needle", [
    ({"f_c": {"direction": "rising", "edges": [10, 20, 15, 75]}}, "20.0 -> 15.0"),
    ({"K_sv_omega_sv2": {"direction": "falling", "edges": [1.0, 1.4, 1.7, 2.2]}}, "decreasing"),
    ({"f_x": {"direction": "rising", "edges": [1, 2, 3, 4]}}, "f_x"),
    ({"f_c": {"direction": "rising", "edges": [10, 20, 1e999, 75]}}, "finite"),
    ({"f_c": {"direction": "up", "edges": [10, 20, 30, 75]}}, "direction"),
    ({"f_c": {"direction": "rising", "edges": [10, 20, 30]}}, "edges"),
    ({"f_c": {"direction": "rising", "edges": [1, 2, 3, 4], "fault_threshold": 1.0}},
     "exactly one"),
    ({"C_ip": {"direction": "rising", "fault_threshold": "NaN"}}, "fault_threshold"),
    ({}, "no parameter"),
])
def test_bad_ranges_file_raises_naming_the_problem(tmp_path, entry, needle):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps({"params": entry}))
    with pytest.raises(ValueError, match="bad.json") as e:
        Ranges.load(p)
    assert needle in str(e.value)


def test_not_json_raises(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(ValueError, match="x.json"):
        Ranges.load(p)
