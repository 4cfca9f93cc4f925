"""Replay: key filters, windows, deterministic direct replay, and a bus replay into the
monitor node on loopback giving the direct replay's health."""

from __future__ import annotations

import io
import threading
import time

import numpy as np
import orjson
import pytest

from helpers import chunk_spans, flip_in_chunk
from hydromon.bus.monitor import run_monitor
from hydromon.bus.replay import replay_bus
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import Health
from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet
from hydromon.store.mcap_layout import CorruptRecording
from hydromon.store.mcap_read import read_recording
from hydromon.store.mcap_write import RecordingWriter
from hydromon.store.replay import (
    KeyFilter,
    NothingToReplay,
    check_window,
    health_jsonl,
    iter_window,
    recording_span,
    replay_direct,
)
from hydromon.store.simfiles import write_mcap
from plant_sim.degradation import TABLE4_PAPER_GRADES


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "fleet.mcap"
    with open(path, "wb") as f:
        n = write_mcap(default_fleet(), 5.0, f)
    assert n == 5 + 5 * 500
    return path


def test_key_filter_semantics():
    f = KeyFilter(["hydro/rig/*/sample"])
    assert f("hydro/rig/a/sample") and not f("hydro/rig/a/config") and not f("hydro/rig/a/b/sample")
    assert not f("other/rig/a/sample")
    g = KeyFilter(["hydro/**/config", "hydro/rig/table4-$*/health"])
    assert g("hydro/rig/a/config") and g("hydro/config") and g("hydro/rig/table4-g1/health")
    assert not g("hydro/rig/a/health") and not g("hydro/rig/a/sample")
    assert KeyFilter(None)("anything/at/all") and KeyFilter(["**"])("a/b")
    for bad in ("hydro//x", "hydro/rig*", "/hydro"):
        with pytest.raises(ValueError, match="not a zenoh key expression"):
            KeyFilter([bad])


def test_window_cuts_by_log_time_from_the_first_message(recording):
    first, last, count = recording_span(recording)
    assert (first, count) == (0, 2505) and last == round(4.99 * 1e9)  # configs at 0, samples at t
    msgs = list(iter_window(recording, keys=["hydro/rig/table4-g2/sample"], start=1.0, duration=0.5))
    seqs = [orjson.loads(p)["seq"] for _, p, _ in msgs]
    assert seqs == list(range(100, 150))
    assert all(1_000_000_000 <= t < 1_500_000_000 for _, _, t in msgs)
    assert len(list(iter_window(recording, start=10.0))) == 0
    with pytest.raises(ValueError, match="start"):
        list(iter_window(recording, start=-1.0))


def test_direct_replay_is_deterministic_and_equals_the_core_on_the_messages(recording):
    h1, core1 = replay_direct(recording)
    h2, _ = replay_direct(recording, batch=37)
    assert h1 == h2 and b"".join(health_jsonl(h1)) == b"".join(health_jsonl(h2))
    assert len(h1) == 5 * 50
    core = MonitorCore()
    assert core.process([(k, p) for k, p, _, _ in read_recording(recording)]) == h1
    for rig, payload in core1.latest.items():
        assert Health.model_validate_json(payload).grade == TABLE4_PAPER_GRADES[int(rig[-1])]
    lines = b"".join(health_jsonl(h1)).splitlines()
    assert orjson.loads(lines[0])["key"] == h1[0][0] and orjson.loads(lines[0])["health"] == orjson.loads(h1[0][1])
    # one rig alone gives that rig's verdicts of the whole run (rigs do not interact)
    one, _ = replay_direct(recording, keys=["hydro/rig/table4-g3/*"])
    assert one == [h for h in h1 if h[0] == "hydro/rig/table4-g3/health"]


def test_direct_replay_of_a_stream(recording):
    data = io.BytesIO(recording.read_bytes())
    assert replay_direct(data)[0] == replay_direct(recording)[0]


def test_cli_direct_twice_gives_identical_files(recording, tmp_path, capsys):
    from hydromon.cli.main import main

    outs = []
    for i in range(2):
        out = tmp_path / f"h{i}.jsonl"
        assert main(["replay", str(recording), "--direct", "--out", str(out)]) == 0
        outs.append(out.read_bytes())
    assert outs[0] == outs[1] and len(outs[0].splitlines()) == 250
    err = capsys.readouterr().err
    assert "table4-g3: fault" in err
    assert main(["replay", str(recording), "--direct", "--loop"]) == 2


