"""Command-line validation: options are checked before any side effect (file, bus, banner,
long work), an error is one line on stderr with exit status 2, and a failed run never
truncates, half-writes or replaces a user's file."""

from __future__ import annotations

import io
import math
import os
import socket

import numpy as np
import pytest

from hydromon.cli.main import main

pytestmark = pytest.mark.timeout(60)

KEEP = "t,ug,x1,x3,x4,x5\n0.0,1.0,2.0,3.0,4.0,5.0\n"


def one_error_line(capsys, command: str, *needles: str) -> str:
    """stderr is exactly one line ``hydromon COMMAND: error: ...`` holding every needle; stdout empty."""
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert cap.out == ""
    assert "\n" not in err, err
    assert err.startswith(f"hydromon {command}: error: "), err
    for n in needles:
        assert n in err, (n, err)
    return err


def no_leftovers(directory) -> None:
    assert not [p for p in os.listdir(directory) if p.endswith(".part")]


@pytest.fixture
def no_bus(monkeypatch):
    """Opening a zenoh session fails the test: every check must come first."""
    def refuse(*_a, **_k):
        raise AssertionError("the bus was opened before the options were checked")

    for mod in ("sim", "monitor", "replay", "record"):
        monkeypatch.setattr(f"hydromon.cli.commands.{mod}.session_from_args", refuse)


# -- 1. sim --to-csv / --to-mcap: no data loss ---------------------------------------------

@pytest.mark.parametrize("extra, needle", [
    (["--rig", "nope"], "no rig 'nope' in the fleet"),
    (["--rig", "table4-g1", "--duration", "inf"], "--duration inf must be a finite number > 0 s"),
    (["--rig", "table4-g1", "--duration", "0.001"], "shorter than one sample"),
])
def test_sim_to_csv_error_keeps_the_existing_file(tmp_path, capsys, extra, needle):
    keep = tmp_path / "keep.csv"
    keep.write_text(KEEP)
    args = ["sim", "--to-csv", str(keep), "--duration", "10", *extra]
    assert main(args) == 2
    one_error_line(capsys, "sim", needle)
    assert keep.read_text() == KEEP
    no_leftovers(tmp_path)


@pytest.mark.parametrize("duration", ["inf", "nan", "0", "-1"])
def test_sim_to_mcap_bad_duration_keeps_the_existing_file(tmp_path, capsys, duration):
    precious = tmp_path / "precious.mcap"
    precious.write_bytes(b"precious")
    assert main(["sim", "--to-mcap", str(precious), "--duration", duration]) == 2
    one_error_line(capsys, "sim", f"--duration {float(duration)!r} must be a finite number > 0 s")
    assert precious.read_bytes() == b"precious"
    no_leftovers(tmp_path)


@pytest.mark.parametrize("failure, status", [(RuntimeError("disk on fire"), None), (KeyboardInterrupt(), 130)])
def test_sim_failure_mid_write_leaves_the_old_file(tmp_path, monkeypatch, failure, status):
    from hydromon.store import simfiles

    def half_then_fail(spec, duration, stream, namespace="hydro", on_block=None, frame=None):
        stream.write(b"\x89MCAP0\r\n half a recording")
        raise failure

    monkeypatch.setattr(simfiles, "write_mcap", half_then_fail)
    precious = tmp_path / "precious.mcap"
    precious.write_bytes(b"precious")
    args = ["sim", "--to-mcap", str(precious), "--duration", "1"]
    if status is None:
        with pytest.raises(RuntimeError):
            main(args)
    else:
        assert main(args) == status
    assert precious.read_bytes() == b"precious"
    no_leftovers(tmp_path)


