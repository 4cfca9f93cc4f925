"""hydromon evaluate: input loading as the live monitor takes a stream (seq, configs) and clear
errors for files that are not what they claim (units, encodings, missing files)."""

import json
from pathlib import Path

import numpy as np
import pytest

from hydromon.cli.main import main
from hydromon.contract import SAMPLE_COLUMNS as CSV_COLUMNS
from hydromon.contract import RigConfig
from hydromon.engine.evaluate import evaluate
from hydromon.report.evaluate import render, to_json
from hydromon.store.csvfile import csv_text
from hydromon.store.recording import load_recording
from plant_sim.degradation import table4_group
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate

GOLDEN_GAP_RESTART = Path(__file__).resolve().parents[2] / "recordings" / "gap-restart.mcap"
SAMPLE_KEY, CONFIG_KEY = "hydro/rig/g4/sample", "hydro/rig/g4/config"


@pytest.fixture(scope="module")
def run():
    return simulate(PaperVariable(), 6.0, params=table4_group(4))


def _messages(run, seqs=None, times=None, configs=()):
    """The run as bus messages ``(key, payload, log_time_ns)``: sample k with seq ``seqs[k]`` and
    time stamp ``times[k]`` (default k and the run's t); ``configs`` = [(k, RigConfig)] go just
    before sample k."""
    seqs = range(len(run.t)) if seqs is None else seqs
    times = run.t if times is None else times
    before = dict(configs)
    out = []
    for k, (seq, t, row) in enumerate(zip(seqs, times, run.samples)):
        log_ns = round(run.t[k] * 1e9)  # received on the recorder's clock
        if k in before:
            out.append((CONFIG_KEY, json.dumps(before[k].model_dump(mode="json")).encode(), log_ns))
        payload = dict(seq=int(seq), t=float(t), **dict(zip(CSV_COLUMNS[1:], map(float, row))))
        out.append((SAMPLE_KEY, json.dumps(payload).encode(), log_ns))
    return out


def _mcap(path, messages):
    from hydromon.store.mcap_write import RecordingWriter

    with open(path, "wb") as f, RecordingWriter(f) as w:
        for key, payload, log_ns in messages:
            w.write(key, payload, log_ns, log_ns)
    return path


def _text(out: str) -> str:
    """Console output with rich's line wrapping undone."""
    return " ".join(out.split())


def _live(messages):
    """The live monitor core's last estimates of rig g4 after these messages."""
    from hydromon.engine.core import MonitorCore

    core = MonitorCore("hydro")
    core.process([(k, p) for k, p, _ in messages])
    return core, core.fleet.estimate(core.fleet.ids.index("g4")).params


# -- 1: seq before time stamps; a duplicate is not a restart --------------------------------------

def test_the_golden_restart_recording_gets_the_restart_hint():
    # before: "t = 0.0 s does not increase strictly (previous 10.49 s)"
    with pytest.raises(ValueError, match=r"seq goes from 1049 back to 0 at sample 1000 .*the rig restarted.*"
                                         r"replay --direct"):
        load_recording(GOLDEN_GAP_RESTART)


def test_a_duplicate_seq_is_dropped_and_counted_as_the_live_monitor_does(run, tmp_path, capsys):
    seqs = np.arange(len(run.t))
    seqs[301] = 300  # 299, 300, 300, 302: a duplicate, then one sample missing
    seqs[451] = 200  # a stale, out-of-order one
    msgs = _messages(run, seqs)
    p = _mcap(tmp_path / "dup.mcap", msgs)
    rec = load_recording(p)
    assert (rec.duplicate, rec.out_of_order) == (1, 1)
    assert rec.restarts == (301, 450) and rec.missing == 2 and len(rec.samples) == len(run.t) - 2
    core, live = _live(msgs)
    assert (core.counters.duplicate, core.counters.out_of_order, core.counters.restarts) == (1, 1, 0)
    ev = evaluate(rec)
    assert ev.assessment.params == live
    assert to_json(ev)["gaps"] == {"count": 2, "missing_samples": 2, "rejected_samples": 0,
                                   "duplicate_samples": 1, "out_of_order_samples": 1}
    render(ev)
    assert "1 duplicate and 1 out-of-order sample(s) dropped" in _text(capsys.readouterr().out)