@pytest.mark.network
@pytest.mark.timeout(90)
def test_bus_replay_into_the_monitor_gives_the_direct_health_on_every_pass(recording):
    direct, _ = replay_direct(recording)
    got: list[tuple[str, bytes]] = []
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as rep_s:
        stop, result = threading.Event(), {}
        mon = threading.Thread(target=lambda: result.update(core=run_monitor(
            mon_s, stop_event=stop, on_health=lambda k, p: got.append((k, p)), stale_after_s=None)), daemon=True)
        mon.start()
        try:
            deadline = time.monotonic() + 30
            while not any(r.ok is not None for r in rep_s.liveliness().get("hydro/monitor/*", timeout=1.0)):
                assert time.monotonic() < deadline, "the monitor never came up"
            stats = replay_bus(rep_s, recording, rate=0, loop=True, max_passes=2)
            assert stats.passes == 2 and stats.published == 2 * 2505
            deadline = time.monotonic() + 60
            while len(got) < 2 * len(direct):
                assert time.monotonic() < deadline, f"{len(got)} of {2 * len(direct)} health messages"
                time.sleep(0.01)
        finally:
            stop.set()
            mon.join(30)
    core = result["core"]
    assert core.counters.restarts == 5 and core.counters.dropped_seq == 0 and core.counters.gaps == 0

    def per_rig(msgs):
        out = {}
        for k, p in msgs:
            out.setdefault(k, []).append(p)
        return out

    want, have = per_rig(direct), per_rig(got)
    assert sorted(want) == sorted(have)
    for key in want:  # each rig's verdicts, byte for byte, twice (the second pass restarts the rig)
        assert have[key] == want[key] + want[key]


