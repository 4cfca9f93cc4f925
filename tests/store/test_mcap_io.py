"""MCAP edge: writer -> reader round trips in memory, metadata, chunk flushing, recovery."""

from __future__ import annotations

import io
import json
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from helpers import SECOND_NS as NS
from helpers import (
    chunk_spans,
    config_and_samples,
    flip_in_chunk,
    health_bytes,
    sample_bytes,
    sample_stream,
    write_messages,
)
from hydromon.contract import Health, RigConfig, Sample
from hydromon.store.mcap_layout import CorruptRecording, RecordingError, TruncatedRecording
from hydromon.store.mcap_read import read_recording, read_rig_config, read_samples
from hydromon.store.mcap_write import RecordingWriter


# -- writer -> reader ---------------------------------------------------------------------------
def test_round_trip_in_memory_with_schemas_and_encodings():
    cfg = RigConfig(p_s=11e6).model_dump_json().encode()
    msgs = [("hydro/rig/r1/config", cfg, NS, NS)]
    msgs += sample_stream(20)
    msgs += [("hydro/rig/r1/health", health_bytes(0, 0.1), 6 * NS, 100_000_000),
             ("hydro/other/thing", b'{"x": 1}', 7 * NS, 7 * NS)]
    data, _ = write_messages(msgs)

    got = list(read_recording(io.BytesIO(data)))
    assert got == sorted(msgs, key=lambda m: m[2])

    summary = make_reader(io.BytesIO(data)).get_summary()
    by_topic = {c.topic: c for c in summary.channels.values()}
    assert set(by_topic) == {m[0] for m in msgs}
    expected = {"hydro/rig/r1/sample": Sample.model_json_schema(),
                "hydro/rig/r1/health": Health.model_json_schema(),
                "hydro/rig/r1/config": RigConfig.model_json_schema(),
                "hydro/other/thing": {}}
    for topic, ch in by_topic.items():
        assert ch.message_encoding == "json"
        schema = summary.schemas[ch.schema_id]
        assert schema.encoding == "jsonschema"
        assert json.loads(schema.data) == expected[topic]
    # one schema per payload model, shared by channels
    assert len(summary.schemas) == 4
    assert summary.statistics.message_count == len(msgs)


def test_read_recording_filters_topics_and_half_open_time_range():
    msgs = sample_stream(10, rig="a") + sample_stream(10, rig="b")
    data, _ = write_messages(msgs)
    a = list(read_recording(io.BytesIO(data), topics="hydro/rig/a/sample"))
    assert [m[0] for m in a] == ["hydro/rig/a/sample"] * 10
    start, end = 5 * NS + 20_000_000, 5 * NS + 50_000_000
    window = list(read_recording(io.BytesIO(data), start_ns=start, end_ns=end))
    assert sorted(m[2] for m in window) == [start, start, start + 10_000_000, start + 10_000_000,
                                            start + 20_000_000, start + 20_000_000]


def test_reader_sorts_by_log_time_when_written_out_of_order():
    msgs = sample_stream(30)
    shuffled = msgs[:]
    random.Random(3).shuffle(shuffled)
    data, _ = write_messages(shuffled, flush_interval_ns=50_000_000)
    assert [m[2] for m in read_recording(io.BytesIO(data))] == [m[2] for m in msgs]


def _library_order(data, topics=None, start_ns=None, end_ns=None):
    return [(c.topic, m.data, m.log_time, m.publish_time) for _s, c, m in make_reader(io.BytesIO(data))
            .iter_messages(topics=topics, starting_at=start_ns, ending_before=end_ns)]


@settings(max_examples=60, deadline=None)
@given(times=st.lists(st.integers(0, 40), min_size=1, max_size=80), seed=st.integers(0, 10**6),
       flush=st.sampled_from([None, 3, 10, 25]), window=st.tuples(st.integers(-5, 45), st.integers(-5, 45)),
       topic_filter=st.booleans())
