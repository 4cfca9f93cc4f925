"""Recorder node: file rotation and naming, publish times, and real zenoh sessions on loopback
(in a thread with a stop event, and as a separate process that is SIGKILLed then recovered)."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import zenoh

from helpers import SECOND_NS as NS
from helpers import sample_bytes, wait_for
from hydromon.bus.recorder import Rotation, publish_time_ns, record
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import RigConfig, config_key, sample_key
from hydromon.store.mcap_read import read_recording, read_rig_config, read_samples

BLOCK = zenoh.CongestionControl.BLOCK  # tests must not lose samples to a full queue


# -- pure parts -----------------------------------------------------------------------------
@pytest.mark.parametrize("obj, expected", [
    ({"t": 1.5}, 1_500_000_000),
    ({"t": 2}, 2 * NS),
    ({"t": 0.0}, 0),
    ({"t": -1.0}, 777),      # before the epoch of the MCAP time: receive time
    ({"t": 1e30}, 777),      # beyond uint64 ns
    ({"t": True}, 777),
    ({"t": "3"}, 777),
    ({"x": 1}, 777),
    ([1, 2], 777),
])
def test_publish_time_is_the_payload_t_in_ns_else_the_receive_time(obj, expected):
    assert publish_time_ns(obj, 777) == expected


def _rotation(tmp_path, **kw):
    opened = []
    kw.setdefault("rotate_bytes", None)
    kw.setdefault("rotate_ns", None)
    r = Rotation(kw.pop("out", tmp_path / "run.mcap"), "hydro", kw["rotate_bytes"], kw["rotate_ns"],
                 {"flush_interval_ns": NS}, opened.append, 0)
    return r, opened


def test_rotation_by_size_keeps_every_message_and_carries_configs(tmp_path):
    r, opened = _rotation(tmp_path, rotate_bytes=3000)
    cfg = RigConfig(p_s=10e6).model_dump_json().encode()
    r.write(config_key("r1"), cfg, 1, 1)
    n = 600
    for i in range(n):
        now = 2 + i * 10_000_000
        r.write(sample_key("r1"), sample_bytes(i, i * 0.01), now, now)
        r.tick(now)
    r.close()
    assert len(r.files) > 2 and opened == r.files
    assert [p.name for p in r.files[:3]] == ["run.mcap", "run-1.mcap", "run-2.mcap"]
    seqs = []
    for p in r.files:
        _, _, seq = read_samples(p)  # every part is a complete, valid recording
        seqs.extend(seq)
        assert read_rig_config(p, "r1") == RigConfig(p_s=10e6)
        # ... as a config message ahead of the part's first sample, so a replay of one part alone
        # grades with the rig's constants, not the defaults
        first = next(iter(read_recording(p)))
        assert first[0] == config_key("r1") and first[1] == cfg
    assert seqs == list(range(n))


def test_rotation_by_age_and_never_an_empty_part(tmp_path):
    r, _ = _rotation(tmp_path, rotate_ns=NS)
    r.tick(5 * NS)  # old but empty: no new file
    assert len(r.files) == 1
    for i in range(30):  # 3 s of messages
        now = 5 * NS + i * 100_000_000
        r.write("hydro/rig/a/sample", sample_bytes(i, i * 0.1), now, now)
        r.tick(now)
    r.close()
    assert len(r.files) == 3
    assert sum(len(list(read_recording(p))) for p in r.files) == 30


def test_a_quiet_bus_after_a_rotation_makes_no_empty_part(tmp_path):
    # the live recorder ticks on while the bus is quiet: the old part is closed when due (complete
    # at once), but the next one is opened only by the next message
    r, opened = _rotation(tmp_path, rotate_ns=NS)
    r.write("hydro/rig/a/sample", sample_bytes(0, 0.0), NS, NS)
    for k in range(2, 20):  # 18 s of ticks, nothing received
        r.tick(k * NS)
    assert len(r.files) == 1 and len(list(read_recording(r.files[0]))) == 1  # closed: readable now
    r.write("hydro/rig/a/sample", sample_bytes(1, 0.01), 20 * NS, 20 * NS)
    r.tick(20 * NS)
    r.close()
    assert opened == r.files and [len(list(read_recording(p))) for p in r.files] == [1, 1]


def test_directory_output_uses_namespace_and_time_never_a_rig_id(tmp_path):
    r, _ = _rotation(tmp_path, out=tmp_path)
    r.write("hydro/rig/evil_rig/sample", sample_bytes(0, 0.0), 1, 1)
    r.close()
    (path,) = r.files
    assert path.parent == tmp_path and path.name.startswith("hydro-") and path.suffix == ".mcap"
    assert "evil" not in path.name


def test_rotation_refuses_to_overwrite_a_recording(tmp_path):
    (tmp_path / "run.mcap").write_bytes(b"precious")
    with pytest.raises(ValueError, match="refusing to overwrite"):
        _rotation(tmp_path)
    assert (tmp_path / "run.mcap").read_bytes() == b"precious"


def test_record_validates_its_arguments(tmp_path):
    with pytest.raises(ValueError, match="namespace"):
        record(None, tmp_path / "x.mcap", namespace="bad ns")
    with pytest.raises(ValueError, match="rotate_seconds"):
        record(None, tmp_path / "x.mcap", rotate_seconds=0)
    with pytest.raises(ValueError, match="rotate_bytes"):
        record(None, tmp_path / "x.mcap", rotate_bytes=-5)


# -- real zenoh sessions on loopback ----------------------------------------------------------
@pytest.mark.network
@pytest.mark.timeout(60)
def test_record_over_a_real_zenoh_session_in_a_thread(tmp_path):
    n = 200
    with listening_session() as (rec_session, ep), open_session("peer", connect=[ep]) as pub_session:
        got = threading.Event()
        count = {"n": 0}

        def on_message(key):
            count["n"] += 1
            if count["n"] == n + 2:
                got.set()

        stop = threading.Event()
        out = tmp_path / "live.mcap"
        result = {}
        worker = threading.Thread(target=lambda: result.update(r=record(
            rec_session, out, stop_event=stop, on_message=on_message)), daemon=True)
        worker.start()
        pub = pub_session.declare_publisher(sample_key("rig-7"), congestion_control=BLOCK)
        wait_for(lambda: pub.matching_status.matching, 20, "the recorder's subscription")
        pub_session.put(config_key("rig-7"), RigConfig(K_f=42.0).model_dump_json())
        for i in range(n):
            pub.put(sample_bytes(i, 100.0 + i * 0.01))
        # the non-JSON one first: it does not reach on_message, so it must not be the last in flight
        pub_session.put("hydro/notes/y", b"not json")
        pub_session.put("hydro/notes/x", b'{"hello": 1}')
        assert got.wait(20), f"recorder saw {count['n']} of {n + 2} messages"
        stop.set()
        worker.join(20)
        assert not worker.is_alive()
    res = result["r"]
    assert res.files == [out] and res.messages == n + 2 and res.not_json == 1
    rig, arr, seq = read_samples(out)
    assert rig == "rig-7" and seq.tolist() == list(range(n))
    np.testing.assert_allclose(arr[:, 0], 100.0 + np.arange(n) * 0.01)
    assert read_rig_config(out, "rig-7").K_f == 42.0
    msgs = list(read_recording(out, topics=sample_key("rig-7")))
    assert [m[3] for m in msgs] == [round((100.0 + i * 0.01) * 1e9) for i in range(n)]  # publish = t
    assert all(m[2] > 1_600_000_000 * NS for m in msgs)  # log time = wall-clock receive time


@pytest.mark.network
@pytest.mark.timeout(60)
def test_a_recorder_started_late_asks_the_running_rigs_for_their_configs(tmp_path):
    # a rig publishes its config once, at its start; a recorder started after the rigs must still
    # record it, or the recording is evaluated and replayed with the default rig constants
    # (`hydromon sim --fleet` with p_s 16 MPa, F_L 6 kN graded that way: m 287 kg, not 125).
    # The sim node answers late joiners on <ns>/rig/*/config, as the monitor uses.
    cfg = RigConfig(K_f=42.0, p_s=16e6).model_dump_json().encode()
    with listening_session() as (rig_session, ep), open_session("peer", connect=[ep]) as rec_session:
        queryable = rig_session.declare_queryable(
            "hydro/rig/*/config", lambda q: q.reply(config_key("rig-7"), cfg))
        stop, result, count = threading.Event(), {}, {"n": 0}
        out = tmp_path / "late.mcap"
        worker = threading.Thread(target=lambda: result.update(r=record(
            rec_session, out, stop_event=stop, on_message=lambda key: count.__setitem__("n", count["n"] + 1))),
            daemon=True)
        worker.start()
        pub = rig_session.declare_publisher(sample_key("rig-7"), congestion_control=BLOCK)
        wait_for(lambda: pub.matching_status.matching, 20, "the recorder's subscription")
        for i in range(20):
            pub.put(sample_bytes(i, i * 0.01))
        wait_for(lambda: count["n"] >= 21, 20, "the samples and the config")
        stop.set()
        worker.join(20)
        queryable.undeclare()
    assert not worker.is_alive()
    assert read_rig_config(out, "rig-7") == RigConfig(K_f=42.0, p_s=16e6)
    msgs = [m[:2] for m in read_recording(out)]
    assert msgs.count((config_key("rig-7"), cfg)) == 1  # as a message too (where it took effect)
    assert [m[0] for m in msgs].count(sample_key("rig-7")) == 20


@pytest.mark.network
@pytest.mark.timeout(60)
def test_a_burst_of_bogus_keys_and_configs_does_not_flood_the_recorders_log(tmp_path, caplog):
    # fault injection: 50,000 distinct bogus rig ids with non-JSON payloads made 50,000 log
    # lines (one per key, and a set of every key held); invalid configs, one line each
    n = 500
    with listening_session() as (rec_session, ep), open_session("peer", connect=[ep]) as pub_session:
        stop, result, probe_in = threading.Event(), {}, threading.Event()

        def on_message(key):
            if key == "hydro/rig/probe/sample":
                probe_in.set()

        worker = threading.Thread(target=lambda: result.update(r=record(rec_session, tmp_path / "b.mcap",
                                                                        stop_event=stop, on_message=on_message)),
                                  daemon=True)
        with caplog.at_level("WARNING"):
            worker.start()
            pub = pub_session.declare_publisher("hydro/rig/probe/sample", congestion_control=BLOCK)
            wait_for(lambda: pub.matching_status.matching, 20, "the recorder's subscription")
            for i in range(n):
                pub_session.put(f"hydro/rig/bogus{i:05d}/sample", b"junk", congestion_control=BLOCK)
                pub_session.put(f"hydro/rig/bogus{i:05d}/config", b'{"A1": -1}', congestion_control=BLOCK)
            pub.put(sample_bytes(0, 0.0))
            # the probe sample went last on the same session and link: once the recorder has
            # handled it, it has handled the whole burst (a fixed 1 s sleep here was a race)
            assert probe_in.wait(30), f"the probe sample never reached the recorder ({caplog.text[-500:]!r})"
            assert "on more keys" in caplog.text and caplog.text.count("not a valid RigConfig") >= 20
            stop.set()
            worker.join(20)
        assert not worker.is_alive()
    res = result["r"]
    assert res.not_json == n
    lines = [r for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) <= 2 * 21, len(lines)
    assert any("counted, not logged" in r.getMessage() for r in lines if "RigConfig" in r.getMessage())


def test_a_part_carries_the_last_valid_config_not_a_rejected_one(tmp_path):
    # an invalid config payload (which the monitor rejects) is not carried into later parts
    r, _ = _rotation(tmp_path, rotate_bytes=3000)
    good = RigConfig(F_L=3000.0).model_dump_json().encode()
    r.write(config_key("r1"), good, 1, 1)
    for i in range(400):
        now = 2 + i * 10_000_000
        if i == 150:
            r.write(config_key("r1"), b'{"F_L": "oops"}', now, now)
        r.write(sample_key("r1"), sample_bytes(i, i * 0.01), now, now)
        r.tick(now)
    r.close()
    assert len(r.files) > 3
    first = next(iter(read_recording(r.files[-1])))
    assert first[0] == config_key("r1") and first[1] == good


def test_the_config_query_is_sent_again_for_a_rig_whose_config_was_not_seen():
    # the first query can find no route (the links or the peers' declarations not yet up, or the
    # rig starts later): a sample of a rig without a config asks again, once per rig, at most
    # every second; a reply already recorded is not recorded again
    from hydromon.bus.recorder import _ConfigQuery

    class Reply:
        def __init__(self, key, payload):
            self.ok = type("S", (), {"key_expr": key, "payload": type("P", (), {"to_bytes": lambda s: payload})()})()

    class Replies:
        def __init__(self, items):
            self.items = list(items)

        def try_recv(self):
            if self.items:
                return self.items.pop(0)
            raise zenoh.ZError("query over")

    class Session:
        def __init__(self):
            self.answers, self.queries = [], 0

        def get(self, selector, handler, timeout):
            assert selector == "hydro/rig/*/config"
            self.queries += 1
            return Replies(self.answers)

    now, session, got = [0.0], Session(), []
    q = _ConfigQuery(session, "hydro", 5.0, clock=lambda: now[0])
    assert q.drain(got.append, {}) == 0 and session.queries == 1  # at the start: no answer yet
    for i in range(3):
        q.saw(sample_key("rig-7"))
    now[0] = 0.5
    q.drain(got.append, {})
    assert session.queries == 1  # not twice in a second
    session.answers = [Reply(config_key("rig-7"), b"{}"), Reply(config_key("rig-8"), b"{}")]
    now[0] = 1.0
    assert q.drain(got.append, {config_key("rig-8"): b"{}"}) == 1 and session.queries == 2
    assert [str(s.key_expr) for s in got] == [config_key("rig-7")]
    q.saw(config_key("rig-7"))  # handle() notes the recorded reply
    q.saw(sample_key("rig-7"))
    now[0] = 5.0
    q.drain(got.append, {})
    assert session.queries == 2  # rig-7 has its config: no more queries