# -- 2: an MCAP is graded by seq; time stamp jitter is counted -------------------------------------

def test_mcap_time_stamp_jitter_is_counted_not_refused(run, tmp_path, capsys):
    times = run.t.copy()
    times[300] += 0.0003  # 0.0103 s after the previous sample: 3 % of a period
    msgs = _messages(run, times=times)
    rec = load_recording(_mcap(tmp_path / "jitter.mcap", msgs))
    assert rec.jitter == 2 and rec.jitter_max == pytest.approx(3e-4) and not rec.restarts
    ev = evaluate(rec)
    assert ev.assessment.params == _live(msgs)[1]
    assert to_json(ev)["timestamp_jitter"] == {"intervals": 2, "max_s": rec.jitter_max}
    render(ev)
    out = _text(capsys.readouterr().out)
    assert "2 sample interval(s) with time stamps off their seq step" in out and "largest 0.3 ms" in out


# -- 3: a config change mid-record: the part after it, with its constants ---------------------------

def test_a_config_change_evaluates_the_samples_after_it_with_the_new_constants(run, tmp_path, capsys):
    new = RigConfig(F_L=3000.0)
    msgs = _messages(run, configs=[(0, RigConfig()), (250, new)])
    p = _mcap(tmp_path / "cfg.mcap", msgs)
    rec = load_recording(p)
    # before: all 600 samples, with the last config
    assert rec.config == new and (rec.config_changes, rec.skipped) == (1, 250)
    np.testing.assert_array_equal(rec.samples, run.samples[250:])
    core, live = _live(msgs)
    assert core.counters.config_changes == 1
    ev = evaluate(rec)
    assert ev.assessment.params == live  # as the live monitor, which restarted the rig's estimates there
    assert to_json(ev)["config_changes"] == {"count": 1, "skipped_samples": 250}
    assert main(["evaluate", str(p)]) == 1  # 3.5 s on ranges not made for F_L 3000 N: not graded to be trusted
    cap = capsys.readouterr()
    out = _text(cap.out)
    assert "rig g4: 350 samples, 3.5 s" in out
    assert "config changed 1 time(s)" in out and "the 250 sample(s) before it were skipped" in out
    assert "250 before its last config change skipped" in cap.err


def test_a_first_config_that_comes_mid_record_is_a_change_as_live(run, tmp_path):
    # a recorder that joined a running rig has no config before its first sample; the first
    # config (at sample 250) is a change, as it is live (the monitor restarts the rig there), not
    # the one in force from the start (which would grade all 600 samples with it)
    msgs = _messages(run, configs=[(250, RigConfig(F_L=3000.0))])
    rec = load_recording(_mcap(tmp_path / "late.mcap", msgs))
    core, live = _live(msgs)
    assert core.counters.config_changes == 1 and (rec.config_changes, rec.skipped) == (1, 250)
    assert evaluate(rec).assessment.params == live


def test_a_config_repeated_unchanged_splits_nothing(run, tmp_path):
    msgs = _messages(run, configs=[(0, RigConfig()), (250, RigConfig())])
    rec = load_recording(_mcap(tmp_path / "same.mcap", msgs))
    assert (rec.config_changes, rec.skipped, len(rec.samples)) == (0, 0, len(run.t))


# -- 4: a CSV at another unit or rate is refused; the header's duration is the span -----------------

@pytest.mark.parametrize("scale, hint", [
    (1000.0, r"line 3: t = 10.0 s is 10.0 s after .*median interval is 10 s.*looks like milliseconds; give t in s"),
    (2.0, r"line 3: .*every 0.01 s \(100 Hz\): the file looks sampled at 50 Hz"),
    (0.5, r"line 3: .*every 0.01 s \(100 Hz\): the file looks sampled at 200 Hz"),
])
def test_csv_in_another_unit_or_rate_is_a_clear_error(run, tmp_path, scale, hint):
    p = tmp_path / "odd.csv"
    p.write_text(csv_text(run.t[:50] * scale, run.samples[:50]))
    with pytest.raises(ValueError, match=hint):  # before (ms, 50 Hz): accepted, all gaps
        load_recording(p)