def test_sim_success_replaces_the_file_keeping_its_mode(tmp_path, capsys):
    out = tmp_path / "run.csv"
    out.write_text("old\n" * 1000)
    out.chmod(0o640)
    assert main(["sim", "--rigs", "1", "--duration", "0.05", "--to-csv", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "t,ug,x1,x3,x4,x5" and len(lines) == 6
    assert out.stat().st_mode & 0o777 == 0o640
    no_leftovers(tmp_path)
    new = tmp_path / "new.csv"
    assert main(["sim", "--rigs", "1", "--duration", "0.05", "--to-csv", str(new)]) == 0
    umask = os.umask(0)
    os.umask(umask)
    assert new.stat().st_mode & 0o777 == 0o666 & ~umask  # as open() would have made it


def test_sim_to_mcap_honours_rig(tmp_path, capsys):
    from hydromon.store import mcap_read

    whole, one = tmp_path / "whole.mcap", tmp_path / "one.mcap"
    assert main(["sim", "--to-mcap", str(whole), "--duration", "0.1"]) == 0
    assert main(["sim", "--to-mcap", str(one), "--duration", "0.1", "--rig", "table4-g3"]) == 0
    assert "11 messages of 1 rig(s)" in capsys.readouterr().err
    rig, data, _ = mcap_read.read_samples(str(one))  # one rig: no --rig needed
    assert rig == "table4-g3"
    _, ref, _ = mcap_read.read_samples(str(whole), rig="table4-g3")
    np.testing.assert_array_equal(data, ref)  # the run it has in the whole fleet's
    assert mcap_read.read_rig_config(str(one), "table4-g3") is not None


@pytest.mark.parametrize("args, needle", [
    (["--to-csv", "{d}/no/such/dir/x.csv", "--rigs", "1"], "directory '{d}/no/such/dir' does not exist"),
    (["--to-csv", "{d}", "--rigs", "1"], "is a directory"),
    (["--to-csv", "{d}/a", "--to-mcap", "{d}/a", "--rigs", "1"], "name the same file"),
    (["--to-mcap", "{d}/x.mcap", "--block", "0"], "--block 0 must be >= 1"),
])
def test_sim_file_errors(tmp_path, capsys, args, needle):
    d = str(tmp_path)
    assert main(["sim", "--duration", "1", *[a.format(d=d) for a in args]]) == 2
    one_error_line(capsys, "sim", needle.format(d=d))
    assert os.listdir(tmp_path) == []


def test_sim_simnode_refuses_an_infinite_duration():
    from hydromon.store import simfiles
    from hydromon.store.fleetfile import default_fleet

    with pytest.raises(ValueError, match="finite"):
        simfiles.write_csv(default_fleet(), math.inf, io.StringIO(), rig="table4-g1")
    buf = io.BytesIO()
    with pytest.raises(ValueError, match="finite"):
        simfiles.write_mcap(default_fleet(), math.inf, buf)
    assert buf.getvalue() == b""  # nothing written before the check


# -- 2. calibrate: --out and --noise before the runs ---------------------------------------

@pytest.fixture
def no_runs(monkeypatch):
    def refuse(*_a, **_k):
        raise AssertionError("runs simulated before the options were checked")

    monkeypatch.setattr("monitor.calibrate.simulate_runs", refuse)


@pytest.mark.parametrize("args, needle", [
    (["--out", "/nonexistdir2/x.json"], "--out '/nonexistdir2/x.json': directory '/nonexistdir2' does not exist"),
    (["--out", "{d}"], "is a directory; give a file name"),
    (["--noise", "bogus", "--out", "-"], "unknown noise model 'bogus'"),
    (["--noise", "pct:200", "--out", "-"], "percentage must lie in [0, 100)"),
])
def test_calibrate_checks_before_the_runs(tmp_path, capsys, no_runs, args, needle):
    assert main(["calibrate", "--runs", "200", *[a.format(d=tmp_path) for a in args]]) == 2
    one_error_line(capsys, "calibrate", needle)


# -- 3. demo --out ---------------------------------------------------------------------------

@pytest.fixture
def no_demo(monkeypatch):
    def refuse(*_a, **_k):
        raise AssertionError("demo started before the options were checked")

    monkeypatch.setattr("hydromon.bus.demo.run_demo", refuse)


@pytest.mark.parametrize("args, needle", [
    (["--out", "{d}/file.txt"], "--out '{d}/file.txt' exists and is not a directory"),
    (["--out", "{d}/file.txt/sub"], "'{d}/file.txt' is not a directory"),
    (["--duration", "-1"], "--duration -1.0 must be a finite number >= 0 s"),
    (["--rate", "-1"], "--rate -1.0 must be a finite number >= 0"),
])
def test_demo_checks_out_and_numbers(tmp_path, capsys, no_demo, args, needle):
    (tmp_path / "file.txt").write_text("mine")
    assert main(["demo", *[a.format(d=tmp_path) for a in args]]) == 2
    one_error_line(capsys, "demo", needle.format(d=tmp_path))
    assert (tmp_path / "file.txt").read_text() == "mine"


# -- 4. audit: errors name the file and the problem -----------------------------------------

@pytest.mark.parametrize("name, text, needle", [
    ("dup.csv", "t,ug,x1,x3,x4,x5\n0,0,0,0,0,0\n0,0,0,0,0,0\n0.02,0,0,0,0,0\n",
     "dup.csv line 3: t = 0.0 s does not increase strictly"),
    ("empty.csv", "", "empty.csv: empty file; expected a header t,ug,x1,x3,x4,x5"),
    ("hdr.csv", "a,b\n1,2\n", "hdr.csv line 1: header 'a,b' lacks column(s)"),
    ("nan.csv", "t,ug,x1,x3,x4,x5\n0,0,0,0,0,0\n0.01,0,x,0,0,0\n", "nan.csv line 3: x1 = 'x' is not a number"),
    ("gap.csv", "t,ug,x1,x3,x4,x5\n" + "".join(f"{0.01 * i!r},0,0,0,0,0\n" for i in (0, 1, 2, 3, 5, 6)),
     "gap.csv line 6: t = 0.05"),
    ("bad.mcap", "junk", "bad.mcap: not an MCAP file"),
])
def test_audit_errors_name_file_and_problem(tmp_path, capsys, name, text, needle):
    p = tmp_path / name
    p.write_text(text)
    assert main(["audit", str(p)]) == 2
    err = one_error_line(capsys, "audit", needle)
    assert err.count(name) == 1  # named once, not twice


def test_audit_missing_file_and_misplaced_rig(tmp_path, capsys):
    assert main(["audit", str(tmp_path / "x.mcap")]) == 2
    one_error_line(capsys, "audit", f"{tmp_path / 'x.mcap'}: no such file")
    p = tmp_path / "a.csv"
    p.write_text("t,ug,x1,x3,x4,x5\n0,0,0,0,0,0\n0.01,0,0,0,0,0\n")
    assert main(["audit", str(p), "--rig", "g1"]) == 2
    one_error_line(capsys, "audit", "--rig selects a rig of an MCAP recording")
    assert main(["audit", str(p), "--train-fraction", "2"]) == 2
    one_error_line(capsys, "audit", "--train-fraction 2.0")


# -- 5. monitor, sim, replay, reproduce: checked before the bus, the banner or the work -------

@pytest.mark.parametrize("command, args, needle", [
    ("monitor", ["--eval-every", "-1"], "--eval-every -1 must be >= 1"),
    ("monitor", ["--eval-every", "0"], "--eval-every 0 must be >= 1"),
    ("monitor", ["--rigs", ""], "--rigs: rig pattern ''"),
    ("monitor", ["--duration", "inf"], "--duration inf must be a finite number > 0 s"),
    ("monitor", ["--node", "a b"], "node name 'a b'"),
    ("sim", ["--rate", "-1"], "--rate -1.0 must be a finite number >= 0"),
    ("sim", ["--block", "0"], "--block 0 must be >= 1"),
    ("sim", ["--block", "-5"], "--block -5 must be >= 1"),
    ("sim", ["--duration", "inf"], "--duration inf must be a finite number > 0 s"),
    ("sim", ["--rig", "table4-g1"], "--rig selects the rig of --to-csv/--to-mcap"),
    ("sim", ["--namespace", "a b"], "namespace 'a b'"),
    ("replay", ["{d}/r.mcap", "--duration", "-5"], "--duration -5.0 must be a finite number >= 0 s"),
    ("replay", ["{d}/r.mcap", "--rate", "-1"], "--rate -1.0 must be a finite number >= 0"),
    ("replay", ["{d}/r.mcap", "--start", "nan"], "--start nan must be a finite number >= 0 s"),
    ("replay", ["{d}/r.mcap", "--keys", "a/**/**x"], "--keys 'a/**/**x'"),
    ("replay", ["{d}/r.mcap", "--direct", "--out", "{d}/no/x.jsonl"], "directory '{d}/no' does not exist"),
])
def test_checked_before_bus_and_banner(tmp_path, capsys, no_bus, command, args, needle):
    assert main([command, *[a.format(d=tmp_path) for a in args]]) == 2
    one_error_line(capsys, command, needle.format(d=tmp_path))


def test_reproduce_rejects_negative_calibration_runs(capsys, monkeypatch):
    def refuse(*_a, **_k):
        raise AssertionError("tables computed before the options were checked")

    monkeypatch.setattr("hydromon.report.reproduce._table2", refuse)
    for n in ("-1", "5"):
        assert main(["reproduce", "--calibration-runs", n]) == 2
        one_error_line(capsys, "reproduce", f"--calibration-runs {n}: 0 (our default ranges) or at least 10")


def test_monitor_core_names_eval_every():
    from hydromon.engine.core import MonitorCore

    with pytest.raises(ValueError, match="eval_every -1 must be >= 1"):
        MonitorCore("hydro", eval_every=-1)


def test_sim_refuses_two_outputs_that_are_one_file_through_a_link(tmp_path, capsys):
    # the check compares files, not absolute paths: a symlink to the other output is the same file
    (tmp_path / "a").write_text("keep")
    os.symlink(tmp_path / "a", tmp_path / "b")
    assert main(["sim", "--duration", "1", "--rigs", "1", "--to-csv", str(tmp_path / "a"),
                 "--to-mcap", str(tmp_path / "b")]) == 2
    one_error_line(capsys, "sim", "name the same file")
    assert (tmp_path / "a").read_text() == "keep"


def test_sigterm_while_writing_leaves_neither_a_part_file_nor_a_half_output(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "long.csv"
    proc = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "sim", "--to-csv", str(out), "--duration", "3000",
                             "--rigs", "1"], stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not any(p.name.endswith(".part") for p in tmp_path.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline, "no temporary file appeared"
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM
    assert list(tmp_path.iterdir()) == []  # before: a .long.csv.*.part file stayed behind


# -- record: its options before the bus -------------------------------------------------------

@pytest.mark.parametrize("extra, needle", [
    (["--rotate-s", "-1"], "--rotate-s -1.0 must be a finite number > 0 s"),
    (["--rotate-s", "nan"], "--rotate-s nan must be a finite number > 0 s"),
    (["--rotate-mb", "0"], "--rotate-mb 0.0 must be a finite number > 0 MB"),
    (["--duration", "-1"], "--duration -1.0 must be a finite number >= 0 s"),
    (["--duration", "inf"], "--duration inf must be a finite number >= 0 s"),
    (["--out", "{tmp}/a-file/x.mcap"], "is not a directory"),
    (["--out", "{tmp}/a-file/parts/"], "is not a directory"),
])
def test_record_checks_its_options_before_the_bus(tmp_path, capsys, no_bus, extra, needle):
    (tmp_path / "a-file").write_text("x")
    extra = [e.format(tmp=tmp_path) for e in extra]
    assert main(["record", "--out", str(tmp_path / "r.mcap"), *extra]) == 2
    one_error_line(capsys, "record", needle)
    assert sorted(os.listdir(tmp_path)) == ["a-file"]  # nothing written


@pytest.mark.network
@pytest.mark.parametrize("command", [["monitor"], ["sim"], ["record", "--out", "{tmp}/r.mcap"]])
def test_a_client_whose_router_is_not_up_is_one_error_line_and_status_1(tmp_path, capsys, command):
    # fault injection: a node started in client mode before its router (a plant's boot order) died
    # with a zenoh traceback, exit status 1
    # a port this test holds bound but never listens on: a connect is refused, and no other
    # process can start listening there meanwhile (as on a port that was merely free a moment ago)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        held.bind(("127.0.0.1", 0))
        ep = f"tcp/127.0.0.1:{held.getsockname()[1]}"
        args = [a.replace("{tmp}", str(tmp_path)) for a in command] + ["--mode", "client", "--connect", ep]
        assert main(args) == 1
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()[-1]
    assert "Traceback" not in cap.err and err.startswith(f"hydromon {command[0]}: error: cannot open the zenoh session")
    assert ep in err and "Unable to connect" in err and " at /" not in err
    assert not (tmp_path / "r.mcap").exists()


@pytest.mark.parametrize("argv", [["evaluate"], ["audit"], ["replay", "--direct"],
                                  ["replay", "--wait", "0", "--connect", "tcp/127.0.0.1:9"], ["recover"]])
def test_a_directory_given_as_the_recording_is_one_error_line_not_a_traceback(tmp_path, capsys, argv):
    # evaluate, replay (bus and --direct) and recover given a directory named like a recording:
    # one error line and exit 2, not an IsADirectoryError traceback or "no such file"
    folder = tmp_path / "run.mcap"
    folder.mkdir()
    assert main([argv[0], str(folder), *argv[1:]]) == 2
    one_error_line(capsys, argv[0], f"{folder}: is a directory")


@pytest.mark.parametrize("text, needle", [
    (None, "missing.json': No such file or directory"),
    ("t,ug,x1\n0,0,0\n", "Invalid JSON: expected ident at line 1 column 2"),
    ('{"params": {"K_sv": {"direction": "up", "edges": [1, 2, 3, 4]}}, "x": 1}',
     "params.K_sv.direction: Input should be 'rising' or 'falling' (got 'up'); x: Extra inputs are not "
     "permitted (got 1)"),
])
def test_a_bad_ranges_file_is_one_error_line(tmp_path, capsys, text, needle):
    # one line naming the file and the problem, not pydantic's own text (several lines per problem,
    # the whole file as its input and a web address) nor "[Errno 2] No such file or directory: '...'"
    path = tmp_path / "missing.json"
    if text is not None:
        path.write_text(text)
    assert main(["monitor", "--ranges", str(path), "--duration", "0.1"]) == 2
    one_error_line(capsys, "monitor", f"ranges file '{path}'", needle)


def test_pydantic_errors_are_one_short_line():
    from pydantic import BaseModel, ValidationError

    from plant_sim.validation import brief_error

    class M(BaseModel):
        a: int
        b: str

    with pytest.raises(ValidationError) as err:
        M(a="x" * 500, b=3)
    line = brief_error(err.value)
    assert "\n" not in line and len(line) < 200  # pydantic's own text echoed the 500 characters
    assert line.startswith("a: Input should be a valid integer") and "...)" in line
    assert "; b: Input should be a valid string (got 3)" in line


def test_a_fleet_file_of_another_format_says_what_a_fleet_file_is(tmp_path, capsys):
    # `sim --fleet a.csv` says what a fleet file is, not only "Expecting value: line 1 column 1 (char 0)"
    path = tmp_path / "a.csv"
    path.write_text("id,severity\nr1,0.5\n")
    assert main(["sim", "--fleet", str(path), "--to-csv", str(tmp_path / "x.csv"), "--duration", "1"]) == 2
    one_error_line(capsys, "sim", f"{path}: not a JSON fleet file", "a fleet file is .toml or .json")


def test_record_names_out_when_its_directory_cannot_be_made(tmp_path, capsys):
    # `record --out /proc/nope/x.mcap` (root may write /proc, but not make a directory there) is
    # refused by the checks, naming --out, not with "[Errno 2] No such file or directory: '/proc/nope'"
    assert main(["record", "--out", "/proc/nope/x.mcap", "--duration", "1", "--listen", "tcp/127.0.0.1:0"]) == 2
    one_error_line(capsys, "record", "--out '/proc/nope/x.mcap'")


def test_a_system_error_is_one_line_and_status_1(monkeypatch, capsys):
    # a full disk or a refused permission inside a command was a traceback
    import errno

    from hydromon.cli.commands import audit

    def full(args):
        raise OSError(errno.ENOSPC, "No space left on device", "report.md")

    monkeypatch.setattr(audit, "run", full)
    assert main(["audit", "x.csv"]) == 1
    one_error_line(capsys, "audit", "No space left on device", "report.md")