def test_chunked_fast_path_yields_exactly_the_library_log_time_order(times, seed, flush, window, topic_filter):
    # ties in log time, messages written out of order (inside a chunk and across chunks), filters:
    # read_recording takes its own chunk-by-chunk path when chunks do not overlap in time and
    # the library's merge otherwise; both must give the library's order, message for message
    rng = random.Random(seed)
    msgs = [(f"hydro/rig/r{rng.randrange(3)}/sample", sample_bytes(i, 0.01 * i), NS + t * 1_000_000, i)
            for i, t in enumerate(times)]
    if rng.random() < 0.5:
        msgs.sort(key=lambda m: m[2])  # in order, as recorded: the fast path is taken
    kw = {} if flush is None else {"flush_interval_ns": flush * 1_000_000}
    data, _ = write_messages(msgs, chunk_size=rng.choice([300, 4 * 1024 * 1024]), **kw)
    topics = ["hydro/rig/r1/sample"] if topic_filter else None
    lo, hi = (NS + w * 1_000_000 for w in sorted(window))
    assert list(read_recording(io.BytesIO(data))) == _library_order(data)
    assert list(read_recording(io.BytesIO(data), topics=topics, start_ns=lo, end_ns=hi)) == \
        _library_order(data, topics, lo, hi)


def test_read_recording_from_a_path(tmp_path):
    data, _ = write_messages(sample_stream(5))
    p = tmp_path / "x.mcap"
    p.write_bytes(data)
    assert len(list(read_recording(p))) == 5
    assert len(list(read_recording(str(p)))) == 5


def test_metadata_holds_each_rig_config_once_per_change():
    c1 = RigConfig(p_s=10e6).model_dump_json().encode()
    c2 = RigConfig(p_s=9e6, F_L=-100.0).model_dump_json().encode()
    other = RigConfig(A1=0.01).model_dump_json().encode()
    msgs = [("hydro/rig/r1/config", c1, 1, 1), ("hydro/rig/r1/config", c1, 2, 2),
            ("hydro/rig/r2/config", other, 3, 3), ("hydro/rig/r1/config", c2, 4, 4)]
    data, _ = write_messages(msgs)
    meta = [(m.name, m.metadata) for m in make_reader(io.BytesIO(data)).iter_metadata()]
    assert [name for name, _ in meta] == ["rig_config/r1", "rig_config/r2", "rig_config/r1"]
    assert json.loads(meta[0][1]["p_s"]) == 10e6
    assert read_rig_config(io.BytesIO(data), "r1") == RigConfig(p_s=9e6, F_L=-100.0)
    assert read_rig_config(io.BytesIO(data), "r2") == RigConfig(A1=0.01)
    # the config messages themselves are all recorded
    assert len(list(read_recording(io.BytesIO(data), topics="hydro/rig/r1/config"))) == 3
    with pytest.raises(ValueError, match="no config for rig 'r3'"):
        read_rig_config(io.BytesIO(data), "r3")
    with pytest.raises(ValueError, match="rig id"):
        read_rig_config(io.BytesIO(data), "../etc")


def test_invalid_config_is_recorded_but_not_stored_as_metadata():
    buf = io.BytesIO()
    with RecordingWriter(buf) as w:
        w.write("hydro/rig/r1/config", b'{"A1": -1}', 1, 1)
        assert w.invalid_configs == 1
    assert list(make_reader(io.BytesIO(buf.getvalue())).iter_metadata()) == []
    assert len(list(read_recording(io.BytesIO(buf.getvalue())))) == 1


@pytest.mark.parametrize("kw, match", [
    ({"compression": "gzip"}, "compression 'gzip'"),
    ({"chunk_size": 0}, "chunk_size=0"),
    ({"flush_interval_ns": 0.5}, "flush_interval_ns=0.5"),
])
def test_writer_rejects_bad_settings(kw, match):
    with pytest.raises(ValueError, match=match):
        RecordingWriter(io.BytesIO(), **kw)