def test_header_duration_is_the_span_gaps_included(run, tmp_path, capsys):
    keep = np.r_[0:100, 120:len(run.t)]
    p = tmp_path / "gap.csv"
    p.write_text(csv_text(run.t[keep], run.samples[keep]))
    rec = load_recording(p)
    assert rec.duration == pytest.approx(6.0) and rec.missing == 20
    render(evaluate(rec))
    assert "rig csv: 580 samples, 6 s" in _text(capsys.readouterr().out)  # before: 5.8 s


# -- 5: encodings, missing and binary files, names in messages --------------------------------------

GOOD = "t,ug,x1,x3,x4,x5\n0.0,2,0,1e6,1e6,0\n0.01,2,0,1e6,1e6,0\n0.02,2,0,1e6,1e6,0\n"


def test_csv_with_a_byte_order_mark_is_read(tmp_path):
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    assert load_recording(p).samples.shape == (3, 5)


@pytest.mark.parametrize("cut, error", [("0.03,2,0,1e6", "4 fields"), ("0.03,2,0,1e6,1e6,0", None),
                                        ("0.03,2,0,1e6,1e6,1.", "beyond the contract's limit")])
def test_a_csv_cut_mid_line_says_so(tmp_path, cut, error):
    # a logger killed mid-write: the error named a field (for x5 with a units hint) and not the cut
    p = tmp_path / "cut.csv"
    p.write_text(GOOD + cut)
    if error is None:  # a cut that leaves a valid row cannot be told from one: read as it is
        assert load_recording(p).samples.shape == (4, 5)
        return
    with pytest.raises(ValueError, match=rf"line 5: .*{error}.*last line and has no line end: was the file cut short"):
        load_recording(p)
    p.write_text(GOOD + cut + "\n")  # the same line, terminated: the plain error
    with pytest.raises(ValueError, match=error) as exc:
        load_recording(p)
    assert "cut short" not in str(exc.value)


def test_missing_and_binary_csv_errors_name_the_file(tmp_path, capsys):
    missing = tmp_path / "missing.csv"
    assert main(["evaluate", str(missing)]) == 2
    assert capsys.readouterr().err.strip() == f"hydromon evaluate: error: {missing}: no such file"
    binary = tmp_path / "bin.csv"
    binary.write_bytes(GOOD.encode() + b"0.03,\x89PNG\n")
    with pytest.raises(ValueError, match=rf"^{binary} line 5: byte 0x89 is not UTF-8 text"):
        load_recording(binary)
    folder = tmp_path / "folder.csv"
    folder.mkdir()
    with pytest.raises(ValueError, match=rf"^{folder}: is a directory; give a recording"):
        load_recording(folder)
    with pytest.raises(ValueError, match=rf"^{tmp_path}: is a directory; give a recording"):
        load_recording(tmp_path)  # no suffix: said so, not "unknown file type ''"
    with pytest.raises(ValueError, match=r"^/dev/null: not a regular file"):
        load_recording("/dev/null")


def test_mcap_errors_name_the_file_once(run, tmp_path):
    p = _mcap(tmp_path / "cut.mcap", _messages(run)[:50])
    p.write_bytes(p.read_bytes()[:-100])
    with pytest.raises(ValueError) as exc:
        load_recording(p)
    assert str(exc.value).startswith(f"{p}: recording has no footer") and f"{p}: {p}" not in str(exc.value)


