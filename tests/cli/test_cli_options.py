"""Command-line options that the other files leave alone: ``monitor --ranges``, ``sim --to-mcap``,
``record --rotate-mb/--rotate-s``, ``replay --start/--duration`` and the ``file:`` profile.

In-process ``hydromon.cli.main.main(argv)`` calls throughout; the bus ones on loopback with explicit
endpoints (multicast scouting is off by default in hydromon.bus.session), bounded waits.
"""

from __future__ import annotations

import threading
import types
from pathlib import Path

import numpy as np
import orjson
import pytest

from helpers import health_seqs, wait_for
from hydromon.bus.session import listening_session
from hydromon.cli.main import main
from hydromon.contract import RigConfig
from hydromon.store.fleetfile import FleetSpec, RigSpec
from hydromon.store.mcap_read import read_recording, read_rig_config, read_samples
from monitor.ranges import Ranges

NS = "hydro"


# -- monitor --ranges -----------------------------------------------------------------------------

def _run_monitor_cli(monkeypatch, extra: list[str], rig: str = "cli-r1") -> dict:
    """Run ``hydromon monitor`` in this (main) thread while a peer publishes a short simulated
    run of one rig; return the rig's latest health (queried from the monitor)."""
    import hydromon.cli.commands.monitor as monitor_cmd

    # the command's stop event is set by SIGINT/SIGTERM; here the feeding thread sets it
    stop = threading.Event()
    monkeypatch.setattr(monitor_cmd, "threading", types.SimpleNamespace(Event=lambda: stop))
    node = f"opt-{rig}"
    got: dict = {}
    errors: list[BaseException] = []

    def feed(s):
        try:
            wait_for(lambda: any(r.ok is not None for r in s.liveliness().get(f"{NS}/monitor/{node}", timeout=1.0)),
                     60, "the monitor's liveliness token", alive=lambda: stop.is_set() and _stopped())
            from hydromon.bus.sim import run_sim

            run_sim(s, FleetSpec(rigs=[RigSpec(id=rig, severity=0.2)]), rate=0, duration=0.5)

            def latest():
                for r in s.get(f"{NS}/rig/{rig}/health", timeout=1.0):
                    if r.ok is not None:
                        got.update(orjson.loads(r.ok.payload.to_bytes()))
                return got.get("seq") == health_seqs(rig, 50)[-1]  # the health after the 50 samples
            wait_for(latest, 30, f"{rig}'s last health")
        except BaseException as exc:  # reported in the main thread
            errors.append(exc)
        finally:
            stop.set()

    def _stopped():
        raise AssertionError("the monitor stopped early")

    # the feeder's session listens (on a free port: listening_session) and the monitor connects to it
    with listening_session() as (s, ep):
        th = threading.Thread(target=feed, args=(s,), daemon=True)
        th.start()
        try:
            code = main(["monitor", "--connect", ep, "--node", node, "--duration", "90", *extra])
        finally:
            stop.set()
            th.join(30)
    assert not th.is_alive()
    if errors:
        raise errors[0]
    assert code == 0
    return got


@pytest.mark.network
@pytest.mark.timeout(120)
def test_monitor_ranges_option_chooses_what_the_valve_is_graded_on(monkeypatch, tmp_path):
    # monitor/data/default_ranges.json grades the valve on its static gain K_sv,
    # monitor/data/table3.json (--ranges paper) on K_sv omega_sv^2 as the paper prints it
    assert "K_sv" in Ranges.default().params and "K_sv_omega_sv2" not in Ranges.default().params
    assert "K_sv_omega_sv2" in Ranges.paper().params and "K_sv" not in Ranges.paper().params
    custom = tmp_path / "ranges.json"  # a file: two of the paper's parameters only
    paper = Ranges.paper()
    Ranges(params={k: paper.params[k] for k in ("f_c", "C_ip")}, rig=RigConfig(), source="test").save(custom)

    graded = {}
    for label, extra in (("none", []), ("default", ["--ranges", "default"]), ("paper", ["--ranges", "paper"]),
                         ("file", ["--ranges", str(custom)])):
        h = _run_monitor_cli(monkeypatch, extra, rig=f"r-{label}")
        graded[label] = set(h["param_grades"])
    assert graded["none"] == graded["default"] == set(Ranges.default().params)
    assert "K_sv" in graded["default"] and "K_sv_omega_sv2" not in graded["default"]
    assert graded["paper"] == set(Ranges.paper().params)
    assert "K_sv_omega_sv2" in graded["paper"] and "K_sv" not in graded["paper"]
    assert graded["file"] == {"f_c", "C_ip"}


