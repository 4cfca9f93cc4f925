"""Readers of MCAP recordings of the bus (layout: ``hydromon.store.mcap_layout``).

Readers take binary streams as well as paths, so tests run in memory.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import logging
import struct
import zlib
from collections.abc import Iterable, Iterator

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.data_stream import ReadDataStream
from mcap.stream_reader import get_chunk_data_stream
from pydantic import ValidationError

from hydromon.contract import SAMPLE_COLUMNS, Frame, RigConfig, Sample, valid_rig_id
from hydromon.store.mcap_layout import (
    DECODE_ERRORS, MAGIC, U64, CorruptRecording, EmptyRecording, RecordingError, TruncatedRecording, damaged,
    empty_message, opened, recover_hint, rig_topic, time_ns,
)

__all__ = ["read_recording", "read_summary", "read_samples", "read_rig_config", "stored_configs", "check_summary_crc",
           "sample_rigs"]

log = logging.getLogger(__name__)

_FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, summary crc


def check_summary_crc(f, name: str) -> None:
    """Compare the footer's summary CRC with the summary's bytes (seekable, complete ``f``)."""
    size = f.seek(0, io.SEEK_END)
    if size < 2 * len(MAGIC) + _FOOTER.size:
        return
    f.seek(size - len(MAGIC) - _FOOTER.size)
    _op, _len, start, _offsets, crc = _FOOTER.unpack(f.read(_FOOTER.size))
    end = size - len(MAGIC) - 4
    if crc and start and len(MAGIC) <= start < end:
        f.seek(start)
        if zlib.crc32(f.read(end - start)) != crc:
            f.seek(0)
            raise CorruptRecording(f"{name}: damaged recording: its summary (index) fails its CRC check; "
                                   f"{recover_hint(name)}")
    f.seek(0)


def _summary_of(f, name: str, required: bool = True):
    """The summary of an open recording, checked: complete, summary CRC, decodes; or RecordingError.

    None for a non-seekable stream, and for a complete file written without a summary unless
    ``required``."""
    _check_complete(f, name)
    if not f.seekable():
        return None
    check_summary_crc(f, name)
    try:
        summary = make_reader(f).get_summary()
    except DECODE_ERRORS as exc:
        raise damaged(name, exc, "its summary (index)") from exc
    if required and (summary is None or summary.statistics is None):
        raise TruncatedRecording(f"{name}: recording has no summary; {recover_hint(name)}")
    return summary


def read_summary(src):
    """The summary (channels, statistics, chunk indexes) of a complete recording.

    Raises :class:`EmptyRecording`, :class:`TruncatedRecording` (no footer or summary) or
    :class:`CorruptRecording` (not MCAP, or the summary does not decode or fails its CRC),
    each naming the file and, where it helps, ``hydromon recover``.
    """
    with opened(src) as (f, name):
        return _summary_of(f, name)


def _check_complete(f, name: str) -> None:
    if not f.seekable():
        return
    size = f.seek(0, io.SEEK_END)
    f.seek(0)
    head = f.read(len(MAGIC))
    if head != MAGIC[:len(head)] or (size >= len(MAGIC) and head != MAGIC):
        raise CorruptRecording(f"{name}: not an MCAP file (bad magic)")
    if size < len(MAGIC):
        raise EmptyRecording(empty_message(name, size))
    tail = b""
    if size >= 2 * len(MAGIC):
        f.seek(size - len(MAGIC))
        tail = f.read(len(MAGIC))
    f.seek(0)
    if tail != MAGIC:
        raise TruncatedRecording(f"{name}: recording has no footer (was the recorder killed?); "
                                 f"run `hydromon recover {name}` to salvage it")


def read_recording(src, topics: Iterable[str] | str | None = None, start_ns: int | None = None,
                   end_ns: int | None = None) -> Iterator[tuple[str, bytes, int, int]]:
    """Messages of a recording as ``(key, payload_bytes, log_time_ns, publish_time_ns)``.

    In log-time order; ``topics`` filters by key; ``start_ns`` (inclusive) and ``end_ns``
    (exclusive) bound the log time [ns]. ``src`` is a path or a seekable binary stream
    (read from its start). Raises :class:`TruncatedRecording` for a file without footer.
    """
    for name, value in (("start_ns", start_ns), ("end_ns", end_ns)):
        if value is not None:
            time_ns(name, value)
    if isinstance(topics, str):
        topics = [topics]
    elif topics is not None:
        topics = list(topics)
    stack = contextlib.ExitStack()
    f, name = stack.enter_context(opened(src))
    try:
        summary = _summary_of(f, name, required=False)
    except BaseException:
        stack.close()
        raise

    def gen():
        with stack:
            if _chunks_in_order(summary):
                yield from _chunked_messages(f, name, summary, topics, start_ns, end_ns)
                return
            try:
                reader = make_reader(f, validate_crcs=True)
                for _schema, channel, msg in reader.iter_messages(
                        topics=topics, starting_at=start_ns, ending_before=end_ns):
                    yield channel.topic, msg.data, msg.log_time, msg.publish_time
            except DECODE_ERRORS as exc:
                raise damaged(name, exc) from exc

    return gen()


_RECORD_HEAD = struct.Struct("<BQ")  # opcode, record length
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_OP_MESSAGE = 0x05


def _chunks_in_order(summary) -> bool:
    """True when the file's chunks, in file order, cover disjoint, ascending log-time spans
    (what the recorder and ``sim --to-mcap`` write): then file order with each chunk's messages
    stably sorted by log time is exactly the library's log-time order."""
    if summary is None or not summary.chunk_indexes:
        return False
    idx = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    return all(a.message_end_time <= b.message_start_time for a, b in zip(idx, idx[1:]))


