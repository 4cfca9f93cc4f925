"""hydromon evaluate: CSV/MCAP edge validation and grading of a simulated recording."""

import json

import numpy as np
import pytest

from hydromon.cli.main import main
from hydromon.contract import SAMPLE_COLUMNS as CSV_COLUMNS
from hydromon.engine.evaluate import evaluate
from hydromon.store.csvfile import csv_text, read_csv
from hydromon.store.recording import load_recording
from plant_sim.degradation import TABLE4_PAPER_GRADES, table4_group
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate

KEYS = {"grade", "level", "confidence", "status", "params", "std_errors", "glitches_replaced", "gaps", "implausible",
        "x1_outside_chambers", "timestamp_jitter", "config_changes", "memory_s", "uncalibrated", "why", "units",
        "frozen", "wiring"}


@pytest.fixture(scope="module")
def g4_run():
    return simulate(PaperVariable(), 10.0, params=table4_group(4))


@pytest.fixture
def g4_csv(g4_run, tmp_path):
    p = tmp_path / "g4.csv"
    p.write_text(csv_text(g4_run.t, g4_run.samples))
    return p


def test_csv_round_trip_is_exact(g4_run, g4_csv):
    rec = load_recording(g4_csv)
    np.testing.assert_array_equal(rec.samples, g4_run.samples)
    np.testing.assert_array_equal(rec.t, g4_run.t)


def test_cli_grades_a_csv_recording(g4_csv, capsys):
    assert main(["evaluate", str(g4_csv)]) == 0
    out = capsys.readouterr().out
    assert TABLE4_PAPER_GRADES[4] in out and "K_sv_omega_sv2" in out