@pytest.mark.parametrize("case", ["duplicate across the change", "gap across the change", "stale seq after it"])
def test_seq_tracking_runs_on_through_a_config_change_as_live(run, tmp_path, case):
    # the seq checks run on the whole record, not on the part after the change only: a duplicate
    # of the last seq before it is dropped, and a gap across it is counted
    seqs = list(range(len(run.t)))
    if case == "duplicate across the change":
        seqs = seqs[:250] + [249] + seqs[250:-1]
    elif case == "gap across the change":
        seqs = seqs[:240] + [s + 20 for s in seqs[240:]]
    else:
        seqs = seqs[:250] + [100] + seqs[250:-1]
    msgs = _messages(run, seqs=seqs, configs=[(0, RigConfig()), (250, RigConfig(F_L=3000.0))])
    rec = load_recording(_mcap(tmp_path / "c.mcap", msgs))
    core, live = _live(msgs)
    c = core.counters
    assert (rec.duplicate, rec.out_of_order, rec.missing) == (c.duplicate, c.out_of_order, c.missing), case
    assert evaluate(rec).assessment.params == live, case


def test_a_duplicate_seq_0_after_a_restart_is_a_duplicate_as_live(run, tmp_path):
    # restarts are found against the last seq, not the highest so far: the second seq 0 of
    # 300..., 0, 0, 1, ... is a duplicate (live drops it), not another restart
    n = len(run.t)
    seqs = list(range(300)) + [0, 0] + list(range(1, n - 302 + 1))
    msgs = _messages(run, seqs=seqs, configs=[(0, RigConfig()), (301, RigConfig(F_L=3000.0))])
    rec = load_recording(_mcap(tmp_path / "r.mcap", msgs))
    core, live = _live(msgs)
    assert rec.duplicate == core.counters.duplicate == 1
    assert evaluate(rec).assessment.params == live


def test_a_config_at_another_sample_rate_is_ignored_as_live_rejects_it(run, tmp_path):
    msgs = _messages(run, configs=[(0, RigConfig()), (300, RigConfig(sample_rate=200.0))])
    rec = load_recording(_mcap(tmp_path / "rate.mcap", msgs))
    core, live = _live(msgs)
    assert core.counters.config_changes == 0 and rec.config_changes == 0
    assert evaluate(rec).assessment.params == live


def test_a_restart_whose_seq_0_was_lost_is_found_as_live_finds_it(run, tmp_path):
    # the live monitor takes a run of seqs below the last one as a restart whose first samples were
    # lost (hydromon.engine.core); evaluate refuses that restart as it refuses a seq 0, instead of grading
    # the old run's estimates on into the new one
    from hydromon.contract import RESTART_RUN

    n = len(run.t)
    seqs = list(range(300)) + list(range(20, 20 + n - 300))
    msgs = _messages(run, seqs=seqs)
    core, _ = _live(msgs)
    assert core.counters.restarts == 1
    with pytest.raises(ValueError, match=rf"seq goes from 299 back to {20 + RESTART_RUN - 1} at sample "
                                         rf"{300 + RESTART_RUN - 1} .*replay --direct"):
        load_recording(_mcap(tmp_path / "lost0.mcap", msgs))


def test_an_invalid_config_message_is_refused_not_graded_on_other_constants(run, tmp_path, capsys):
    bad = {**RigConfig(p_s=16e6).model_dump(mode="json"), "p_s": "16MPa"}  # a unit string: --config's form only
    msgs = [(CONFIG_KEY, json.dumps(bad).encode(), 0)] + _messages(run)
    path = _mcap(tmp_path / "badcfg.mcap", msgs)
    with pytest.raises(ValueError, match=r"config message on hydro/rig/g4/config at log time 0 ns is not a valid "
                                         r"rig config \(p_s: .*--config FILE"):
        load_recording(path)
    assert load_recording(path, config=RigConfig(p_s=16e6)).config.p_s == 16e6  # the constants given instead
    assert main(["evaluate", str(path)]) == 2
    assert "is not a valid rig config" in _text(capsys.readouterr().err)


def test_mcap_samples_that_are_all_invalid_say_why(run, tmp_path):
    msgs = [(k, p[:-1] + b', "temp": 41.5}', t) for k, p, t in _messages(run)]  # a field the contract lacks
    with pytest.raises(ValueError, match=r"rig 'g4' has no valid samples: all 600 were invalid, the first bad "
                                         r"sample .*temp.*Extra inputs are not permitted"):
        load_recording(_mcap(tmp_path / "extra.mcap", msgs))