def test_monitor_ranges_option_rejects_a_bad_file_before_the_bus(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"params": {"nope": {}}}')
    assert main(["monitor", "--ranges", str(bad), "--listen", "tcp/127.0.0.1:0", "--duration", "0.1"]) == 2
    assert str(bad) in capsys.readouterr().err


# -- sim --to-mcap --------------------------------------------------------------------------------

def test_sim_to_mcap_reads_back_with_every_sample_and_the_configs(tmp_path, capsys):
    out = tmp_path / "run.mcap"
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[config]\np_s = 12e6\n[[rigs]]\nid = "a"\nseverity = 0.1\n'
                     '[[rigs]]\nid = "b"\ntable4 = 3\n')
    assert main(["sim", "--fleet", str(fleet), "--duration", "0.3", "--to-mcap", str(out)]) == 0
    assert f"62 messages of 2 rig(s) -> {out}" in capsys.readouterr().err
    for rig in ("a", "b"):
        rid, data, seq = read_samples(out, rig=rig)
        assert rid == rig and data.shape == (30, 6)
        assert seq.tolist() == list(range(30))
        np.testing.assert_allclose(data[:, 0], np.arange(30) * 0.01, atol=1e-12)
        assert read_rig_config(out, rig) == RigConfig(p_s=12e6)
    keys = [k for k, *_ in read_recording(out)]
    assert keys[:2] == ["hydro/rig/a/config", "hydro/rig/b/config"] and len(keys) == 62
    # --namespace goes into the keys; --duration is required
    assert main(["sim", "--severity", "0.2", "--duration", "0.05", "--namespace", "site2",
                 "--to-mcap", str(tmp_path / "ns.mcap")]) == 0
    assert {k for k, *_ in read_recording(tmp_path / "ns.mcap")} == {"site2/rig/rig-0000/config",
                                                                     "site2/rig/rig-0000/sample"}
    assert main(["sim", "--to-mcap", str(tmp_path / "x.mcap")]) == 2
    assert "--duration" in capsys.readouterr().err


# -- record --rotate-mb / --rotate-s --------------------------------------------------------------

def _record_while_publishing(tmp_path, capsys, extra: list[str], n: int, pause_every: int = 0,
                             pause_s: float = 0.0) -> list:
    """``hydromon record --out DIR/rec.mcap`` in this thread while a peer puts ``n`` samples of
    one rig (and its config); the feeder stops the recorder once all of them are on disk.
    Returns the files the command printed, in order."""
    import hydromon.cli.commands.record as record_cmd
    from hydromon.contract import config_key, sample_key

    stop = threading.Event()
    out = tmp_path / "rec.mcap"
    errors: list[BaseException] = []

    def feed(s):
        try:
            pub = s.declare_publisher(sample_key("rot"))
            wait_for(lambda: pub.matching_status.matching, 60, "the recorder's subscription")
            s.put(config_key("rot"), orjson.dumps(RigConfig(p_s=11e6).model_dump(mode="json")))
            for i in range(n):
                pub.put(orjson.dumps({"seq": i, "t": i * 0.01, "ug": 2.0, "x1": 0.001 * i, "x3": 6e6,
                                      "x4": 5e6, "x5": 1e-5}))
                if pause_every and (i + 1) % pause_every == 0:
                    stop.wait(pause_s)
            # the recorder has them all once its message count says so: poll its files
            wait_for(lambda: _on_disk(out) >= n + 1, 30, "every message on disk")
        except BaseException as exc:
            errors.append(exc)
        finally:
            stop.set()

    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(record_cmd, "threading", types.SimpleNamespace(Event=lambda: stop))
    # the feeder's session listens (on a free port: listening_session) and the recorder connects to it
    with listening_session() as (s, ep):
        th = threading.Thread(target=feed, args=(s,), daemon=True)
        th.start()
        try:
            code = main(["record", "--out", str(out), "--connect", ep, "--duration", "90", *extra])
        finally:
            stop.set()
            th.join(30)
            monkeypatch.undo()
    assert not th.is_alive()
    if errors:
        raise errors[0]
    assert code == 0
    files = [Path(p) for p in capsys.readouterr().out.split()]
    assert sorted(files) == sorted(tmp_path.glob("rec*.mcap"))
    return files


