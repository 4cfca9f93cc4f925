"""The recorder against everything the bus can send it, and a disk that fills up: real zenoh
sessions on loopback, the recorder in a thread of this process."""

from __future__ import annotations

import os
import shutil
import subprocess
import threading
import time

import orjson
import pytest
import zenoh

from helpers import BAD_SAMPLES, sample_bytes, wait_for
from hydromon.bus.recorder import Rotation, publish_time_ns, record
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import sample_key
from hydromon.store.mcap_read import read_recording, read_samples

BLOCK = zenoh.CongestionControl.BLOCK
NS = 1_000_000_000
RIG = "r1"


# -- time fields ------------------------------------------------------------------------------------
@pytest.mark.parametrize("t", [1e300, -1e300, -1, -0.5, 1.8446744073709552e10, 2**64, 2**63 - 1, 10**30,
                               "nan", "NaN", "inf", "-Infinity", "1e300", None, True, [], [[1.0]], ["1"], [1e300],
                               {"s": 1}])
def test_a_time_that_no_timestamp_holds_is_not_used_as_one(t):
    assert publish_time_ns({"t": t}, 777) == 777


def test_a_plausible_time_is_used_to_the_nanosecond():
    assert publish_time_ns({"t": 1.5}, 7) == 1_500_000_000
    assert publish_time_ns({"t": 18446744073}, 7) == 18446744073 * NS  # the last whole second uint64 ns holds
    assert publish_time_ns({"t": [2.5, 2.51]}, 7) == 2_500_000_000  # a frame: its first sample's time


# -- everything the bus can send --------------------------------------------------------------------
ARBITRARY_KEYS = ["hydro/rig/r1/health", "hydro/rig/r1/config", "hydro/rig/r1/event", "hydro/x", "hydro/a/b/c/d",
                  "hydro/rig/other-rig/sample", "hydro/rig/r1/sample/extra"]
BAD_TIMES = [b'{"t":1e300}', b'{"t":-1e300}', b'{"t":-5}', b'{"t":"nan"}', b'{"t":18446744073709551615}',
             b'{"t":1e300,"seq":1,"ug":0,"x1":0,"x3":0,"x4":0,"x5":0}']
BIG = 10_000_000  # [B]


def _is_json(payload: bytes) -> bool:
    try:
        orjson.loads(payload)
    except orjson.JSONDecodeError:
        return False
    return True


