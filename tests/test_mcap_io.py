"""MCAP edge: writer -> reader round trips in memory, metadata, chunk flushing, recovery."""

from __future__ import annotations

import io
import json
import random

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from hydromon import docs_gen
from hydromon.cli import main as cli_main
from hydromon.contract import Health, RigConfig, Sample
from helpers import chunk_spans, flip_in_chunk
from hydromon.mcap_io import (
    MAGIC, CorruptRecording, EmptyRecording, RecordingError, RecordingWriter, TruncatedRecording, read_recording,
    read_rig_config, read_samples, recover,
)

NS = 1_000_000_000


def sample_bytes(seq: int, t: float, **kw) -> bytes:
    vals = dict(ug=0.01 * seq, x1=1e-3 * np.sin(seq), x3=6e6 + seq, x4=3e6 - seq, x5=1e-5 * seq)
    vals.update(kw)
    return Sample(seq=seq, t=t, **vals).model_dump_json().encode()


def health_bytes(seq: int, t: float) -> bytes:
    return Health(seq=seq, t=t, grade="health", level=0, confidence=0.9, params={"m": 800.0},
                  param_grades={"m": "health"}, status="ok").model_dump_json().encode()


def write_messages(msgs, **kw) -> tuple[bytes, list[int]]:
    """Write ``(key, payload, log_ns, pub_ns)``; return the bytes and the size after each write."""
    buf = io.BytesIO()
    sizes = []
    w = RecordingWriter(buf, **kw)
    for m in msgs:
        w.write(*m)
        sizes.append(buf.tell())
    w.close()
    return buf.getvalue(), sizes


def sample_stream(n: int, dt_ns: int = 10_000_000, rig: str = "r1", t0_ns: int = 5 * NS):
    return [(f"hydro/rig/{rig}/sample", sample_bytes(i, i * dt_ns / NS), t0_ns + i * dt_ns, i * dt_ns)
            for i in range(n)]


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


def _survivors_after_cut(msgs, sizes, data, cut):
    out = io.BytesIO()
    report = recover(io.BytesIO(data[:cut]), out)
    got = list(read_recording(io.BytesIO(out.getvalue())))
    assert report.messages == len(got)
    return got, report


@settings(max_examples=60, deadline=None)
@given(gaps=st.lists(st.integers(1_000_000, 150_000_000), min_size=300, max_size=300),
       frac=st.floats(0.0, 1.0))
def test_chunks_are_flushed_by_log_time_so_a_cut_loses_at_most_the_last_interval(gaps, frac):
    log = np.cumsum([0] + gaps)
    keep = log <= 6 * NS
    log = log[keep]
    msgs = [("hydro/rig/r1/sample", sample_bytes(i, i * 0.01), int(t), int(t)) for i, t in enumerate(log)]
    data, sizes = write_messages(msgs, chunk_size=1 << 40, flush_interval_ns=NS)
    # cut anywhere after the 2 s mark (once the message at log time >= 2 s was written)
    i2 = int(np.searchsorted(log, 2 * NS))
    assume(i2 < len(msgs))  # some message at or after 2 s (long gaps can end the run before)
    lo = sizes[i2]
    cut = lo + int(frac * (len(data) - lo))
    got, _ = _survivors_after_cut(msgs, sizes, data, cut)
    # the recorder "died" after the last write whose bytes all fit before the cut
    last = max(i for i in range(len(msgs)) if sizes[i] <= cut)
    t_cut = msgs[last][2]
    must = [m for m in msgs if m[2] <= t_cut - NS]
    assert got[: len(must)] == must
    assert got == msgs[: len(got)]


def test_without_time_flushing_a_cut_loses_everything():
    # the control for the test above: one huge chunk never written before close
    msgs = sample_stream(300)
    data, sizes = write_messages(msgs, chunk_size=1 << 40, flush_interval_ns=10**18)
    got, _ = _survivors_after_cut(msgs, sizes, data, sizes[-1])
    assert got == []