def test_cli_json_is_one_document_with_the_contract_keys(g4_csv, capsys):
    assert main(["evaluate", str(g4_csv), "--json"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)  # stdout holds exactly one JSON document
    assert set(doc) == KEYS
    assert doc["grade"] == "average" and doc["level"] == 2 and doc["status"] == "ok"
    assert 0.5 < doc["confidence"] <= 1.0
    assert abs(doc["params"]["K_sv_omega_sv2"] - 1.6) < 0.01
    assert set(doc["params"]) == set(doc["std_errors"])
    assert "samples" in captured.err  # the log line goes to stderr
    assert doc["glitches_replaced"] == {"x1": 0, "x3": 0, "x4": 0, "x5": 0}


def test_sensor_glitches_are_reported_and_do_not_move_the_grade(g4_run, tmp_path, capsys):
    samples = g4_run.samples.copy()
    samples[500, 3] -= 2e7  # x4 glitch
    samples[700, 4] += 1e-3  # x5 glitch
    p = tmp_path / "glitched.csv"
    p.write_text(csv_text(g4_run.t, samples))
    assert main(["evaluate", str(p), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["glitches_replaced"] == {"x1": 0, "x3": 0, "x4": 1, "x5": 1}
    assert doc["grade"] == "average"
    assert main(["evaluate", str(p)]) == 0
    assert "glitches replaced" in capsys.readouterr().out


def test_short_recording_is_converging_with_null_level(g4_run, tmp_path, capsys):
    p = tmp_path / "short.csv"
    p.write_text(csv_text(g4_run.t[:200], g4_run.samples[:200]))
    assert main(["evaluate", str(p), "--json"]) == 1  # not graded (hydromon.cli.exits)
    doc = json.loads(capsys.readouterr().out)
    assert doc["status"] == "converging" and doc["level"] is None and doc["grade"] == "unknown"
    assert doc["std_errors"]["m"] is None  # inf: not identified yet, null in JSON
    # the table says why: the record's length (not an unexcited valve)
    assert main(["evaluate", str(p)]) == 1
    out = " ".join(capsys.readouterr().out.split())
    assert "not converged: the chamber and valve equations need 300 rows each" in out
    assert "this record has 200 samples" in out and "smooth command" not in out


@pytest.mark.parametrize("group", [1, 2, 3, 5])
def test_evaluate_grades_table4_groups(group):
    run = simulate(PaperVariable(), 10.0, params=table4_group(group))
    from hydromon.contract import RigConfig
    from hydromon.engine.record import Recording
    ev = evaluate(Recording("g", run.t, run.samples, RigConfig(), "mem"))
    assert ev.assessment.grade == TABLE4_PAPER_GRADES[group]


def _write(tmp_path, text):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    return p


GOOD = "t,ug,x1,x3,x4,x5\n0.0,2,0,1e6,1e6,0\n0.01,2,0,1e6,1e6,0\n0.02,2,0,1e6,1e6,0\n"


def test_good_small_csv_parses(tmp_path):
    assert load_recording(_write(tmp_path, GOOD)).samples.shape == (3, 5)


@pytest.mark.parametrize("text, match", [
    (GOOD.replace("x4,", ""), r"line 1.*lacks column\(s\) x4"),
    (GOOD.replace("0.01,2,0,1e6", "0.01,2,nan,1e6"), r"line 3: x1 = 'nan' is not finite"),
    (GOOD.replace("0.01,2,0,1e6", "0.01,2,abc,1e6"), r"line 3: x1 = 'abc' is not a number"),
    (GOOD.replace("0.01,2,0,1e6", "0.01,2,0,1e300"), r"line 3: x3 = '1e300' is beyond the contract's limit"),
    (GOOD.replace("0.01,2,0,1e6", "0.01,2,25,1e6"), r"line 3: x1 = '25' is beyond .* \|x1\| <= 10"),
    (GOOD.replace("0.02,", "0.005,"), r"line 4: t = 0.005 s does not increase"),
    (GOOD.replace("0.02,", "0.01,"), r"line 4: t = 0.01 s does not increase"),
    (GOOD.replace("0.02,", "0.0203,"), r"line 4: .*every 0.01 s"),
    (GOOD + "0.03,2,0\n", r"line 5: 3 fields"),
    ("", r"empty file"),
    ("t,ug,x1,x3,x4,x5\n", r"no samples"),
    (GOOD + "\n0.03,2,0,1e6,1e6,0\n", r"line 5: empty line"),  # a blank line inside the data
])
def test_bad_csv_raises_a_clear_error(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        load_recording(_write(tmp_path, text))


def test_blank_lines_at_the_end_are_allowed(tmp_path):
    # an editor's extra newline at the end is not refused as "line N: empty line"
    assert len(load_recording(_write(tmp_path, GOOD + "\n\n  \n")).t) == len(load_recording(_write(tmp_path, GOOD)).t)


def test_sampling_within_one_percent_is_accepted(tmp_path):
    assert len(load_recording(_write(tmp_path, GOOD.replace("0.02,", "0.0200999,"))).t) == 3


def test_cli_reports_bad_csv_and_unknown_type(tmp_path, capsys):
    p = _write(tmp_path, GOOD.replace("x4,", ""))
    assert main(["evaluate", str(p)]) == 2
    assert "lacks column" in capsys.readouterr().err
    q = tmp_path / "x.txt"
    q.write_text(GOOD)
    assert main(["evaluate", str(q)]) == 2
    assert "unknown file type" in capsys.readouterr().err


def test_read_csv_column_order_is_free():
    import io
    text = "x5,x4,x3,x1,ug,t\n0,1,2,3,4,5\n"
    np.testing.assert_array_equal(read_csv(io.StringIO(text))[0], [5, 4, 3, 2, 1, 0])
    assert CSV_COLUMNS == ("t", "ug", "x1", "x3", "x4", "x5")


def test_mcap_recording_is_graded(g4_run, tmp_path, capsys):
    from hydromon.store.mcap_write import RecordingWriter

    p = tmp_path / "g4.mcap"
    with open(p, "wb") as f, RecordingWriter(f) as w:
        for k, (t, row) in enumerate(zip(g4_run.t, g4_run.samples)):
            payload = dict(seq=k, t=float(t), **dict(zip(CSV_COLUMNS[1:], map(float, row))))
            t_ns = int(round(t * 1e9))
            w.write("hydro/rig/g4/sample", json.dumps(payload).encode(), t_ns, t_ns)
    rec = load_recording(p)
    assert rec.rig == "g4"
    np.testing.assert_array_equal(rec.samples, g4_run.samples)
    assert main(["evaluate", str(p), "--json", "--rig", "g4"]) == 0
    assert json.loads(capsys.readouterr().out)["grade"] == "average"
    with pytest.raises(ValueError, match="not in recording"):
        load_recording(p, rig="other")



def test_an_mcap_without_the_rigs_config_says_the_papers_constants_were_taken(g4_run, tmp_path, capsys):
    """An MCAP holding no config for the rig is graded with the paper's constants, and evaluate
    says so instead of "rig constants as recorded"."""
    from hydromon.store.mcap_write import RecordingWriter

    p = tmp_path / "bare.mcap"
    with open(p, "wb") as f, RecordingWriter(f) as w:
        for k, (t, row) in enumerate(zip(g4_run.t[:50], g4_run.samples)):
            payload = dict(seq=k, t=float(t), **dict(zip(CSV_COLUMNS[1:], map(float, row))))
            w.write("hydro/rig/g4/sample", json.dumps(payload).encode(), k * 10**7, k * 10**7)
    assert main(["evaluate", str(p), "--json"]) == 1  # 50 samples: converging, not graded
    err = capsys.readouterr().err
    assert "rig constants: the paper's at 100 Hz (the recording holds no config for the rig" in err
    assert "as recorded" not in err
    with open(p, "wb") as f, RecordingWriter(f) as w:
        w.write("hydro/rig/g4/config", g4_run.config.model_dump_json().encode(), 0, 0)
        for k, (t, row) in enumerate(zip(g4_run.t[:50], g4_run.samples)):
            payload = dict(seq=k, t=float(t), **dict(zip(CSV_COLUMNS[1:], map(float, row))))
            w.write("hydro/rig/g4/sample", json.dumps(payload).encode(), k * 10**7, k * 10**7)
    assert main(["evaluate", str(p), "--json"]) == 1
    assert "rig constants as recorded" in capsys.readouterr().err

def test_multi_rig_mcap_needs_rig(g4_run, tmp_path):
    from hydromon.store.mcap_write import RecordingWriter

    p = tmp_path / "two.mcap"
    with open(p, "wb") as f, RecordingWriter(f) as w:
        for rig in ("a", "b"):
            for k in range(3):
                payload = dict(seq=k, t=k * 0.01, ug=2.0, x1=0.0, x3=1e6, x4=1e6, x5=0.0)
                w.write(f"hydro/rig/{rig}/sample", json.dumps(payload).encode(), k * 10**7, k * 10**7)
    with pytest.raises(ValueError, match="several rigs.*--rig ID"):
        load_recording(p)
    assert load_recording(p, rig="b").rig == "b"


def _gappy_mcap(run, path, drop=range(400, 430), invalid=(600,)):
    """The run as an MCAP with samples dropped (a gap in seq and t) and invalid ones."""
    from hydromon.store.mcap_write import RecordingWriter

    msgs = []
    with open(path, "wb") as f, RecordingWriter(f) as w:
        for k, (t, row) in enumerate(zip(run.t, run.samples)):
            if k in drop:
                continue
            payload = dict(seq=k, t=float(t), **dict(zip(CSV_COLUMNS[1:], map(float, row))))
            if k in invalid:
                payload["x3"] = 5e9  # beyond the contract's limit: the monitor drops it
            data = json.dumps(payload).encode()
            t_ns = int(round(t * 1e9))
            w.write("hydro/rig/g4/sample", data, t_ns, t_ns)
            msgs.append(("hydro/rig/g4/sample", data))
    return msgs


def test_gaps_and_invalid_samples_are_evaluated_as_the_live_monitor_takes_them(g4_run, tmp_path, capsys):
    from hydromon.engine.core import MonitorCore

    p = tmp_path / "gappy.mcap"
    msgs = _gappy_mcap(g4_run, p)
    rec = load_recording(p)
    assert rec.restarts == (400, 570) and rec.missing == 31 and rec.rejected == 1
    ev = evaluate(rec)
    # the live core on the same messages: filters restart at each gap, the estimates carry on
    core = MonitorCore("hydro")
    core.process(msgs)
    live = core.fleet.estimate(core.fleet.ids.index("g4"))
    assert ev.assessment.params == live.params
    assert main(["evaluate", str(p), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["gaps"] == {"count": 2, "missing_samples": 31, "rejected_samples": 1, "duplicate_samples": 0,
                           "out_of_order_samples": 0}
    assert doc["grade"] == "average"
    assert main(["evaluate", str(p)]) == 0
    assert "2 gap(s), 31 sample(s) missing, 1 invalid" in capsys.readouterr().out


def test_csv_gaps_of_whole_periods_restart_the_filters(g4_run, tmp_path):
    keep = np.r_[0:300, 320:len(g4_run.t)]
    p = tmp_path / "gap.csv"
    p.write_text(csv_text(g4_run.t[keep], g4_run.samples[keep]))
    rec = load_recording(p)
    assert rec.restarts == (300,) and rec.missing == 20
    assert evaluate(rec).assessment.grade == "average"


def test_a_restarted_rig_is_refused_with_a_hint(g4_run, tmp_path):
    from hydromon.store.mcap_write import RecordingWriter

    p = tmp_path / "restart.mcap"
    with open(p, "wb") as f, RecordingWriter(f) as w:
        for k in range(6):
            payload = dict(seq=k % 3, t=k * 0.01, ug=2.0, x1=0.0, x3=1e6, x4=1e6, x5=0.0)
            w.write("hydro/rig/a/sample", json.dumps(payload).encode(), k * 10**7, k * 10**7)
    with pytest.raises(ValueError, match="back to 0 at sample 3.*replay --direct"):
        load_recording(p)


def test_refine_on_too_short_a_stretch_keeps_the_evaluation(g4_run, tmp_path, capsys):
    keep = np.r_[0:120, 125:240, 245:300]  # no stretch without a gap is long enough to refine
    p = tmp_path / "short.csv"
    p.write_text(csv_text(g4_run.t[keep], g4_run.samples[keep]))
    assert main(["evaluate", str(p), "--json", "--refine"]) == 1  # 3 s: converging, not graded
    doc = json.loads(capsys.readouterr().out)
    assert doc["grade"] and doc["gaps"]["count"] == 2
    assert doc["refined"]["ok"] is False and "not run" in doc["refined"]["message"]
    assert all(v is None for v in doc["refined"]["std_errors"].values())


def test_plots_show_the_run_the_evaluation_saw(g4_run, tmp_path, capsys):
    from hydromon.report.evaluate_plots import plot_evaluation

    keep = np.r_[0:300, 320:len(g4_run.t)]  # a gap
    samples = g4_run.samples[keep].copy()
    samples[500, 2] += 2e7  # an x3 glitch after the gap
    samples[100, 1] += 0.02  # an x1 glitch before it
    p = tmp_path / "gappy.csv"
    p.write_text(csv_text(g4_run.t[keep], samples))
    ev = evaluate(load_recording(p))
    assert ev.glitches == {"x1": 1, "x3": 1, "x4": 0, "x5": 0}
    summary = plot_evaluation(ev, tmp_path / "plots")
    # the markers are where the stream's gate replaced values, gap and all
    assert summary.glitch_markers == ev.glitches and summary.gaps == 1
    assert summary.evaluations == len(ev.history) >= (len(samples) - 2) // 10 - 1  # one per 10 samples
    assert [f.name for f in summary.files] == ["gappy-csv-grade.png", "gappy-csv-params.png",
                                               "gappy-csv-params-other.png", "gappy-csv-signals.png"]
    for f in summary.files:
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f.stat().st_size > 10_000
    # a rig with no ranges made for it: every parameter in one figure, not graded
    from dataclasses import replace

    ungraded = plot_evaluation(replace(ev, ranges=None), tmp_path / "ungraded")
    assert [f.name for f in ungraded.files] == ["gappy-csv-grade.png", "gappy-csv-params.png",
                                                "gappy-csv-signals.png"]
    # the CLI writes the same three and says where
    assert main(["evaluate", str(p), "--plots", str(tmp_path / "cli")]) == 0
    err = capsys.readouterr().err
    assert err.count("wrote") == 4 and sorted(x.name for x in (tmp_path / "cli").iterdir()) == \
        sorted(f.name for f in summary.files)


def test_an_x1_beyond_a_chamber_is_reported(g4_run, capsys):
    """Not physical: the rig constants or x1's zero/sign/unit are wrong; say so, do not hide it."""
    from hydromon.contract import RigConfig
    from hydromon.engine.record import Recording
    from hydromon.report.evaluate import render, to_json

    cfg = RigConfig(V10=0.0004)  # chamber 1 empties at x1 = -V10 / A1 = -0.05 m
    s = g4_run.samples.copy()
    assert to_json(evaluate(Recording("r", g4_run.t, s, cfg, "<test>")))["x1_outside_chambers"] == 0
    s[:, 1] -= 0.08  # x1 from the other end: every sample below -0.05 m until x1 > 0.03 m
    from monitor.identify import V_MIN

    # clamped below 1 % of V10 (V_MIN); the gate holds the last two samples
    expected = int(np.sum(g4_run.samples[:-2, 1] - 0.08 < -(1 - V_MIN) * 0.05))
    ev = evaluate(Recording("r", g4_run.t, s, cfg, "<test>"))
    assert expected > 100 and to_json(ev)["x1_outside_chambers"] == ev.x1_clamped == expected
    render(ev)
    out = capsys.readouterr().out
    assert "at a chamber's end" in out and "x1 < -0.0495 m" in out


def test_plot_markers_count_a_burst_the_gate_still_holds(g4_run, tmp_path):
    from hydromon.report.evaluate_plots import plot_evaluation

    keep = np.r_[0:400, 420:len(g4_run.t)]
    samples = g4_run.samples[keep].copy()
    # bursts judged by the last sample before the gap and by the record's last sample: the
    # second of each is replaced (and counted) where the gate holds it, and never released
    samples[397:399, 2] += 2e7
    samples[-3:-1, 3] -= 2e7
    p = tmp_path / "bursts.csv"
    p.write_text(csv_text(g4_run.t[keep], samples))
    ev = evaluate(load_recording(p))
    assert ev.glitches == {"x1": 0, "x3": 2, "x4": 2, "x5": 0}
    assert plot_evaluation(ev, tmp_path / "plots").glitch_markers == ev.glitches


def test_plots_into_a_file_is_refused_before_the_evaluation(g4_csv, tmp_path, capsys, monkeypatch):
    # an existing file as --plots is refused before the evaluation, not after (minutes with
    # --refine), as audit --report and reproduce --plots are
    import hydromon.engine.evaluate

    target = tmp_path / "a-file"
    target.write_text("")
    monkeypatch.setattr(hydromon.engine.evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated"))
    assert main(["evaluate", str(g4_csv), "--json", "--refine", "--plots", str(target)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip() == f"hydromon evaluate: error: --plots {str(target)!r} exists and is not a directory"


def test_a_plotting_error_comes_after_the_result(g4_csv, tmp_path, capsys, monkeypatch):
    import hydromon.report.evaluate_plots

    def fail(result, directory):
        raise ValueError(f"plots directory {str(directory)!r}: No space left on device")

    monkeypatch.setattr(hydromon.report.evaluate_plots, "plot_evaluation", fail)
    assert main(["evaluate", str(g4_csv), "--json", "--plots", str(tmp_path / "plots")]) == 2
    captured = capsys.readouterr()
    assert json.loads(captured.out)["grade"] == "average"  # the evaluation is not lost
    assert "plots directory" in captured.err


def test_cli_ranges_choose_what_grades_the_valve(g4_csv, capsys, tmp_path):
    from monitor.ranges import Ranges

    grades = {}
    for spec in ("default", "paper"):
        assert main(["evaluate", str(g4_csv), "--ranges", spec]) == 0
        grades[spec] = capsys.readouterr().out
    # the table's grade column: K_sv graded by default, K_sv omega^2 by Table 3 as printed
    def grade(out, k):  # the grade cell of parameter k's row in the rich table
        for line in out.splitlines():
            cells = [c.strip() for c in line.split("\u2502")]
            if len(cells) > 2 and cells[1] == k:
                return cells[-2]
        raise AssertionError(f"no row {k}")

    assert grade(grades["default"], "K_sv") == "average"  # Table 4 group 4: K_sv omega^2 1.6
    assert grade(grades["default"], "K_sv_omega_sv2") == ""
    assert grade(grades["paper"], "K_sv_omega_sv2") == "average" and grade(grades["paper"], "K_sv") == ""
    assert Ranges.resolve("paper") == Ranges.paper() and Ranges.resolve("default") == Ranges.default()
    (tmp_path / "r.json").write_text("{}")
    (tmp_path / "latin1.json").write_bytes(b"\xe9")
    with pytest.raises(ValueError, match="bad ranges file"):
        Ranges.resolve(tmp_path / "r.json")
    # unreadable ranges (missing, a directory, not UTF-8): a clear error naming it, exit 2
    for bad in (tmp_path / "missing.json", tmp_path, tmp_path / "latin1.json"):
        assert main(["evaluate", str(g4_csv), "--ranges", str(bad)]) == 2
        assert f"ranges file '{bad}'" in capsys.readouterr().err


def test_the_valve_note_is_in_the_docs_not_at_the_end_of_every_evaluation(tmp_path, capsys):
    """What the valve is graded on is said once, in docs/method.md; an evaluation shows the
    omega^2 standard error that tells an unexcited valve."""
    from pathlib import Path

    from plant_sim.noise import noise_model
    from plant_sim.profiles import PaperIdentification

    run = simulate(PaperIdentification(), 11.0, noise=noise_model("realistic"), seed=0)
    p = tmp_path / "midrun.csv"
    p.write_text(csv_text(run.t[100:] - run.t[100], run.samples[100:]))
    assert main(["evaluate", str(p)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "graded on its static gain" not in out and "omega_sv2" in out
    method = (Path(__file__).resolve().parents[2] / "docs" / "method.md").read_text()
    assert "## The valve is graded on its static gain" in method
    assert "K_sv omega^2 is still identified and reported" in method


@pytest.mark.parametrize("converged, level, implausible, status", [
    (True, 2, (), "ok"),
    (True, -1, (), "converging"),  # converged but no grade placed: the live monitor says converging
    (False, -1, (), "converging"),
    (True, -1, ("B_fv",), "bad-input"),
])
def test_status_follows_the_live_monitors_rule(converged, level, implausible, status):
    from hydromon.engine.evaluate import Evaluation
    from monitor.evaluations import Assessment

    a = Assessment(count=1000, level=level, confidence=0.0, params={}, std_errors={}, param_levels={},
                   converged=converged, implausible=implausible)
    assert Evaluation(recording=None, assessment=a).status == status
