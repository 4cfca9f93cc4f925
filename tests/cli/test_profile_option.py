"""``sim --profile file:PATH``: a command voltage from a CSV file, interpolated, held, limited as the contract's ug."""

from __future__ import annotations

import numpy as np
import pytest

from hydromon.cli.main import main
from hydromon.store.mcap_read import read_samples
from plant_sim.profiles import FromFile, parse_profile


def test_file_profile_interpolates_and_holds_beyond_its_ends(tmp_path):
    p = tmp_path / "u.csv"
    p.write_text("t,ug\n0.5,1.0\n1.5,3.0\n2.0,-1.0\n")
    prof = parse_profile(f"file:path={p}")
    assert isinstance(prof, FromFile) and prof.spec() == f"file:path={p}"
    t = np.array([0.0, 0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 9.0])
    np.testing.assert_allclose(prof(t), [1.0, 1.0, 2.0, 2.5, 3.0, 1.0, -1.0, -1.0])
    assert float(prof(1.0)) == 2.0  # a scalar time too
    # extra columns are ignored; their order does not matter
    q = tmp_path / "v.csv"
    q.write_text("ug,note,t\n2.0,a,0\n4.0,b,1\n")
    np.testing.assert_allclose(parse_profile(f"file:path={q}")([0.25]), [2.5])


@pytest.mark.parametrize("text, match", [
    ("time,ug\n0,1\n", "columns t,ug"),
    ("t,u\n0,1\n", "columns t,ug"),
    ("", "columns t,ug"),
    ("t,ug\n0,1\n1,2\n1,3\n", "t must increase strictly"),
    ("t,ug\n0,1\n2,2\n1,3\n", "t must increase strictly"),
    ("t,ug\n0,1\n1,nan\n", "non-finite"),
    ("t,ug\n0,1\n1,abc\n", r"u\.csv: line 3: .*'abc'"),
    ("t,ug\n0,1\n1,\n", r"u\.csv: line 3"),
    ("t,ug\n0,1\n1\n", r"u\.csv: line 3"),  # a short row: was a TypeError (float(None))
    ("t,ug\n0,1\n1,2500\n", r"u\.csv: line 3: ug = 2500.0 V is beyond \+-1000 V"),  # mV: out-of-contract samples
])
def test_file_profile_rejects_a_bad_file_naming_it(tmp_path, text, match):
    p = tmp_path / "u.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        parse_profile(f"file:path={p}")


def test_file_profile_missing_file_and_missing_path(tmp_path, capsys):
    with pytest.raises(FileNotFoundError, match="profile file '.*nope.csv': no such file"):
        parse_profile(f"file:path={tmp_path / 'nope.csv'}")
    with pytest.raises(ValueError, match="cannot be read as CSV text"):
        parse_profile(f"file:path={tmp_path}")  # a directory
    assert main(["sim", "--profile", f"file:path={tmp_path / 'nope.csv'}", "--duration", "1",
                 "--to-csv", str(tmp_path / "o.csv")]) == 2
    assert "profile file" in capsys.readouterr().err  # (was a bare "[Errno 2] ...")
    with pytest.raises(ValueError, match="needs path=FILE"):
        parse_profile("file")


def test_sim_profile_file_drives_the_command_voltage(tmp_path, capsys):
    prof = tmp_path / "u.csv"
    prof.write_text("t,ug\n0.05,1.0\n0.15,3.0\n")
    out = tmp_path / "run.csv"
    assert main(["sim", "--severity", "0.3", "--profile", f"file:path={prof}", "--duration", "0.25",
                 "--to-csv", str(out)]) == 0
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (25, 6)
    expect = np.interp(data[:, 0], [0.05, 0.15], [1.0, 3.0])  # held at 1 V before 0.05 s, 3 V after 0.15 s
    np.testing.assert_allclose(data[:, 1], expect, atol=1e-12)
    # the same through a fleet file, into an MCAP
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(f'[[rigs]]\nid = "f"\nseverity = 0.3\nprofile = "file:path={prof}"\n')
    assert main(["sim", "--fleet", str(fleet), "--duration", "0.25", "--to-mcap", str(tmp_path / "f.mcap")]) == 0
    _, mdata, _ = read_samples(tmp_path / "f.mcap", rig="f")
    np.testing.assert_allclose(mdata[:, 1], expect, atol=1e-12)
    capsys.readouterr()
    # errors are clear, exit 2, no traceback
    bad = tmp_path / "bad.csv"
    for text, what in (("t,ug\n0,1\n0,2\n", "t must increase strictly"), ("t,ug\n0,1\n1\n", "line 3")):
        bad.write_text(text)
        assert main(["sim", "--profile", f"file:path={bad}", "--duration", "0.1", "--to-csv", str(out)]) == 2
        err = capsys.readouterr().err
        assert "hydromon sim: error:" in err and what in err and str(bad) in err
    assert main(["sim", "--profile", f"file:path={tmp_path / 'nope.csv'}", "--duration", "0.1",
                 "--to-csv", str(out)]) == 2
    assert "nope.csv" in capsys.readouterr().err


def test_the_profile_file_limit_is_the_contract_s():
    from hydromon.contract import SAMPLE_LIMITS

    assert FromFile.UG_LIMIT == SAMPLE_LIMITS["ug"]  # plant_sim cannot import the contract (layers)


@pytest.mark.parametrize("opt, name, other", [("--to-csv", "run.mcap", "--to-mcap"), ("--to-mcap", "run.CSV", "--to-csv")])
def test_sim_refuses_a_file_name_that_says_the_other_format(tmp_path, capsys, opt, name, other):
    # --to-csv x.mcap would write CSV text into x.mcap (which evaluate and replay then refuse)
    assert main(["sim", "--duration", "1", opt, str(tmp_path / name)]) == 2
    assert f"use {other}" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