@pytest.mark.network
@pytest.mark.timeout(120)
def test_no_payload_on_any_key_stops_the_recorder_and_no_valid_message_is_lost(tmp_path, caplog):
    junk = [p for _, p in BAD_SAMPLES] + BAD_TIMES
    messages = []  # (key, payload) in the order sent
    seq = 0
    for i, payload in enumerate(junk):
        for key in [sample_key(RIG)] + ARBITRARY_KEYS:
            messages.append((sample_key(RIG), sample_bytes(seq, seq * 0.01)))
            seq += 1
            messages.append((key, payload))
    # the bus node's catalogue too: bad configs on a config key, good samples under bad rig ids and on
    # keys outside the contract
    from test_bad_input_bus import BAD_CONFIGS, BAD_RIG_IDS, OUTSIDE

    for _, payload in BAD_CONFIGS:
        messages.append(("hydro/rig/r1/config", payload))
    outside = [k for k in OUTSIDE if k.startswith("hydro/") and "@" not in k]  # ** never matches a verbatim @ chunk
    for key in [f"hydro/rig/{r}/sample" for r in BAD_RIG_IDS] + outside:
        messages.append((key, sample_bytes(0, 0.0)))
    for key in (sample_key(RIG), "hydro/blob", "hydro/rig/r1/health"):  # 10 MB on a sample key and elsewhere
        messages.append((key, b'{"t": 1.0, "pad": "' + b"x" * (BIG - 21) + b'"}'))
        messages.append((sample_key(RIG), sample_bytes(seq, seq * 0.01)))
        seq += 1
    skipped, handled = [], []
    with listening_session() as (rec_session, ep), open_session("peer", connect=[ep]) as pub_session:
        stop, result = threading.Event(), {}
        out = tmp_path / "junk.mcap"
        worker = threading.Thread(target=lambda: result.update(r=record(
            rec_session, out, stop_event=stop, on_message=handled.append,
            on_skip=lambda k, why: skipped.append((k, why)))), daemon=True)
        with caplog.at_level("WARNING"):
            worker.start()
            probe = pub_session.declare_publisher("hydro/probe", congestion_control=BLOCK)
            wait_for(lambda: probe.matching_status.matching, 20, "the recorder's subscription")
            for key, payload in messages:  # one session, one link: zenoh keeps this order
                pub_session.put(key, payload, congestion_control=BLOCK)
            probe.put(b'{"probe": true}')
            wait_for(lambda: "hydro/probe" in handled, 60, "the probe, sent last", poll_s=0.05)
            assert worker.is_alive()
            stop.set()
            worker.join(30)
    assert not worker.is_alive()
    res = result["r"]
    not_json = [(k, p) for k, p in messages if not _is_json(p)]
    big = [(k, p) for k, p in messages if len(p) > 1_000_000]
    assert res.failed == 0 and res.unwritten == 0 and res.disk_full == 0
    assert res.not_json == len(not_json) and res.too_large == len(big) == 3
    assert sorted(skipped) == sorted([(k, "not-json") for k, _ in not_json] + [(k, "too-large") for k, _ in big])
    assert "not recording a payload of 10000000 B on hydro/blob" in caplog.text
    recorded = list(read_recording(out))  # a complete file, readable as it is
    kept = [(k, p) for k, p in messages if _is_json(p) and len(p) <= 1_000_000] + [("hydro/probe", b'{"probe": true}')]
    assert [(k, p) for k, p, _, _ in recorded] == kept  # every JSON payload as received, in order
    assert res.messages == len(kept)
    # every good sample: none lost among the junk (which a reader skips, as the monitor rejects it)
    good = {sample_bytes(i, i * 0.01) for i in range(seq)}
    assert [p for k, p, _, _ in recorded if p in good and k == sample_key(RIG)] == \
        [sample_bytes(i, i * 0.01) for i in range(seq)]
    rejected = []
    _, _, seqs = read_samples(out, RIG, rejected=rejected)
    assert [s for s in seqs.tolist() if s != 1 or seqs.tolist().count(1) == 1] == list(range(seq)) or \
        sorted(seqs.tolist()) == sorted(list(range(seq)) + [1])  # the junk {"t": 1e300, "seq": 1, ...} is a sample
    assert rejected
    # a time no timestamp holds: the receive time instead
    for k, p, log_ns, pub_ns in recorded:
        if p in BAD_TIMES:
            assert pub_ns == log_ns


# -- a disk that fills up -----------------------------------------------------------------------------
def _mount_tmpfs(path, size: str) -> str | None:
    """Mount a tmpfs of ``size`` at ``path``; the reason it cannot be, or None."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return "mounting a tmpfs needs root"
    if shutil.which("mount") is None:
        return "no mount command"
    path.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        return f"mount -t tmpfs refused: {done.stderr.strip() or done.returncode}"
    return None


@pytest.fixture
def small_disk(tmp_path):
    """A 6 MB tmpfs (skipped where this process cannot mount one)."""
    disk = tmp_path / "disk"
    why = _mount_tmpfs(disk, "6m")
    if why:
        pytest.skip(f"no small disk to fill: {why}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)


def _fill(disk, leave_bytes: int):
    """A file that takes the disk's space until ``leave_bytes`` are free."""
    free = shutil.disk_usage(disk).free
    with open(disk / "filler", "ab") as f:
        f.write(b"\0" * max(0, free - leave_bytes))
    return disk / "filler"