def _chunk_messages(f, ci, channels, wanted, lo, hi) -> list:
    """The messages of one chunk (its index ``ci``) in the window, stably sorted by log time."""
    f.seek(ci.chunk_start_offset + 1 + 8)
    stream, size = get_chunk_data_stream(Chunk.read(ReadDataStream(f)), validate_crc=True)
    data = stream.read(size)
    out = []
    pos = 0
    while pos < size:
        op, length = _RECORD_HEAD.unpack_from(data, pos)
        pos += 9
        if op == _OP_MESSAGE:
            cid, _seq, log_ns, pub_ns = _MESSAGE_HEAD.unpack_from(data, pos)
            if lo <= log_ns < hi and (wanted is None or cid in wanted):
                if cid not in channels:
                    raise McapError(f"a message on channel id {cid}, which the recording does not declare")
                out.append((channels[cid].topic, data[pos + 22:pos + length], log_ns, pub_ns))
        pos += length
    if pos != size:
        raise McapError("its records overrun the chunk")
    if any(a[2] > b[2] for a, b in zip(out, out[1:])):
        out.sort(key=lambda m: m[2])  # stable: ties keep file order, as the library's heap does
    return out


def _chunked_messages(f, name, summary, topics, start_ns, end_ns):
    """Messages chunk by chunk, in log-time order (ties in file order), as read_recording yields.

    The mcap library's ordered reader merges every message through a heap of Python objects
    (measured: 70 % of a direct replay's time); for chunks that do not overlap in time that
    merge is a per-chunk stable sort, and the records of a decompressed chunk are sliced here
    with two struct unpacks each. Decompression and CRC checks stay the library's; a chunk
    that fails them raises :class:`CorruptRecording` naming the file and the chunk.
    """
    channels = summary.channels
    wanted = None
    if topics is not None:
        names = set(topics)
        wanted = {cid for cid, c in channels.items() if c.topic in names}
    lo = -1 if start_ns is None else start_ns
    hi = U64 if end_ns is None else end_ns
    for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        if ci.message_end_time < lo or ci.message_start_time >= hi:
            continue
        try:
            out = _chunk_messages(f, ci, channels, wanted, lo, hi)
        except DECODE_ERRORS as exc:
            raise damaged(name, exc, f"the chunk at byte {ci.chunk_start_offset} (log time "
                                     f"{ci.message_start_time / 1e9:.3f}-{ci.message_end_time / 1e9:.3f} s)") from exc
        yield from out


def _topics(src) -> list[str]:
    return sorted({c.topic for c in read_summary(src).channels.values()})