@pytest.mark.parametrize("args, match", [
    (("k", b"{}", -1, 0), "log_time_ns=-1"),
    (("k", b"{}", 1.5, 0), "log_time_ns=1.5"),
    (("k", b"{}", 0, 2**64), "publish_time_ns="),
    (("", b"{}", 0, 0), "key ''"),
    (("k", "{}", 0, 0), "must be bytes"),
])
def test_writer_rejects_bad_messages(args, match):
    w = RecordingWriter(io.BytesIO())
    with pytest.raises(ValueError, match=match):
        w.write(*args)


def test_write_after_close_raises():
    w = RecordingWriter(io.BytesIO())
    w.close()
    with pytest.raises(ValueError, match="closed"):
        w.write("k", b"{}", 0, 0)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_every_compression_round_trips(compression):
    msgs = sample_stream(50)
    data, _ = write_messages(msgs, compression=compression, flush_interval_ns=100_000_000)
    assert list(read_recording(io.BytesIO(data))) == msgs


# -- read_samples ---------------------------------------------------------------------------
def test_read_samples_returns_si_arrays_in_contract_column_order():
    msgs = sample_stream(40, rig="a") + sample_stream(3, rig="b")
    data, _ = write_messages(msgs)
    rig, arr, seq = read_samples(io.BytesIO(data), rig="a")
    assert rig == "a" and arr.shape == (40, 6) and arr.dtype == np.float64
    expected = np.array([[s.t, s.ug, s.x1, s.x3, s.x4, s.x5]
                         for s in (Sample.model_validate_json(m[1]) for m in msgs[:40])])
    np.testing.assert_array_equal(arr, expected)
    np.testing.assert_array_equal(seq, np.arange(40))
    assert arr[5, 3] == 6e6 + 5  # x3 in Pa, not MPa


def test_read_samples_needs_a_rig_when_there_are_several():
    data, _ = write_messages(sample_stream(3, rig="a") + sample_stream(3, rig="b"))
    with pytest.raises(ValueError, match=r"several rigs \(a, b\)"):
        read_samples(io.BytesIO(data))
    with pytest.raises(ValueError, match="rig 'c' not in recording; it holds a, b"):
        read_samples(io.BytesIO(data), rig="c")
    only, _ = write_messages(sample_stream(3, rig="solo"))
    assert read_samples(io.BytesIO(only))[0] == "solo"


def test_read_samples_rejects_a_bad_sample_naming_it():
    msgs = sample_stream(3)
    msgs.append(("hydro/rig/r1/sample", b'{"seq": 3, "t": 0.03, "ug": 0, "x1": 0, "x3": 1, "x4": 1}',
                 9 * NS, 0))
    data, _ = write_messages(msgs)
    with pytest.raises(RecordingError, match="bad sample on hydro/rig/r1/sample .*x5"):
        read_samples(io.BytesIO(data))


# -- truncation, flushing, recovery ---------------------------------------------------------
def test_reading_a_cut_file_says_truncated_and_names_recover():
    data, _ = write_messages(sample_stream(100))
    with pytest.raises(TruncatedRecording, match="hydromon recover"):
        read_recording(io.BytesIO(data[: len(data) // 2]))
    with pytest.raises(CorruptRecording, match="not an MCAP file"):
        read_recording(io.BytesIO(b"hello world, not mcap at all"))


def test_reading_a_chunk_that_fails_its_crc_says_so_never_returns_other_bytes():
    msgs = config_and_samples()
    data, _ = write_messages(msgs, flush_interval_ns=NS // 2)
    bad = flip_in_chunk(data, 4)
    with pytest.raises(CorruptRecording, match=f"damaged recording: the chunk at byte {chunk_spans(data)[4][0]} "
                                               r"\(log time 7.000-7.490 s\) (fails its CRC check|does not decompress)"
                                               ".*run `hydromon recover"):
        list(read_recording(io.BytesIO(bad)))
    assert list(read_recording(io.BytesIO(bad), end_ns=7 * NS)) == [m for m in msgs if m[2] < 7 * NS]


