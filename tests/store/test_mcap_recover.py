"""Recovery of cut and damaged MCAP recordings (a killed recorder, flipped bits, broken framing), and the recover command."""

from __future__ import annotations

import io
import json
import random

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from helpers import SECOND_NS as NS
from helpers import chunk_spans, config_and_samples, flip_in_chunk, sample_bytes, sample_stream, write_messages
from hydromon.cli.main import main as cli_main
from hydromon.contract import RigConfig, Sample
from hydromon.store.mcap_layout import MAGIC, CorruptRecording, EmptyRecording
from hydromon.store.mcap_read import read_recording, read_rig_config
from hydromon.store.mcap_recover import recover


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


@pytest.mark.parametrize("footer", [True, False], ids=["complete", "cut"])
@pytest.mark.parametrize("which", [0, 4, -1], ids=["first", "middle", "last"])
def test_recover_skips_a_damaged_chunk_and_keeps_every_other(which, footer):
    msgs = config_and_samples()
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
    # a flipped bit in a chunk record's length (or opcode) must not stop the walk there and lose
    # every intact chunk after it: the file's summary knows where they start
    msgs = config_and_samples()
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
    # damage that still fits in the file (cases found by fuzzing) must not swallow intact chunks,
    # end the walk as "whole", write an index record as a sample, or count one lost chunk twice
    msgs = config_and_samples()
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
    data, _ = write_messages(config_and_samples(), flush_interval_ns=NS // 2)
    src = tmp_path / "flip.mcap"
    src.write_bytes(flip_in_chunk(data, 5))
    assert cli_main(["recover", str(src), "--json"]) == 1  # written, but a script must not walk past the loss
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert "is missing data the source held" in err
    assert report["messages"] == 450 and report["chunks_lost"] == 1 and report["messages_lost"] == 50
    assert report["lost"][0]["byte"] == chunk_spans(data)[5][0] and report["lost"][0]["messages"] == 50


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