def test_recover_at_many_random_offsets_keeps_a_prefix_and_refuses_less_than_the_magic():
    cfg = RigConfig().model_dump_json().encode()
    msgs = [("hydro/rig/r1/config", cfg, 5 * NS, 5 * NS)] + sample_stream(400)[1:]
    data, sizes = write_messages(msgs, flush_interval_ns=200_000_000)
    rng = random.Random(7)
    offsets = (set(range(0, 40)) | {len(data) - k for k in range(1, 40)}
               | {rng.randrange(len(data)) for _ in range(150)})
    counts = []
    for cut in sorted(offsets):
        out = io.BytesIO()
        if cut < len(MAGIC):  # nothing to recover: refused, nothing written
            with pytest.raises(EmptyRecording, match="nothing to read or recover"):
                recover(io.BytesIO(data[:cut]), out)
            assert out.getvalue() == b""
            continue
        report = recover(io.BytesIO(data[:cut]), out)
        got = list(read_recording(io.BytesIO(out.getvalue())))
        assert got == msgs[: len(got)], cut
        assert report.messages == len(got)
        assert not report.data_complete or len(got) == len(msgs), cut
        assert report.bytes_ok <= cut == report.bytes_total
        counts.append(len(got))
    assert counts == sorted(counts)  # a longer prefix of the file never recovers less
    assert counts[-1] > 300


def test_recover_of_a_complete_file_keeps_everything_and_metadata():
    cfg = RigConfig(K_f=35.0).model_dump_json().encode()
    msgs = [("hydro/rig/r1/config", cfg, 5 * NS, 5 * NS)] + sample_stream(100)[1:]
    data, _ = write_messages(msgs, flush_interval_ns=100_000_000)
    out = io.BytesIO()
    report = recover(io.BytesIO(data), out)
    assert report.data_complete and report.stopped_by is None and report.messages == len(msgs)
    assert list(read_recording(io.BytesIO(out.getvalue()))) == msgs
    assert read_rig_config(io.BytesIO(out.getvalue()), "r1").K_f == 35.0
    summary = make_reader(io.BytesIO(out.getvalue())).get_summary()
    channel = next(c for c in summary.channels.values() if c.topic.endswith("sample"))
    schema = summary.schemas[channel.schema_id]
    assert schema.encoding == "jsonschema" and json.loads(schema.data) == Sample.model_json_schema()


@settings(max_examples=200, deadline=None)
@given(pos=st.integers(8, 10_000), bit=st.integers(0, 7))
def test_recover_survives_any_single_bit_flip(pos, bit):
    msgs = sample_stream(200)
    data, _ = write_messages(msgs, flush_interval_ns=300_000_000)
    pos = pos % len(data)
    bad = bytearray(data)
    bad[pos] ^= 1 << bit
    out = io.BytesIO()
    report = recover(io.BytesIO(bytes(bad)), out)
    got = list(read_recording(io.BytesIO(out.getvalue())))  # the output is always valid
    assert report.messages == len(got) <= len(msgs)


def _config_and_samples(n: int = 500):
    cfg = RigConfig().model_dump_json().encode()
    return [("hydro/rig/r1/config", cfg, 5 * NS, 5 * NS)] + sample_stream(n)[1:]