class _FakeTime:
    """A clock and a stop event in one: waiting advances the clock (no real sleeping)."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now

    def is_set(self):
        return False

    def wait(self, s):
        self.now += s
        return False


class _FakeSession:
    def __init__(self, clock, put_cost=0.0):
        self.clock, self.put_cost, self.sent = clock, put_cost, []

    def declare_publisher(self, key, **kw):
        session = self

        class Pub:
            matching_status = type("M", (), {"matching": True})()

            def put(self, payload):
                session.sent.append((key, session.clock.now))
                session.clock.now += session.put_cost

            def undeclare(self):
                pass

        return Pub()


@pytest.mark.parametrize("rate", [1.0, 2.5])
def test_pacing_follows_the_recording_without_drift(recording, rate):
    ft = _FakeTime()
    session = _FakeSession(ft)
    stats = replay_bus(session, recording, rate=rate, keys=["hydro/rig/table4-g1/*"], stop_event=ft, clock=ft)
    log_times = [t for _, _, t in iter_window(recording, keys=["hydro/rig/table4-g1/*"])]
    assert stats.published == len(log_times) == 501
    # every message at t0 + offset / rate, computed from the recording, not summed sleeps
    sent = np.array([t for _, t in session.sent]) - 100.0
    np.testing.assert_allclose(sent, (np.array(log_times) - log_times[0]) / 1e9 / rate, rtol=0, atol=1e-9)


def test_late_sends_do_not_shift_later_deadlines(recording):
    ft = _FakeTime()
    keys = ["hydro/rig/table4-g1/sample"]
    log_times = np.array([t for _, _, t in iter_window(recording, keys=keys)])
    due = (log_times - log_times[0]) / 1e9

    class Slow(_FakeSession):  # the 10th put takes 0.5 s: the next 49 go out late, at once
        def declare_publisher(self, key, **kw):
            pub = super().declare_publisher(key, **kw)
            put = pub.put

            def slow_put(payload):
                put(payload)
                if len(self.sent) == 10:
                    self.clock.now += 0.5
            pub.put = slow_put
            return pub

    session = Slow(ft)
    stats = replay_bus(session, recording, rate=1.0, keys=keys, stop_event=ft, clock=ft)
    sent = np.array([t for _, t in session.sent]) - 100.0
    assert stats.max_late == pytest.approx(0.5 - 0.01, abs=1e-9)
    late = sent > due + 1e-9
    assert late.sum() == 49 and np.all(sent[late] == sent[10])  # sent back to back when late
    np.testing.assert_allclose(sent[~late], due[~late], rtol=0, atol=1e-9)  # back on the grid after


@pytest.mark.parametrize("rate", [0.0, 1.0])
def test_a_replay_stopped_mid_pass_reports_where_not_a_whole_pass(recording, rate):
    # a replay stopped by Ctrl-C/SIGTERM after 3 s of a 20 s recording reports where it stopped,
    # not "1 pass(es)" with a full bar (the bar's total is the window, not the position reached);
    # a replay running late still looks at the stop event
    class Stopping(_FakeTime):
        stop = False

        def is_set(self):
            return self.stop

        def wait(self, s):
            super().wait(s)
            return self.stop

    ft = Stopping()
    session = _FakeSession(ft)
    calls = []

    def progress(done, total):
        calls.append((done, total))
        if len(session.sent) >= 1000:
            ft.stop = True

    stats = replay_bus(session, recording, rate=rate, stop_event=ft, clock=ft, progress=progress)
    first, last, _ = recording_span(recording)
    assert stats.passes == 0 and stats.published == 1000
    assert stats.stopped_at == pytest.approx(calls[-1][0], abs=0.011) and stats.stopped_at < 2.5
    assert all(total == pytest.approx((last - first) / 1e9) for _, total in calls)  # the window, not the position
    assert calls[-1][0] < calls[-1][1]  # the bar stays where the replay stopped


# -- damaged files and empty windows: a clear error naming the file, exit 2 -----------------------
def _summary_flip(data: bytes) -> bytes:
    import struct

    start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]  # the footer's summary start
    bad = bytearray(data)
    bad[(start + len(data) - 8 - 29) // 2] ^= 1  # halfway into the summary
    return bytes(bad)


DAMAGE = {  # what was done to the file -> what replay must say
    "footer cut": (lambda d: d[:-8], "recording has no footer .*run `hydromon recover {f}`"),
    "cut at half": (lambda d: d[: len(d) // 2], "recording has no footer .*run `hydromon recover {f}`"),
    "empty": (lambda d: b"", "empty recording \\(0 bytes\\): nothing to read or recover"),
    "bit flip in the summary": (_summary_flip, "damaged recording: its summary .*CRC.*run `hydromon recover {f}`"),
}


def _cli(argv, capsys):
    from hydromon.cli.main import main

    rc = main(argv)
    return rc, capsys.readouterr().err


@pytest.fixture
def no_session(monkeypatch):
    """A bus replay must fail before it opens a session: opening one fails the test (and keeps it off the network)."""
    def refuse(args):
        raise AssertionError("a session was opened")
    monkeypatch.setattr("hydromon.cli.commands.replay.session_from_args", refuse)


@pytest.mark.parametrize("mode", [["--direct"], ["--quiet", "--wait", "0"]], ids=["direct", "bus"])
@pytest.mark.parametrize("damage", DAMAGE)
def test_replay_of_a_damaged_file_names_it_and_recover_and_exits_2(recording, tmp_path, capsys, damage, mode,
                                                                   no_session):
    import re

    cut, want = DAMAGE[damage]
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(cut(recording.read_bytes()))
    out = tmp_path / "h.jsonl"
    rc, err = _cli(["replay", str(bad), *mode] + (["--out", str(out)] if "--direct" in mode else []), capsys)
    assert rc == 2 and "Traceback" not in err
    assert re.search(f"hydromon replay: error: {re.escape(str(bad))}: " + want.format(f=re.escape(str(bad))), err), err
    assert not out.exists()


def test_a_chunk_failing_its_crc_in_a_complete_file_is_a_clear_error_not_wrong_health(recording, tmp_path, capsys):
    bad = tmp_path / "flip.mcap"
    bad.write_bytes(flip_in_chunk(recording.read_bytes(), 2))  # zstd may still decompress it: the CRC must tell
    rc, err = _cli(["replay", str(bad), "--direct"], capsys)
    assert rc == 2 and "Traceback" not in err
    assert f"{bad}: damaged recording: the chunk at byte {chunk_spans(bad.read_bytes())[2][0]} (log time" in err
    assert f"run `hydromon recover {bad}` to salvage the intact chunks" in err
    ft = _FakeTime()  # the bus replay: the same error when it reaches the chunk
    with pytest.raises(CorruptRecording, match="damaged recording: the chunk at byte .* fails its CRC check"):
        replay_bus(_FakeSession(ft), bad, rate=0, stop_event=ft, clock=ft)


def _rewrite(src, dst, keep=lambda k: True, key=lambda k: k, n=None):
    with open(dst, "wb") as f, RecordingWriter(f) as w:
        for k, p, log_ns, pub_ns in list(read_recording(src))[:n]:
            if keep(k):
                w.write(key(k), p, log_ns, pub_ns)
    return dst


def test_direct_replay_under_another_namespace_says_which_and_exits_2(recording, tmp_path, capsys):
    site = _rewrite(recording, tmp_path / "site.mcap", key=lambda k: k.replace("hydro/", "site1/lineA/", 1), n=600)
    out = tmp_path / "h.jsonl"
    rc, err = _cli(["replay", str(site), "--direct", "--out", str(out)], capsys)
    assert rc == 2 and not out.exists()
    assert f"{site}: recorded under namespace site1/lineA, not hydro; use --namespace site1/lineA" in err
    rc, err = _cli(["replay", str(site), "--direct", "--out", str(out), "--namespace", "site1/lineA"], capsys)
    assert rc == 0 and out.read_bytes().count(b"\n") > 0


def test_direct_replay_that_grades_nothing_exits_2(recording, tmp_path, capsys):
    configs = _rewrite(recording, tmp_path / "configs.mcap", keep=lambda k: not k.endswith("/sample"), n=600)
    rc, err = _cli(["replay", str(configs), "--direct"], capsys)
    assert rc == 2 and "no rig samples (<ns>/rig/<id>/sample or .../frame) among the replayed topics" in err
    rc, err = _cli(["replay", str(recording), "--direct", "--start", "3", "--duration", "0"], capsys)
    assert rc == 2 and f"{recording}: no sample in the window" in err
    with pytest.raises(NothingToReplay, match="holds no messages"):
        check_window(_rewrite(recording, tmp_path / "none.mcap", keep=lambda k: False))


@pytest.mark.parametrize("mode", [["--direct"], ["--quiet", "--wait", "0"]], ids=["direct", "bus"])
@pytest.mark.parametrize("args, want", [
    (["--start", "1e6"], "--start 1e\\+06 s is past the recording's end \\(its messages span 4.990 s"),
    (["--keys", "bad key"], "no topic matches --keys 'bad key'; the recording's topics: hydro/rig/table4-g1/config"),
])
def test_a_window_with_nothing_in_it_is_an_error_in_both_modes(recording, capsys, mode, args, want, no_session):
    import re

    rc, err = _cli(["replay", str(recording), *mode, *args], capsys)
    assert rc == 2 and re.search(f"hydromon replay: error: {re.escape(str(recording))}: {want}", err), err


def test_a_bus_replay_that_sent_nothing_exits_2(recording, capsys, monkeypatch):
    import contextlib

    session = _FakeSession(_FakeTime())
    monkeypatch.setattr("hydromon.cli.commands.replay.session_from_args", lambda args: contextlib.nullcontext(session))
    # an empty window (no time in it) sends nothing, not even the configs carried into a window
    rc, err = _cli(["replay", str(recording), "--quiet", "--rate", "0", "--wait", "0", "--start", "1",
                    "--duration", "0"], capsys)
    assert rc == 2 and session.sent == []
    assert f"hydromon replay: error: {recording}: no message in the window (--start, --duration, --keys): nothing sent" in err


def test_a_bus_replay_of_another_namespace_says_where_its_messages_go(recording, tmp_path, capsys, monkeypatch):
    import contextlib

    site = _rewrite(recording, tmp_path / "site.mcap", key=lambda k: k.replace("hydro/", "site1/lineA/", 1), n=600)
    session = _FakeSession(_FakeTime())
    monkeypatch.setattr("hydromon.cli.commands.replay.session_from_args", lambda args: contextlib.nullcontext(session))
    rc, err = _cli(["replay", str(site), "--quiet", "--rate", "0", "--wait", "0"], capsys)
    assert rc == 0 and session.sent and all(k.startswith("site1/lineA/") for k, *_ in session.sent)
    assert "recorded under namespace site1/lineA" in err and "--namespace site1/lineA" in err
    rc, err = _cli(["replay", str(recording), "--quiet", "--rate", "0", "--wait", "0"], capsys)
    assert rc == 0 and "recorded under namespace" not in err


def test_a_replay_cut_short_exits_1_unless_looping():
    # `hydromon replay F` stopped by Ctrl-C after 3 s of 20 exits 1, so a script's
    # `replay && evaluate` does not go on as if the whole record had been sent
    from hydromon.bus.replay import ReplayStats
    from hydromon.cli.commands.replay import exit_code

    assert exit_code(ReplayStats(published=10, passes=1), loop=False) == 0
    assert exit_code(ReplayStats(published=10, passes=0, stopped_at=3.0), loop=False) == 1
    assert exit_code(ReplayStats(published=10, passes=2, stopped_at=3.0), loop=True) == 0


def test_a_bus_replay_skips_topics_that_are_not_zenoh_keys_and_says_so(recording, tmp_path, capsys, monkeypatch):
    import contextlib

    # a ROS-style topic (a leading slash) cannot be a zenoh key: zenoh refuses to declare it
    ros = _rewrite(recording, tmp_path / "ros.mcap", key=lambda k: "/" + k if k.endswith("/config") else k, n=600)
    session = _FakeSession(_FakeTime())
    monkeypatch.setattr("hydromon.cli.commands.replay.session_from_args", lambda args: contextlib.nullcontext(session))
    rc, err = _cli(["replay", str(ros), "--quiet", "--rate", "0", "--wait", "0"], capsys)
    assert rc == 0 and session.sent and not any(k.startswith("/") for k, *_ in session.sent)
    assert "that are not zenoh keys and cannot be published: '/hydro/rig/" in err and "Traceback" not in err