def _on_disk(out) -> int:
    """Messages readable now from the recorder's files (the live one being written too)."""
    import io

    from hydromon.store.mcap_recover import recover

    total = 0
    for p in out.parent.glob("rec*.mcap"):
        total += recover(io.BytesIO(p.read_bytes()), io.BytesIO()).messages
    return total


def _check_parts(files: list) -> list[int]:
    """Every part is a complete recording with the rig's config; the seqs over all parts are
    0.. without a loss or a repeat. Returns the sample count per part."""
    seqs, counts = [], []
    for f in files:
        assert read_rig_config(f, "rot") == RigConfig(p_s=11e6)
        _, _, seq = read_samples(f, rig="rot")  # a complete file: read_samples would raise otherwise
        counts.append(len(seq))
        seqs += seq.tolist()
    assert seqs == list(range(len(seqs)))
    return counts


@pytest.mark.network
@pytest.mark.timeout(120)
def test_record_rotate_mb_splits_the_run_into_complete_files(tmp_path, capsys):
    # a file grows when its chunk is flushed (~0.5 s after the chunk's first message): four
    # bursts of 40 samples 0.7 s apart against --rotate-mb 0.004 (4000 B). The first file with
    # its schemas, channels and one burst is ~3.1 kB, each further burst ~1.5 kB: so the first
    # file takes two bursts (or more, if flushes are late), and the run needs more than one file
    files = _record_while_publishing(tmp_path, capsys, ["--rotate-mb", "0.004"], n=160, pause_every=40,
                                     pause_s=0.7)
    assert len(files) >= 2
    assert all(f.stat().st_size >= 4000 for f in files[:-1])  # closed once it reached the size
    counts = _check_parts(files)  # every part holds samples: none is empty
    assert sum(counts) == 160 and counts[0] >= 80  # MB, not kB: one burst did not fill a file


@pytest.mark.network
@pytest.mark.timeout(120)
def test_record_rotate_s_splits_the_run_into_complete_files(tmp_path, capsys):
    # bursts of 20 samples 0.5 s apart against --rotate-s 0.1: a file never outlives a pause,
    # and the quiet bus at the end leaves no empty part
    files = _record_while_publishing(tmp_path, capsys, ["--rotate-s", "0.1"], n=100, pause_every=20,
                                     pause_s=0.5)
    assert len(files) >= 3
    counts = _check_parts(files)
    assert sum(counts) == 100
    assert main(["record", "--rotate-mb", "0", "--out", str(tmp_path / "z.mcap")]) == 2


# -- replay --start / --duration ------------------------------------------------------------------

@pytest.fixture(scope="module")
def two_rigs(tmp_path_factory):
    path = tmp_path_factory.mktemp("rep") / "two.mcap"
    assert main(["sim", "--rigs", "2", "--duration", "3", "--to-mcap", str(path)]) == 0
    return path


def _seqs(jsonl: bytes) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for line in jsonl.splitlines():
        d = orjson.loads(line)
        out.setdefault(d["key"].split("/")[2], []).append(d["health"]["seq"])
    return out


def test_replay_direct_start_and_duration_grade_the_window_only(two_rigs, tmp_path, capsys):
    whole, part = tmp_path / "whole.jsonl", tmp_path / "part.jsonl"
    assert main(["replay", str(two_rigs), "--direct", "--out", str(whole)]) == 0
    assert "600 samples of 2 rig(s)" in capsys.readouterr().err
    # 1.0 s after the first message (the configs at t = 0), 0.5 s long: samples t in [1.0, 1.5)
    assert main(["replay", str(two_rigs), "--direct", "--out", str(part), "--start", "1.0",
                 "--duration", "0.5"]) == 0
    assert "100 samples of 2 rig(s)" in capsys.readouterr().err
    whole_seqs, part_seqs = _seqs(whole.read_bytes()), _seqs(part.read_bytes())
    assert set(part_seqs) == set(whole_seqs) == {"rig-0000", "rig-0001"}
    for rig, seqs in part_seqs.items():
        assert seqs and all(100 <= s < 150 for s in seqs)
        assert seqs == [s for s in whole_seqs[rig] if 100 <= s < 150]  # same phase of health as whole
    # --start alone: to the end; --duration alone: from the start
    assert main(["replay", str(two_rigs), "--direct", "--out", str(part), "--start", "2.5"]) == 0
    assert "100 samples of 2 rig(s)" in capsys.readouterr().err
    assert main(["replay", str(two_rigs), "--direct", "--out", str(part), "--duration", "0.2"]) == 0
    assert "40 samples of 2 rig(s)" in capsys.readouterr().err
    assert main(["replay", str(two_rigs), "--direct", "--start", "-1"]) == 2
    assert "start" in capsys.readouterr().err