def _rig_topics(src, leaf: str, rig: str | None) -> dict[str, str]:
    found: dict[str, str] = {}
    for topic in _topics(src):
        parsed = rig_topic(topic)
        if parsed and parsed[1] == leaf:
            if parsed[0] in found:
                raise RecordingError(f"rig {parsed[0]!r} appears under two namespaces: "
                                     f"{found[parsed[0]]!r} and {topic!r}")
            found[parsed[0]] = topic
    if rig is not None and not valid_rig_id(rig):
        raise ValueError(f"rig id {rig!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return found


def sample_rigs(src) -> list[str]:
    """The ids of the rigs whose samples a recording holds, sorted."""
    return sorted(_rig_topics(src, "sample", None))


def _first_error(exc: ValidationError) -> str:
    """``field: what is wrong`` of a validation error's first complaint."""
    err = exc.errors()[0]
    return f"{'.'.join(map(str, err.get('loc', ()))) or 'payload'}: {err.get('msg')}"


def read_samples(src, rig: str | None = None, rejected: list | None = None,
                 configs: list | None = None, drive: list | None = None,
                 bad_configs: list | None = None) -> tuple[str, np.ndarray, np.ndarray]:
    """One rig's samples, sent one per message or in frames: ``(rig_id, data, seq)``.

    ``data`` is float64 ``(N, 6)`` with columns :data:`SAMPLE_COLUMNS` (t [s], ug [V],
    x1 [m], x3 [Pa], x4 [Pa], x5 [m]), ``seq`` int64 ``(N,)``, both in log-time order.
    ``rig`` may be None only if the recording holds one rig. Every payload is validated
    against :class:`~hydromon.contract.Sample`; a bad one raises :class:`RecordingError`,
    unless a ``rejected`` list is given: then it is skipped and described there (as the
    live monitor drops it), and its seq is missing from ``seq``.

    With a ``configs`` list, the rig's config messages (same namespace) are read in the same
    pass and appended as ``(i, RigConfig)``: i is the index in ``data`` of the first sample
    that follows the config in log time (where a live monitor would switch to it). A config
    that is not a valid RigConfig is left out, as the monitor rejects it (the recorder logged it),
    and described in ``bad_configs`` when that list is given.

    With a ``drive`` list, each sample's valve drive ``u`` [V] is appended to it (NaN for a
    sample without one), so ``drive[i]`` belongs to ``data[i]``.
    """
    rigs = _rig_topics(src, "sample", rig)
    for rig_id, topic in _rig_topics(src, "frame", rig).items():  # frames: many samples a message
        head = topic.rsplit("/", 1)[0]
        if rig_id in rigs and rigs[rig_id].rsplit("/", 1)[0] != head:
            raise RecordingError(f"rig {rig_id!r} appears under two namespaces: {rigs[rig_id]!r} and {topic!r}")
        rigs.setdefault(rig_id, topic)
    if not rigs:
        raise RecordingError("recording holds no rig samples")
    if rig is None:
        if len(rigs) > 1:
            raise ValueError(f"recording holds several rigs ({', '.join(sorted(rigs))}); choose one")
        rig = next(iter(rigs))
    elif rig not in rigs:
        raise ValueError(f"rig {rig!r} not in recording; it holds {', '.join(sorted(rigs))}")
    head = rigs[rig].rsplit("/", 1)[0]
    sample_topic, frame_topic = head + "/sample", head + "/frame"
    topics = [sample_topic, frame_topic]
    if configs is not None:  # one pass, so a config falls between the samples it fell between live
        topics.append(head + "/config")
    rows, seqs = [], []
    for key, payload, log_ns, _ in read_recording(src, topics=topics):
        if key not in (sample_topic, frame_topic):
            try:
                configs.append((len(rows), RigConfig.model_validate_json(payload)))
            except ValidationError as exc:
                if bad_configs is not None:
                    bad_configs.append(f"its config message on {key} at log time {log_ns} ns is not a valid rig "
                                       f"config ({_first_error(exc)})")
            continue
        try:
            s = (Sample if key == sample_topic else Frame).model_validate_json(payload)
        except ValidationError as exc:
            why = (f"bad {key.rsplit('/', 1)[1]} on {key} at log time {log_ns} ns: "
                   f"{exc.errors()[0].get('loc')}: {exc.errors()[0].get('msg')}")
            if rejected is None:
                raise RecordingError(why) from None
            rejected.append(why)
            continue
        if key == frame_topic:  # a frame: samples seq, seq + 1, ...
            n = len(s.t)
            rows += zip(s.t, s.ug, s.x1, s.x3, s.x4, s.x5)
            seqs += range(s.seq, s.seq + n)
            if drive is not None:
                drive += [math.nan] * n if s.u is None else s.u
            continue
        rows.append((s.t, s.ug, s.x1, s.x3, s.x4, s.x5))
        seqs.append(s.seq)
        if drive is not None:
            drive.append(math.nan if s.u is None else s.u)
    data = np.array(rows, dtype=np.float64).reshape(len(rows), len(SAMPLE_COLUMNS))
    return rig, data, np.array(seqs, dtype=np.int64)


def stored_configs(src, rig: str) -> list[RigConfig]:
    """Every config of ``rig`` stored as metadata ``rig_config/<id>``, in file order: the one
    in force when the file was opened (or first seen), then each change."""
    if not valid_rig_id(rig):
        raise ValueError(f"rig id {rig!r} must be 1-64 chars of [A-Za-z0-9_-]")
    with opened(src) as (f, name):
        _summary_of(f, name)
        try:
            found = [m.metadata for m in make_reader(f).iter_metadata() if m.name == f"rig_config/{rig}"]
        except DECODE_ERRORS as exc:
            raise damaged(name, exc, "a metadata record") from exc
    out = []
    for i, m in enumerate(found):
        try:
            out.append(RigConfig.model_validate({k: json.loads(v) for k, v in m.items()}))
        except json.JSONDecodeError as exc:
            raise ValueError(f"the rig config stored as metadata rig_config/{rig} (record {i}) is not JSON: "
                             f"{exc}") from None
        except ValidationError as exc:
            raise ValueError(f"the rig config stored as metadata rig_config/{rig} (record {i}) is not a valid rig "
                             f"config ({_first_error(exc)}); give the rig's constants with --config FILE") from None
    return out


def read_rig_config(src, rig: str) -> RigConfig:
    """The last config of ``rig`` in the recording (metadata ``rig_config/<id>``, else the
    last message on its config channel). Raises ValueError if there is none. A rig whose
    config changed mid-record has others before it (:func:`stored_configs`)."""
    found = stored_configs(src, rig)
    if found:
        return found[-1]
    topics = _rig_topics(src, "config", rig)
    if rig in topics:
        last = None
        for _, payload, _, _ in read_recording(src, topics=[topics[rig]]):
            last = payload
        if last is not None:
            return RigConfig.model_validate_json(last)
    raise ValueError(f"no config for rig {rig!r} in recording (rigs with a config: "
                     f"{', '.join(sorted(topics)) or 'none'})")
