"""``hydromon audit`` refuses a record it cannot fit, or a path it must not read, with one line
naming the file and why (exit status 2)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from hydromon.cli.main import main


def _moving_csv(path, mutate=lambda a: a, rows=None):
    """A 5 s clean record of the reference rig as a CSV (t,ug,x1,x3,x4,x5), ``mutate``d."""
    from hydromon.tools.audit_sweep import _record

    s, cfg = _record("clean", {}, "paper-var", 0.3, "realistic", 5, duration=5.0)
    a = mutate(np.column_stack([cfg.h * np.arange(len(s)), s]))[:rows]
    path.write_text("t,ug,x1,x3,x4,x5\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in a))
    return path


def _set(col, value):
    def mutate(a):
        a[:, col] = value if not callable(value) else value(a)
        return a
    return mutate


@pytest.mark.parametrize("mutate, rows, needle", [
    (_set(5, 0.0), None, "rec.csv: x5 is 0 in every sample: a sensor that is not logged, stuck"),
    (_set(3, 4e6), None, "rec.csv: x3 is 4e+06 in every sample"),
    (_set(4, lambda a: a[:, 3]), None, "rec.csv: the audit's equations cannot be solved on this record"),
    (lambda a: a, 100, "rec.csv: need at least 250 samples, got 100"),
    (lambda a: (a.__setitem__((slice(300, 340), 2), 0.0), a)[1], None,
     "rec.csv: x1 jumps -43.8 mm from sample 300 to 339 (t = 3.00-3.39 s) and back"),
    (_set(1, 2.5), None, "rec.csv: the rig is held at one command in the fitting part (t = 0.00-3.49 s)"),
    (_set(3, lambda a: a[:, 3] / 1e5), None, "rec.csv: x3 never exceeds"),  # x3 in bar, x4 in Pa
    (_set(5, lambda a: a[:, 5] * 100), None, "rec.csv: x5 reaches"),
])
def test_audit_of_a_record_it_cannot_fit_names_the_file_and_why(tmp_path, capsys, mutate, rows, needle):
    """A dead sensor, two pressures that read as one, too short a record, a dropout of x1, a command
    held at one value or a channel in other units than SI: one line naming the file, not numpy's
    "Singular matrix", an equation's row count alone, or a cause the record cannot show."""
    _moving_csv(tmp_path / "rec.csv", mutate, rows)
    assert main(["audit", str(tmp_path / "rec.csv")]) == 2
    cap = capsys.readouterr()
    # the line before it says the paper's rig constants are used (a CSV carries none)
    assert cap.out == "" and "the paper's rig constants" in cap.err.splitlines()[0], cap.err
    err = cap.err.splitlines()[-1]
    assert err.startswith("hydromon audit: error: ") and needle in err and err.count("rec.csv") == 1, err


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_audit_refuses_a_pipe_or_a_device_before_reading_it(tmp_path, capsys):
    fifo = tmp_path / "f.csv"
    os.mkfifo(fifo)  # with no writer: reading it would block forever
    (tmp_path / "zero.csv").symlink_to("/dev/zero")  # read to the end, it never ends
    for path in (fifo, tmp_path / "zero.csv"):
        assert main(["audit", str(path)]) == 2
        cap = capsys.readouterr()
        assert cap.out == "" and cap.err == (f"hydromon audit: error: {path}: is not a regular file (a device or a "
                                             "pipe); give a .csv or .mcap file\n"), cap.err


@pytest.mark.parametrize("argv, needle", [
    (["--report", ""], "--report '': give the directory to write the report into"),
    (["--train-fraction", "0.1"], "--train-fraction 0.1: train_fraction must lie in [0.2, 0.9]"),
])
def test_audit_refuses_an_empty_report_directory_and_a_fraction_outside_its_range(tmp_path, capsys, argv, needle):
    """``--report ''`` wrote no report and said nothing; the fraction's range is in --help too."""
    path = _moving_csv(tmp_path / "rec.csv")
    assert main(["audit", str(path), *argv]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.count("\n") == 1, cap.err
    assert cap.err.startswith(f"hydromon audit: error: {needle}"), cap.err
    with pytest.raises(SystemExit):
        main(["audit", "--help"])
    assert "(0.2-0.9; default 0.7)" in capsys.readouterr().out


def test_a_lone_sensor_glitch_is_replaced_as_the_live_monitor_replaces_it_and_said(tmp_path, capsys):
    """A one-sample spike (x1 1 m, x3 900 MPa) is the live monitor's outlier gate's to mend: the
    audit goes on with the neighbours' mean there and says how many it replaced."""
    def spikes(a):
        a[300, 2], a[200, 3] = 1.0, 9e8
        return a
    path = _moving_csv(tmp_path / "rec.csv", spikes)
    assert main(["audit", str(path)]) == 0
    out = capsys.readouterr().out
    assert "sensor glitches replaced by their neighbours' mean before the audit: x1 1, x3 1" in out, out
    assert main(["audit", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["glitches_replaced"] == {"x1": 1, "x3": 1, "x4": 0, "x5": 0}