@pytest.mark.parametrize("opt", [["--rate", "0.5"], ["--wait", "1"], ["--loop"]])
def test_replay_direct_refuses_the_bus_replays_pacing_options(two_rigs, capsys, opt):
    # --direct grades as fast as it can: a --rate or --wait given with it was silently ignored
    assert main(["replay", str(two_rigs), "--direct", *opt]) == 2
    assert f"{opt[0]} has no meaning with --direct" in capsys.readouterr().err
    assert main(["replay", str(two_rigs), "--rate", "-1"]) == 2  # the bus replay still checks them
    assert "--rate" in capsys.readouterr().err


def test_a_replay_window_carries_each_rigs_config_from_before_it(tmp_path, capsys):
    # the configs are recorded once, at t = 0: a window starting later used to leave them out,
    # and the monitor graded the rig with the default constants (p_s 10 MPa, not 14)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[config]\np_s = 14e6\n[[rigs]]\nid = "a"\nseverity = 0.1\n')
    rec = tmp_path / "cfg.mcap"
    assert main(["sim", "--fleet", str(fleet), "--duration", "1.5", "--to-mcap", str(rec)]) == 0
    from hydromon.store.replay import iter_window

    msgs = list(iter_window(rec, start=1.0, duration=0.2))
    assert [k for k, _, _ in msgs] == ["hydro/rig/a/config"] + ["hydro/rig/a/sample"] * 20
    assert RigConfig.model_validate_json(msgs[0][1]).p_s == 14e6
    assert msgs[0][2] == msgs[1][2] == 1_000_000_000  # stamped with the window's first message
    assert [k for k, _, _ in iter_window(rec, keys=["hydro/rig/*/sample"], start=1.0, duration=0.2)] == \
        ["hydro/rig/a/sample"] * 20  # --keys still filters it
    assert list(iter_window(rec, start=5.0)) == []  # an empty window stays empty
    from hydromon.store.replay import health_jsonl, replay_direct

    health, core = replay_direct(rec, start=1.0)
    assert core.configs["a"].p_s == 14e6 and core.counters.configs == 1
    out = tmp_path / "part.jsonl"
    assert main(["replay", str(rec), "--direct", "--out", str(out), "--start", "1.0"]) == 0
    assert out.read_bytes() == b"".join(health_jsonl(health)) and health
    capsys.readouterr()


@pytest.mark.network
@pytest.mark.timeout(120)
def test_replay_on_the_bus_publishes_the_window_only(two_rigs):
    got: list[tuple[str, int]] = []
    lock = threading.Lock()

    def on_sample(s):
        with lock:
            got.append((str(s.key_expr), orjson.loads(s.payload.to_bytes()).get("seq", -1)))

    with listening_session() as (sess, ep):
        sub = sess.declare_subscriber(f"{NS}/rig/*/*", on_sample)
        try:
            assert main(["replay", str(two_rigs), "--connect", ep, "--rate", "0", "--quiet", "--wait", "30",
                         "--keys", f"{NS}/rig/rig-0001/*", "--start", "2.0", "--duration", "0.25"]) == 0
            wait_for(lambda: len(got) >= 26, 20, "the config and 25 replayed samples")
        finally:
            sub.undeclare()
    # the rig's config (recorded at t = 0, before the window) goes first
    assert got == [(f"{NS}/rig/rig-0001/config", -1)] + [(f"{NS}/rig/rig-0001/sample", s) for s in range(200, 225)]


# -- the file: profile ----------------------------------------------------------------------------


