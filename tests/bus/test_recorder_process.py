"""The recorder as a separate process: killed, stopped, timed; and its clock."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time

import pytest
import zenoh

from helpers import SECOND_NS as NS
from helpers import health_seqs, sample_bytes, wait_for, window_end  # noqa: F401
from hydromon.bus.session import listening_session
from hydromon.contract import sample_key
from hydromon.store.mcap_layout import MAGIC, TruncatedRecording
from hydromon.store.mcap_read import read_recording, read_samples
from hydromon.store.mcap_recover import recover

BLOCK = zenoh.CongestionControl.BLOCK  # tests must not lose samples to a full queue


def _live_count(path) -> int:
    """Messages readable from a snapshot of a file that is still being written."""
    data = path.read_bytes() if path.exists() else b""
    if len(data) < len(MAGIC):  # just created: recover refuses what is shorter than the magic
        return 0
    return recover(io.BytesIO(data), io.BytesIO()).messages


def _live_seqs(path) -> set[int]:
    """Sample seqs readable from a snapshot of a file that is still being written."""
    data = path.read_bytes() if path.exists() else b""
    if len(data) < len(MAGIC):  # just created: recover refuses what is shorter than the magic
        return set()
    fixed = io.BytesIO()
    recover(io.BytesIO(data), fixed)
    return {json.loads(m[1])["seq"] for m in read_recording(fixed) if m[0].endswith("/sample")}


def _record_process(out, ep, log):
    """``hydromon record`` connecting to ``ep``, where the test's session already listens: the
    recorder's session is up as soon as it opens. (The other way round, the test's session
    connected before the process listened, and zenoh's connect retries, backing off to every
    4 s, decided when the two met: one CI run waited 45 s in vain, and under load a monitor
    process met its test up to 4 s late.)"""
    return subprocess.Popen(
        [sys.executable, "-m", "hydromon.cli", "record", "--out", str(out), "--connect", ep],
        stdout=log, stderr=log, env={**os.environ, "PYTHONUNBUFFERED": "1"})


def _wait_subscribed(pub, proc, log_path):
    """Wait for the recorder process's subscription; fail at once if it exits, and with its
    log either way (one CI run timed out here after 45 s with nothing to go on)."""
    def alive():
        if proc.poll() is not None:
            raise AssertionError(f"the recorder exited ({proc.returncode}); its log: {log_path.read_text()[-2000:]!r}")
    try:
        wait_for(lambda: pub.matching_status.matching, 45, "the recorder process to subscribe", alive=alive)
    except AssertionError as exc:
        if "its log" in str(exc):
            raise
        raise AssertionError(f"{exc}; the recorder's log: {log_path.read_text()[-2000:]!r}") from None


@pytest.mark.network
@pytest.mark.timeout(90)
def test_sigkilled_recorder_loses_at_most_its_last_second(tmp_path):
    out = tmp_path / "killed.mcap"
    with open(tmp_path / "record.log", "wb") as log, listening_session() as (session, ep):
        proc = _record_process(out, ep, log)
        try:
            pub = session.declare_publisher(sample_key("k1"), congestion_control=BLOCK)
            _wait_subscribed(pub, proc, tmp_path / "record.log")
            sent_ns = []
            start = time.monotonic()
            i = 0
            while time.monotonic() - start < 3.0:  # 100 Hz for ~3 s
                now = time.time_ns()
                pub.put(sample_bytes(i, now / NS))
                sent_ns.append(now)
                i += 1
                time.sleep(0.01)
                if i % 15 == 0:
                    # what is on disk now is what a kill now would leave: check it too
                    snap_ns = time.time_ns()
                    on_disk = _live_seqs(out)
                    due = {k for k, t in enumerate(sent_ns) if t < snap_ns - NS}
                    assert due <= on_disk, f"{len(due - on_disk)} samples > 1 s old not on disk"
            kill_ns = time.time_ns()
            proc.send_signal(signal.SIGKILL)
            proc.wait(20)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(20)
    assert proc.returncode == -signal.SIGKILL
    with pytest.raises(TruncatedRecording):
        read_recording(out)
    fixed = tmp_path / "fixed.mcap"
    report = recover(out, fixed)
    _, _, seq = read_samples(fixed)
    old = [k for k, t in enumerate(sent_ns) if t < kill_ns - NS]
    assert len(old) > 100
    assert set(old) <= set(seq.tolist()), report.summary()
    assert seq.tolist() == list(range(len(seq)))  # a prefix, in order


@pytest.mark.network
@pytest.mark.timeout(90)
def test_sigterm_stops_the_recorder_cleanly_with_a_complete_file(tmp_path):
    out = tmp_path / "clean.mcap"
    with open(tmp_path / "record.log", "wb") as log, listening_session() as (session, ep):
        proc = _record_process(out, ep, log)
        try:
            pub = session.declare_publisher(sample_key("k2"), congestion_control=BLOCK)
            _wait_subscribed(pub, proc, tmp_path / "record.log")
            for i in range(50):
                pub.put(sample_bytes(i, i * 0.01))
            # the live file is flushed within the flush interval: all 50 become readable
            wait_for(lambda: _live_count(out) == 50, 20, "the 50 samples in the live file")
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(30) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(20)
    printed = (tmp_path / "record.log").read_text()
    assert str(out) in printed
    _, _, seq = read_samples(out)  # has its summary: no recover needed
    assert seq.tolist() == list(range(50))


@pytest.mark.network
@pytest.mark.timeout(60)
def test_record_command_stops_after_its_duration_and_prints_the_file(tmp_path, capsys):
    from hydromon.cli.main import main as cli_main

    out = tmp_path / "sub" / "short.mcap"
    assert cli_main(["record", "--out", str(out), "--listen", "tcp/127.0.0.1:0", "--duration", "0.3"]) == 0
    captured = capsys.readouterr()
    assert captured.out.split() == [str(out)]
    assert f"writing {out}" in captured.err
    assert list(read_recording(out)) == []  # a complete, empty recording


def test_the_recorders_clock_does_not_follow_a_wall_clock_step():
    # log times follow a steady clock, not time.time_ns() per message: an NTP step back during a
    # recording would put later samples before earlier ones in log-time order (evaluate would call
    # it a rig restart), and a step forward would be waited out by a paced replay and end
    # --duration at once
    from hydromon.bus.recorder import steady_wall_clock

    wall, mono = [1_700_000_000 * NS], [5 * NS]
    clock = steady_wall_clock(lambda: wall[0], lambda: mono[0])
    assert clock() == 1_700_000_000 * NS
    wall[0] -= 3600 * NS  # the wall clock is set back an hour...
    mono[0] += NS // 100  # ...while 10 ms pass
    assert clock() == 1_700_000_000 * NS + NS // 100
    wall[0] += 7200 * NS
    mono[0] += NS // 100
    assert clock() == 1_700_000_000 * NS + 2 * (NS // 100)