@pytest.mark.parametrize("footer", [True, False], ids=["complete", "cut"])
@pytest.mark.parametrize("which", [0, 4, -1], ids=["first", "middle", "last"])
def test_recover_skips_a_damaged_chunk_and_keeps_every_other(which, footer):
    msgs = _config_and_samples()
    data, _ = write_messages(msgs, flush_interval_ns=NS // 2)
    spans = chunk_spans(data)
    assert len(spans) == 10
    which %= len(spans)
    bad = flip_in_chunk(data, which)
    if not footer:
        bad = bad[: spans[-1][1]]  # a killed recorder: nothing after the last chunk
    out = io.BytesIO()
    report = recover(io.BytesIO(bad), out)
    # the chunk's messages: those in its log-time span (chunks cut by log time, half a second each)
    lo, hi = msgs[0][2] + which * NS // 2, msgs[0][2] + (which + 1) * NS // 2
    in_chunk = [m for m in msgs if lo <= m[2] < hi]
    assert len(in_chunk) == 50
    got = list(read_recording(io.BytesIO(out.getvalue())))
    rest = [m for m in msgs if m not in in_chunk]
    if which == 0 and not footer:  # the only record of the channel was in the lost chunk, and no summary
        assert got == [] and report.orphans == len(rest)
        assert f"{len(rest)} messages without a channel dropped" in report.summary()
        return
    assert got == rest  # a complete file's summary names the channels of a lost first chunk
    assert report.chunks == 9 and report.chunks_lost == 1 and report.orphans == 0
    lost = report.lost[0]
    assert lost["byte"] == spans[which][0] and lost["log_time_s"] == [in_chunk[0][2] / NS, in_chunk[-1][2] / NS]
    assert lost["why"].startswith(("CRCValidationError", "ZstdError"))
    assert not report.data_complete
    if footer:  # the message indexes after the chunk (cut away with the footer here) count its messages
        assert report.stopped_by is None and report.messages_lost == lost["messages"] == len(in_chunk)
        assert f"LOST 1 damaged chunk(s) with {len(in_chunk)} messages (byte {spans[which][0]}" in report.summary()
        assert "source read to its end" in report.summary()
    assert report.messages == len(msgs) - len(in_chunk)


@pytest.mark.parametrize("field", ["length", "opcode"])
def test_recover_resumes_at_the_next_chunk_where_a_records_framing_breaks(field):
    # a review: a flipped bit in a chunk record's length (or opcode) stopped the walk there, and
    # every intact chunk after it was lost although the file's summary knows where they start
    msgs = _config_and_samples()
    data, _ = write_messages(msgs, flush_interval_ns=NS // 2)
    spans = chunk_spans(data)
    bad = bytearray(data)
    at = spans[4][0] + (1 + 6 if field == "length" else 0)  # the length's high byte, or the opcode
    bad[at] ^= 0x40
    out = io.BytesIO()
    report = recover(io.BytesIO(bytes(bad)), out)
    got = list(read_recording(io.BytesIO(out.getvalue())))
    lo, hi = msgs[0][2] + 4 * NS // 2, msgs[0][2] + 5 * NS // 2
    assert got == [m for m in msgs if not lo <= m[2] < hi]  # every other chunk's messages (before: 4 of 10 chunks)
    assert report.chunks == 9 and report.chunks_lost == 1 and not report.data_complete
    assert report.lost[0]["byte"] == spans[4][0] and "resumed at the next chunk" in report.lost[0]["why"]


@pytest.mark.parametrize("case", ["chunk length grown, still in the file", "chunk length shrunk",
                                  "index opcode -> footer", "index opcode -> message", "index length grown"])
def test_recover_judges_framing_by_the_summarys_chunks(case):
    # a review's fuzzing: damage that still fits in the file swallowed intact chunks, ended the walk
    # as "whole", wrote an index record as a sample, or counted one lost chunk twice
    msgs = _config_and_samples()
    data, _ = write_messages(msgs, flush_interval_ns=NS // 2)
    spans = chunk_spans(data)
    bad = bytearray(data)
    start, end, _ = spans[3]
    if case == "chunk length grown, still in the file":
        bad[start + 2] ^= 0x20  # + 8 kB: across the next chunks
    elif case == "chunk length shrunk":
        bad[start + 2] = 0
        bad[start + 1] = 0x10
    else:  # the first record after chunk 3 is its message index
        assert bad[end] == 0x07
        if case == "index opcode -> footer":
            bad[end] = 0x02
        elif case == "index opcode -> message":
            bad[end] = 0x05
        else:
            bad[end + 2] ^= 0x20
    out = io.BytesIO()
    report = recover(io.BytesIO(bytes(bad)), out)
    got = list(read_recording(io.BytesIO(out.getvalue())))
    lo, hi = msgs[0][2] + 3 * NS // 2, msgs[0][2] + 4 * NS // 2
    chunk3 = [m for m in msgs if lo <= m[2] < hi]
    if case.startswith("chunk"):
        assert got == [m for m in msgs if m not in chunk3] and report.chunks_lost == 1, report.summary()
        assert report.lost[0]["byte"] == start
    else:  # only index records lost: every message kept, and the report says something was skipped
        assert got == msgs and report.chunks_lost == 0, report.summary()
        assert report.lost and report.lost[0]["messages"] == 0
    assert not report.data_complete and report.stopped_by is None


def test_recover_command_reports_the_lost_chunk(tmp_path, capsys):
    data, _ = write_messages(_config_and_samples(), flush_interval_ns=NS // 2)
    src = tmp_path / "flip.mcap"
    src.write_bytes(flip_in_chunk(data, 5))
    assert cli_main(["recover", str(src), "--json"]) == 1  # written, but a script must not walk past the loss
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert "is missing data the source held" in err
    assert report["messages"] == 450 and report["chunks_lost"] == 1 and report["messages_lost"] == 50
    assert report["lost"][0]["byte"] == chunk_spans(data)[5][0] and report["lost"][0]["messages"] == 50


def test_reading_a_chunk_that_fails_its_crc_says_so_never_returns_other_bytes():
    msgs = _config_and_samples()
    data, _ = write_messages(msgs, flush_interval_ns=NS // 2)
    bad = flip_in_chunk(data, 4)
    with pytest.raises(CorruptRecording, match=f"damaged recording: the chunk at byte {chunk_spans(data)[4][0]} "
                                               r"\(log time 7.000-7.490 s\) (fails its CRC check|does not decompress)"
                                               ".*run `hydromon recover"):
        list(read_recording(io.BytesIO(bad)))
    assert list(read_recording(io.BytesIO(bad), end_ns=7 * NS)) == [m for m in msgs if m[2] < 7 * NS]


def test_an_empty_file_is_empty_not_truncated_and_recover_writes_nothing(tmp_path, capsys):
    src = tmp_path / "empty.mcap"
    src.write_bytes(b"")
    with pytest.raises(EmptyRecording, match=f"{src}: empty recording \\(0 bytes\\): nothing to read or recover"):
        read_recording(src)
    assert cli_main(["recover", str(src)]) == 2
    assert f"hydromon recover: error: {src}: empty recording (0 bytes): nothing to read or recover" \
        in capsys.readouterr().err
    assert not (tmp_path / "empty.recovered.mcap").exists()
    src.write_bytes(MAGIC[:5])
    assert cli_main(["recover", str(src)]) == 2
    assert "5 bytes, shorter than the MCAP magic" in capsys.readouterr().err


def test_recover_rejects_what_is_not_mcap():
    with pytest.raises(CorruptRecording, match="not an MCAP file"):
        recover(io.BytesIO(b"PK\x03\x04 zip file"), io.BytesIO())


def test_recover_command_writes_next_to_the_file_and_will_not_overwrite(tmp_path, capsys):
    data, _ = write_messages(sample_stream(200), flush_interval_ns=200_000_000)
    src = tmp_path / "run.mcap"
    src.write_bytes(data[: len(data) * 2 // 3])
    assert cli_main(["recover", str(src), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    out = tmp_path / "run.recovered.mcap"
    assert report["out"] == str(out) and report["messages"] > 0
    assert len(list(read_recording(out))) == report["messages"]
    assert cli_main(["recover", str(src)]) == 2  # exists: refuses
    assert "exists" in capsys.readouterr().err
    assert cli_main(["recover", str(src), "-o", str(src), "--force"]) == 2  # never onto itself



def test_recover_out_that_cannot_be_written_is_a_clear_error_and_a_failed_run_keeps_the_old_out(tmp_path, capsys):
    data, _ = write_messages(sample_stream(200), flush_interval_ns=200_000_000)
    src = tmp_path / "run.mcap"
    src.write_bytes(data[: len(data) * 2 // 3])
    (tmp_path / "dir").mkdir()
    # a directory (was an IsADirectoryError traceback, exit 1) or a missing one (a bare errno)
    assert cli_main(["recover", str(src), "-o", str(tmp_path / "dir"), "--force"]) == 2
    assert f"--out '{tmp_path / 'dir'}' is a directory" in capsys.readouterr().err
    assert cli_main(["recover", str(src), "-o", str(tmp_path / "no" / "x.mcap")]) == 2
    assert "does not exist" in capsys.readouterr().err
    # nothing recoverable after the magic: exit 2, and an existing OUT is left as it was (was
    # truncated and replaced by an empty recording, exit 0)
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(MAGIC + b"\x5e" * 500)
    out = tmp_path / "out.mcap"
    out.write_bytes(b"mine")
    assert cli_main(["recover", str(junk), "-o", str(out), "--force"]) == 2
    assert "nothing to recover" in capsys.readouterr().err
    assert out.read_bytes() == b"mine"
    assert not (tmp_path / "junk.recovered.mcap").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir", "junk.mcap", "out.mcap", "run.mcap"]
    assert cli_main(["recover", str(src), "-o", str(out), "--force"]) == 0
    assert len(list(read_recording(out))) > 0

# -- docs -----------------------------------------------------------------------------------
def test_docs_contract_md_is_up_to_date():
    assert docs_gen.DOC_PATH.read_text() == docs_gen.render(), "run `python -m hydromon.docs_gen`"