def test_json_into_a_closed_pipe_is_not_a_traceback(tmp_path):
    """`hydromon ... --json | head -c 100` ends quietly (status 141), not in a BrokenPipeError
    traceback. Here the reader has closed its end before the command writes (deterministic,
    unlike `| head`)."""
    import subprocess
    import sys

    csv = tmp_path / "r.csv"
    assert main(["sim", "--duration", "1", "--rig", "table4-g1", "--to-csv", str(csv)]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "evaluate", str(csv), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(120) == 141 and "Traceback" not in err, err


def test_the_console_entry_keeps_status_and_output(tmp_path):
    """``hydromon`` leaves through ``cli.entry`` (os._exit after flushing, no interpreter
    finalization, where zenoh's threads could abort the process): its status and everything
    printed come through as from ``main``."""
    import subprocess
    import sys

    def run(*args):
        return subprocess.run([sys.executable, "-m", "hydromon.cli", *args], capture_output=True, text=True,
                              timeout=120)

    ok = run("--help")
    assert ok.returncode == 0 and "usage: hydromon" in ok.stdout
    bad = run("sim", "--nope")
    assert bad.returncode == 2 and "unrecognized arguments: --nope" in bad.stderr
    err = run("evaluate", str(tmp_path / "missing.csv"))
    assert err.returncode == 2 and "error:" in err.stderr
    csv = tmp_path / "r.csv"
    assert main(["sim", "--duration", "1", "--rig", "table4-g1", "--to-csv", str(csv)]) == 0
    out = run("evaluate", str(csv), "--json")
    # the whole document, flushed; a record too short to grade exits 1 (hydromon.cli.exits)
    assert out.returncode == (0 if orjson.loads(out.stdout)["status"] == "ok" else 1)


def test_a_node_that_will_meet_nobody_says_so(capsys):
    # two nodes started with default flags (peer, no endpoint, multicast off) each waited for
    # the other in silence
    from hydromon.cli.busopts import isolation_hint

    assert "will meet no other node" in isolation_hint("peer", [], [], False)
    assert "will meet no other node" in isolation_hint("client", [], [], False)
    for mode, connect, listen, multicast in (("peer", ["tcp/127.0.0.1:1"], [], False),
                                             ("peer", [], ["tcp/127.0.0.1:1"], False),
                                             ("peer", [], [], True), ("router", [], [], False)):
        assert isolation_hint(mode, connect, listen, multicast) is None


# -- sim --frame ----------------------------------------------------------------------------------

def test_a_framed_recording_evaluates_replays_and_audits_as_its_samples(tmp_path, capsys):
    runs = {}
    for name, extra in (("samples", []), ("frames", ["--frame", "10"])):
        path = tmp_path / f"{name}.mcap"
        assert main(["sim", "--noise", "realistic", "--duration", "6", "--rig", "table4-g4", "--to-mcap",
                     str(path), *extra]) == 0
        assert main(["replay", "--direct", str(path), "--out", str(tmp_path / f"{name}.jsonl")]) == 0
        capsys.readouterr()
        assert main(["evaluate", str(path), "--json"]) == 0
        ev = orjson.loads(capsys.readouterr().out)
        assert main(["audit", str(path), "--json"]) == 0
        runs[name] = (ev, orjson.loads(capsys.readouterr().out), (tmp_path / f"{name}.jsonl").read_bytes())
    assert {k for k, *_ in read_recording(tmp_path / "frames.mcap")} == {"hydro/rig/table4-g4/config",
                                                                         "hydro/rig/table4-g4/frame"}
    (ev_s, au_s, h_s), (ev_f, au_f, h_f) = runs["samples"], runs["frames"]
    assert h_f == h_s and h_s.count(b"\n") == 60
    drop = lambda d: {k: v for k, v in d.items() if k not in ("source", "file")}  # noqa: E731
    assert drop(ev_f) == drop(ev_s) and drop(au_f) == drop(au_s)
    assert main(["sim", "--frame", "0", "--duration", "1", "--to-mcap", str(tmp_path / "x.mcap")]) == 2
    assert main(["sim", "--frame", "1001", "--duration", "1", "--to-mcap", str(tmp_path / "x.mcap")]) == 2
    assert main(["sim", "--frame", "5", "--duration", "1", "--to-csv", str(tmp_path / "x.csv")]) == 2
