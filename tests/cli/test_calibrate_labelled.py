"""``hydromon calibrate --labelled``: a record whose input is bad is left out, not put into the
edges; ``--out`` never writes over what the command reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hydromon.cli.main import main
from hydromon.store.csvfile import csv_text
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

GRADES = ("health", "sub-health", "average", "deterioration", "fault")


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Five labelled 20 s records, one per grade, and the healthy one with x3's sign turned."""
    d = tmp_path_factory.mktemp("labelled")
    paths = {}
    for g, sev in zip(GRADES, (0.05, 0.3, 0.5, 0.7, 0.9)):
        run = simulate(parse_profile("paper-var"), 20.0, params=degrade(sev), noise=noise_model("realistic"), seed=7)
        (d / f"{g}.csv").write_text(csv_text(run.t, run.samples))
        paths[g] = d / f"{g}.csv"
        if g == "health":
            s = run.samples.copy()
            s[:, 2] *= -1.0
            (d / "turned.csv").write_text(csv_text(run.t, s))
            (d / "dead-drive.csv").write_text(csv_text(run.t, run.samples, np.zeros(len(run.t))))
    return d, paths


def _list(d, rows):
    path = d / "list.csv"
    path.write_text("recording,grade\n" + "".join(f"{p},{g}\n" for p, g in rows))
    return path


def test_a_record_with_bad_input_is_left_out_and_said_so(records, tmp_path, capsys):
    d, paths = records
    bad = [(d / "turned.csv", "health"), (d / "dead-drive.csv", "health")]
    listed = _list(d, [(paths[g], g) for g in GRADES] + bad)
    out = tmp_path / "ranges.json"
    assert main(["calibrate", "--labelled", str(listed), "--out", str(out)]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "turned.csv (health): left out: its input is bad" in err, err
    assert "dead-drive.csv (health): left out: " in err and "u (the valve drive) is 0 V in every sample" in err, err
    edges = json.loads(out.read_text())
    assert edges  # written, from the five good records only
    # the same list without the bad record gives the same ranges
    again = tmp_path / "again.json"
    assert main(["calibrate", "--labelled", str(_list(d, [(paths[g], g) for g in GRADES])), "--out", str(again)]) == 0
    assert json.loads(again.read_text()) == edges


@pytest.mark.parametrize("which", ["record", "list"])
def test_out_is_never_one_of_the_inputs(records, capsys, which):
    d, paths = records
    listed = _list(d, [(paths[g], g) for g in GRADES])
    target = paths["average"] if which == "record" else listed
    before = target.read_bytes()
    assert main(["calibrate", "--labelled", str(listed), "--out", str(target)]) == 2
    assert "is one of this command's inputs" in capsys.readouterr().err and target.read_bytes() == before


def test_commission_never_writes_over_its_recording_even_with_force(records, capsys):
    _, paths = records
    before = paths["health"].read_bytes()
    assert main(["commission", str(paths["health"]), "--out", str(paths["health"]), "--force", "--runs", "0"]) == 2
    assert "is one of this command's inputs" in capsys.readouterr().err and paths["health"].read_bytes() == before


def test_commission_says_how_many_gaps_its_record_holds(tmp_path, capsys):
    run = simulate(parse_profile("paper-var"), 30.0, params=degrade(0.05), noise=noise_model("realistic"), seed=8)
    keep = list(range(0, 1200)) + list(range(1600, 3000))  # 4 s lost mid-record
    path = tmp_path / "gap.csv"
    path.write_text(csv_text(run.t[keep], run.samples[keep]))
    main(["commission", str(path), "--out", str(tmp_path / "r.json"), "--runs", "0"])
    err = " ".join(capsys.readouterr().err.split())
    assert "rig csv, 26.0 s; 1 gap(s), 400 sample(s) missing;" in err, err


def test_a_toml_list_with_a_misspelt_key_is_refused_naming_it(tmp_path):
    """``rigg = "press-7"`` was dropped without a word, and the record read as the file's only rig."""
    from hydromon.store.labelled import load_labelled

    good = tmp_path / "good.toml"
    good.write_text('[[records]]\nrecording = "a.mcap"\ngrade = "health"\nrig = "press-7"\n')
    assert load_labelled(good)[0].rig == "press-7"
    bad = tmp_path / "bad.toml"
    bad.write_text('[[records]]\nrecording = "a.mcap"\ngrade = "health"\nrigg = "press-7"\n')
    with pytest.raises(ValueError, match=r"bad.toml record 1: unknown key\(s\) 'rigg' \(a record takes recording, "
                                         r"grade, rig\)"):
        load_labelled(bad)
