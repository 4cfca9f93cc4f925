"""``--config FILE`` on evaluate and audit: a CSV's rig constants (a CSV carries none)."""

import json
import re

import pytest

from hydromon.cli.main import main
from hydromon.contract import RigConfig
from hydromon.store.csvfile import csv_text
from plant_sim.degradation import table4_group
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate


@pytest.fixture(scope="module")
def other_rig():
    """A rig whose constants differ from the paper's (supply 14 MPa, larger chambers)."""
    cfg = RigConfig(p_s=14e6, V10=0.0012, V20=0.0009)
    return cfg, simulate(PaperVariable(), 10.0, params=table4_group(2), config=cfg)


def _grade(args, capsys):
    code = main(["evaluate", *args, "--json"])
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert code == (0 if doc["status"] == "ok" else 1)
    return doc, captured.err


def test_a_csv_is_evaluated_with_the_constants_given(other_rig, tmp_path, capsys):
    cfg, run = other_rig
    csv = tmp_path / "rig.csv"
    csv.write_text(csv_text(run.t, run.samples))
    conf = tmp_path / "rig.json"
    conf.write_text(cfg.model_dump_json())
    true = run.params.identified()
    right, err = _grade([str(csv), "--config", str(conf)], capsys)
    assert "rig constants from --config (100 Hz)" in err
    wrong, err = _grade([str(csv)], capsys)
    assert "the paper's at 100 Hz (a CSV carries none; give yours with --config FILE)" in err
    for k in ("inv_beta_e", "CdW_sqrt_rho"):  # the chamber parameters depend on the constants
        assert right["params"][k] == pytest.approx(true[k], rel=0.01), k
        assert abs(wrong["params"][k] / true[k] - 1) > 0.05, k
    # a rig of other constants: no ranges were made for it, so it is reported, not graded
    assert (right["grade"], right["status"]) == ("unknown", "uncalibrated")
    assert (wrong["grade"], wrong["status"]) != ("unknown", "uncalibrated")  # taken for the reference rig
    assert "p_s 1.4e+07" in right["uncalibrated"]
    conf.write_bytes(b"\xef\xbb\xbf" + cfg.model_dump_json().encode())  # a byte order mark, as Windows editors write
    assert _grade([str(csv), "--config", str(conf)], capsys)[0] == right


@pytest.mark.parametrize("text, match", [
    ("{", "--config .*rig.json: not JSON"),
    ('{"p_s": -1}', "--config .*rig.json: p_s -1 Pa is outside 0.1..100 MPa: give a unit, e.g. 12MPa"),
    ('{"nonsense": 1}', "--config .*rig.json: nonsense: "),
])
def test_a_bad_config_file_is_a_clear_error_naming_it(tmp_path, capsys, text, match):
    csv = tmp_path / "rig.csv"
    csv.write_text("t,ug,x1,x3,x4,x5\n0,2,0,6e6,4e6,0\n")
    conf = tmp_path / "rig.json"
    conf.write_text(text)
    for cmd in ("evaluate", "audit"):
        assert main([cmd, str(csv), "--config", str(conf)]) == 2
        assert re.search(match, capsys.readouterr().err), cmd
    assert main(["evaluate", str(csv), "--config", str(tmp_path / "none.json")]) == 2
    assert "none.json: no such file" in capsys.readouterr().err