@pytest.mark.network
@pytest.mark.timeout(120)
def test_a_full_disk_closes_the_file_complete_counts_what_it_cannot_write_and_resumes_in_a_new_file(
        small_disk, caplog):
    chunk = 32 * 1024
    handled, skipped = [], []
    sent = 0

    def send(pub, n):
        nonlocal sent
        for _ in range(n):
            pub.put(sample_bytes(sent, sent * 0.01))
            sent += 1

    with listening_session() as (rec_session, ep), open_session("peer", connect=[ep]) as pub_session:
        stop, result = threading.Event(), {}
        worker = threading.Thread(target=lambda: result.update(r=record(
            rec_session, small_disk / "run.mcap", stop_event=stop, chunk_size=chunk, flush_interval_ns=NS // 20,
            max_payload_bytes=64 * 1024, on_message=handled.append, on_skip=lambda k, why: skipped.append(why))),
            daemon=True)
        with caplog.at_level("WARNING"):
            worker.start()
            pub = pub_session.declare_publisher(sample_key(RIG), congestion_control=BLOCK)
            wait_for(lambda: pub.matching_status.matching, 20, "the recorder's subscription")
            send(pub, 3000)
            wait_for(lambda: len(handled) == 3000, 30, "the first samples")
            # another writer takes the disk: less free than the recorder keeps to close a file complete
            filler = _fill(small_disk, 600_000)
            wait_for(lambda: (send(pub, 50), "disk nearly full" in caplog.text)[1], 30, "the recorder to stop")
            before_full = sent
            send(pub, 1000)  # received while the disk is full: counted
            wait_for(lambda: len(handled) + len(skipped) == sent, 30, "the samples sent meanwhile")
            assert len(skipped) >= 1000 and set(skipped) == {"unwritten"}
            filler.unlink()  # room again
            time.sleep(0.3)  # the recorder looks at the free space every 0.1 s
            n_before = len(handled)
            send(pub, 2000)
            wait_for(lambda: len(handled) == n_before + 2000, 30, "the samples after the room came back")
            stop.set()
            worker.join(30)
    assert not worker.is_alive()
    res = result["r"]
    assert res.disk_full == 1 and res.failed == 0
    assert res.unwritten == len(skipped) and res.messages + res.unwritten == sent
    first, second = res.files
    assert (first.name, second.name) == ("run.mcap", "run-1.mcap")
    _, _, seq1 = read_samples(first)  # closed complete: readable as it is
    _, _, seq2 = read_samples(second)
    # nothing written before the disk filled is lost; what came while it was full is counted
    assert seq1.tolist() == list(range(len(seq1))) and len(seq1) >= 3000 and len(seq1) <= before_full
    assert seq2.tolist() == list(range(sent - 2000, sent))
    assert len(seq1) + res.unwritten + len(seq2) == sent
    print(f"full disk: {sent} samples sent; {len(seq1)} in {first.name} (closed complete), {res.unwritten} received "
          f"while the disk was full (counted, not written), {len(seq2)} in {second.name}; 0 lost otherwise")
    assert "disk has room again" in caplog.text
    assert f"{res.unwritten} message(s) received meanwhile were not recorded" in caplog.text


def test_a_disk_that_fills_under_a_write_leaves_its_complete_chunks_for_recover(small_disk, caplog):
    # the room kept back was taken faster than the recorder looked (or it kept none): the write
    # fails; the file is cut back to its last complete chunk, and the recorder carries on counting
    from hydromon.store.mcap_recover import recover

    r = Rotation(small_disk / "cut.mcap", "hydro", None, None, {"chunk_size": 16 * 1024, "flush_interval_ns": NS // 10},
                 None, 0, low_space_bytes=None)
    filler = _fill(small_disk, 300_000)
    written = 0
    with caplog.at_level("WARNING"):
        for i in range(100_000):
            now = NS + i * 1_000_000
            if not r.write(sample_key(RIG), sample_bytes(i, i * 0.001, ug=float(i % 7), x5=1e-6 * (i % 11)), now, now):
                break
            written += 1
            r.tick(now)
        else:
            pytest.fail("the disk never filled")
    assert r.full and r.disk_full == 1 and r.unwritten == 1
    assert "cut back to its last complete chunk" in caplog.text
    fixed = small_disk.parent / "fixed.mcap"
    report = recover(small_disk / "cut.mcap", fixed)
    _, _, seqs = read_samples(fixed)
    assert report.messages == len(seqs) > 0 and seqs.tolist() == list(range(len(seqs)))  # a prefix, in order
    filler.unlink()
    now = NS + 10**12
    assert r.write(sample_key(RIG), sample_bytes(0, 0.0), now, now)  # room again: a new part
    r.close()
    assert len(r.files) == 2 and len(list(read_recording(r.files[1]))) == 1