def test_an_mcap_whose_config_rate_its_time_stamps_contradict_is_refused(run, tmp_path):
    msgs = _messages(run, configs=[(0, RigConfig(sample_rate=50.0))])  # samples 10 ms apart
    with pytest.raises(ValueError, match=r"rig 'g4': its time stamps step 0\.01 s per seq, but its config says the "
                                         r"rig samples every 0\.02 s \(50 Hz\): the file looks sampled at 100 Hz"):
        load_recording(_mcap(tmp_path / "rate50.mcap", msgs))
    jittered = _messages(run, times=run.t + np.random.default_rng(3).uniform(-2e-3, 2e-3, len(run.t)))
    rec = load_recording(_mcap(tmp_path / "jitter.mcap", jittered))  # jitter is counted, not refused
    assert rec.jitter > 0


def test_not_converged_says_whether_the_record_is_too_short_or_lacks_motion(tmp_path, capsys):
    noise = np.random.default_rng(1).normal(size=(2000, 5)) * [0.0, 5e-6, 5e3, 5e3, 5e-7]  # realistic sensors
    still = np.tile([0.4, 0.01, 5e6, 4e6, 0.0], (2000, 1)) + noise  # a rig held still for 20 s: no motion
    (tmp_path / "still.csv").write_text(csv_text(np.arange(2000) / 100.0, still))
    main(["evaluate", str(tmp_path / "still.csv")])
    out = _text(capsys.readouterr().out)
    assert "this record has 2000 samples, which would be enough: what it lacks is motion" in out, out
    (tmp_path / "short.csv").write_text(csv_text(np.arange(300) / 100.0, still[:300]))
    main(["evaluate", str(tmp_path / "short.csv")])
    assert "this record has 300 samples: give a longer one" in _text(capsys.readouterr().out)


def test_a_record_whose_readings_repeat_one_reading_is_not_to_be_trusted(run, tmp_path, capsys):
    frozen = np.tile([0.4, 0.01, 5e6, 4e6, 0.0], (2000, 1))  # one sample, 2000 times: it fits a still rig
    (tmp_path / "frozen.csv").write_text(csv_text(np.arange(2000) / 100.0, frozen))
    assert main(["evaluate", str(tmp_path / "frozen.csv"), "--json"]) == 1
    got = json.loads(capsys.readouterr().out)
    assert got["status"] == "bad-input" and got["frozen"].startswith("ug, x1, x3, x4 and x5 repeat one reading "
                                                                     "for 19.99 s from sample 0"), got
    s = run.samples.copy()
    s[200:400] = s[199]  # a 2 s stall in a real record
    rec = load_recording((tmp_path / "stall.csv").write_text(csv_text(run.t, s)) and tmp_path / "stall.csv")
    assert evaluate(rec).status == "bad-input"
    s[200:399] = s[199]
    (tmp_path / "short-stall.csv").write_text(csv_text(run.t, s[:399]))
    assert evaluate(load_recording(tmp_path / "short-stall.csv")).frozen is None  # 1.99 s: not a stall yet


@pytest.mark.parametrize("value, said", [('"16MPa"', r"is not a valid rig config \(p_s: "), ("{nope", "is not JSON")])
def test_invalid_rig_config_metadata_is_a_clear_error_naming_it(run, tmp_path, value, said):
    from hydromon.store.mcap_write import RecordingWriter

    path = tmp_path / "meta.mcap"
    with open(path, "wb") as f, RecordingWriter(f) as w:
        w._writer.add_metadata("rig_config/g4", {"p_s": value})  # as another tool might have written it
        for key, payload, log_ns in _messages(run):
            w.write(key, payload, log_ns, log_ns)
    with pytest.raises(ValueError, match=rf"the rig config stored as metadata rig_config/g4 \(record 0\) {said}"):
        load_recording(path)
