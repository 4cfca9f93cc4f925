"""What a new user meets first on the command line: the version, an example in every command's
help, a suggestion for a mistyped option or command, and one rule for the exit status of the
commands that give a verdict (hydromon.cli.exits): 0 graded, 1 not graded or not to be
trusted, 2 usage."""

from __future__ import annotations

import json
import re
import shlex

import numpy as np
import pytest

from hydromon.cli.main import build_parser, main
from hydromon.cli.exits import exit_status
from hydromon.contract import RigConfig
from hydromon.store.csvfile import csv_text
from plant_sim.degradation import table4_group
from plant_sim.noise import noise_model
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate

COMMANDS = build_parser()._subparsers._group_actions[0].choices


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["--version"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("hydromon ") and out.split()[1][0].isdigit()


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_shows_examples_that_parse(name):
    p = COMMANDS[name]
    assert p.examples, name
    text = p.format_help()
    assert "\nexamples:\n" in text
    for example in p.examples:
        assert f"  {example}\n" in text
        words = shlex.split(example, comments=True)
        assert words[:2] == ["hydromon", name], example
        build_parser().parse_args(words[1:])  # a usage error would raise SystemExit


@pytest.mark.parametrize("argv, hint", [
    (["demo", "--duraton", "5"], "did you mean --duration?"),
    (["evaluate", "x.csv", "--jsno"], "did you mean --json?"),
    (["sim", "--efect", "load_offset=1N"], "did you mean --effect?"),
    (["evalute", "x.csv"], "did you mean evaluate?"),
    (["wach", "--once"], "did you mean watch?"),
    (["--verison"], "did you mean --version?"),
])
def test_a_mistyped_option_or_command_gets_the_closest_one(capsys, argv, hint):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert hint in err and "error:" in err
    if argv[0] in COMMANDS:
        assert f"hydromon {argv[0]}: error: unrecognized arguments" in err  # named by its command


def test_no_suggestion_for_an_option_like_none(capsys):
    with pytest.raises(SystemExit):
        main(["demo", "--zzzzzz"])
    assert "did you mean" not in capsys.readouterr().err


# -- exit statuses --------------------------------------------------------------------------------

def test_the_rule():
    assert exit_status(["ok", "ok"]) == 0
    for bad in ("bad-input", "uncalibrated", "stale", "converging", "commissioning"):
        assert exit_status(["ok", bad]) == 1, bad
    assert exit_status([]) == 1  # nothing graded


@pytest.fixture(scope="module")
def g2_run():
    return simulate(PaperVariable(), 10.0, params=table4_group(2), noise=noise_model("realistic"), seed=3)


def _csv(tmp_path, run, name="rec.csv", scale=(1.0, 1.0, 1.0, 1.0, 1.0), n=None):
    path = tmp_path / name
    samples = run.samples[:n] * np.array(scale)
    path.write_text(csv_text(run.t[:n], samples))
    return path


def test_evaluate_exits_0_graded_1_bad_input_or_too_short_2_usage(g2_run, tmp_path, capsys):
    ok = _csv(tmp_path, g2_run)
    assert main(["evaluate", str(ok), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["status"] == "ok"
    bar = _csv(tmp_path, g2_run, "bar.csv", scale=(1, 1, 1e-5, 1e-5, 1))  # pressures in bar: bad input
    for extra in ([], ["--json"]):
        assert main(["evaluate", str(bar), *extra]) == 1
    short = _csv(tmp_path, g2_run, "short.csv", n=200)  # 2 s: not converged, no grade
    assert main(["evaluate", str(short), "--json"]) == 1
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["status"] == "converging"
    assert main(["evaluate", str(tmp_path / "missing.csv")]) == 2
    assert main(["evaluate", str(ok), "--memory", "5"]) == 2


def test_pressures_in_bar_are_refused_by_the_audit_naming_the_unit_and_not_trusted_by_evaluate(g2_run, tmp_path,
                                                                                                 capsys):
    bar = _csv(tmp_path, g2_run, "bar.csv", scale=(1, 1, 1e-5, 1e-5, 1))
    assert main(["audit", str(bar), "--json"]) == 2  # refused before anything is fitted
    err = capsys.readouterr().err.splitlines()[-1]
    assert "the pressures x3 and x4 never exceed" in err and "are they in bar, MPa or psi?" in err, err
    assert main(["evaluate", str(bar), "--json"]) == 1


def test_a_rig_without_ranges_made_for_its_constants_is_uncalibrated_and_exits_1(tmp_path, capsys):
    cfg = RigConfig(p_s=14e6, V10=0.0012, V20=0.0009)
    run = simulate(PaperVariable(), 10.0, params=table4_group(2), config=cfg)
    csv = _csv(tmp_path, run)
    conf = tmp_path / "rig.json"
    conf.write_text(cfg.model_dump_json())
    assert main(["evaluate", str(csv), "--config", str(conf), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["status"] == "uncalibrated" and doc["grade"] == "unknown"
    assert "p_s 1.4e+07 (ranges made for 1.2e+07)" in doc["uncalibrated"]
    assert main(["evaluate", str(csv), "--config", str(conf)]) == 1
    out = " ".join(capsys.readouterr().out.split())
    assert "not graded: " in out and "hydromon commission" in out


def test_evaluate_explains_confidence_and_unknown_standard_errors_in_words(tmp_path, capsys):
    run = simulate(PaperVariable(), 10.0, params=table4_group(3), noise=noise_model("realistic"), seed=1)
    assert main(["evaluate", str(_csv(tmp_path, run))]) == 0
    out = " ".join(capsys.readouterr().out.split())  # rich wraps at the terminal's width
    assert "grade fault" in out
    assert re.search(r"why: internal leakage \d\.\dx the fault threshold \(\d\.\de-10 m\^3/\(s Pa\)\)", out), out
    assert re.search(r"valve gain -6\d % of its baseline \(-0\.00017 m/V\)", out), out
    assert "confidence 0.60: the chance the grade is right given the estimates' uncertainty, 3 of 5 graded " \
           "parameters placed" in out
    assert not re.search(r"\binf\b", out) and "std error -: not identifiable from this record" in out
    assert "K_sv omega^2 is reported, not graded" not in out  # said once, in docs/method.md


# -- whole recordings -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fleet_mcap(tmp_path_factory):
    """The default fleet (the five Table 4 rigs), 10 s, realistic noise, as one recording."""
    path = tmp_path_factory.mktemp("fleet") / "fleet.mcap"
    assert main(["sim", "--to-mcap", str(path), "--duration", "10", "--noise", "realistic", "--seed", "1"]) == 0
    return path


def test_evaluate_grades_every_rig_of_a_recording(fleet_mcap, capsys):
    from plant_sim.degradation import TABLE4_PAPER_GRADES

    code = main(["evaluate", str(fleet_mcap), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert sorted(doc) == [f"table4-g{g}" for g in range(1, 6)]
    assert code == (0 if all(d["status"] == "ok" for d in doc.values()) else 1)
    right = sum(doc[f"table4-g{g}"]["grade"] == TABLE4_PAPER_GRADES[g] for g in range(1, 6))
    assert right >= 4, {rig: d["grade"] for rig, d in doc.items()}
    assert all(isinstance(d["why"], list) for d in doc.values())
    main(["evaluate", str(fleet_mcap)])
    out = capsys.readouterr().out
    table = [line for line in out.splitlines() if line.strip().startswith(("┃", "│"))]
    assert "rig" in table[0] and "grade" in table[0] and "why" in table[0]
    rows = [line for line in table if "table4-g" in line]
    assert len(rows) == 5 and "table4-g3" in rows[0]  # the fault first
    assert "one rig in full: hydromon evaluate" in " ".join(out.split())
    assert main(["evaluate", str(fleet_mcap), "--rig", "table4-g2", "--json"]) in (0, 1)
    assert json.loads(capsys.readouterr().out)["grade"] == doc["table4-g2"]["grade"]


def test_audit_audits_every_rig_of_a_recording(tmp_path, capsys):
    fleet = tmp_path / "two.toml"  # two rigs, one with a hidden dead band (the audit takes seconds a rig)
    fleet.write_text('[[rigs]]\nid = "a"\nseverity = 0.1\n[[rigs]]\nid = "b"\nseverity = 0.1\n'
                     '[rigs.effects]\nvalve_dead_band = "5um"\n')
    rec = tmp_path / "two.mcap"
    assert main(["sim", "--fleet", str(fleet), "--to-mcap", str(rec), "--duration", "8", "--noise", "realistic"]) == 0
    code = main(["audit", str(rec), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert sorted(doc) == ["a", "b"] and code == 0
    assert doc["b"]["cause"] == "valve_dead_band" and doc["a"]["cause"] != "valve_dead_band", doc
    assert main(["audit", str(rec)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["rig", "cause", "free-run"] and out[2].startswith("b ")
    assert "valve_dead_band" in out[2]


def test_sim_to_csv_writes_one_file_per_rig_of_a_fleet(tmp_path, capsys):
    assert main(["sim", "--to-csv", str(tmp_path / "run.csv"), "--duration", "1"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"run-table4-g{g}.csv" for g in range(1, 6)]
    (tmp_path / "dir").mkdir()
    assert main(["sim", "--to-csv", str(tmp_path / "dir"), "--duration", "1", "--effect", "valve_dead_band=5um"]) == 0
    assert len(list((tmp_path / "dir").glob("table4-g*.csv"))) == 5
    assert main(["sim", "--to-csv", str(tmp_path / "x.csv"), "--duration", "1", "--effect", "valve_dead_band=2.5"]) == 2
    assert "valve_dead_band 2.5 m is outside" in capsys.readouterr().err
