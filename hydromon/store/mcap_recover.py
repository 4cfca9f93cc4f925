"""Recovery of cut or damaged MCAP recordings (e.g. the recorder was SIGKILLed).

A killed recorder leaves a file without summary or footer and with a partial last chunk.
:func:`recover` walks the records in file order by their framing (opcode, length), keeps
every schema, channel, message and metadata record, and rewrites them into a valid
recording. A chunk whose length is sane but whose content is damaged (CRC mismatch, does
not decompress or decode) is skipped and reported with the messages its message indexes
name; reading stops only where the framing itself breaks (the file ends inside a record,
an unknown opcode, a length beyond the end of the file) or a record outside the chunks
does not decode.
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Message, MessageIndex, Metadata, Schema
from mcap.reader import make_reader
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer

from hydromon.store.mcap_layout import (
    DECODE_ERRORS, MAGIC, CorruptRecording, EmptyRecording, RecordingError, empty_message,
)
from hydromon.store.mcap_read import check_summary_crc

__all__ = ["recover", "RecoverReport"]

_MAX_CHUNK_BYTES = 1 << 30  # a chunk claiming more than 1 GiB uncompressed is corrupt
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, record length
_KNOWN_OPCODES = frozenset(int(o) for o in Opcode)
_KEPT = {Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: Channel.read, Opcode.METADATA: Metadata.read}


@dataclass
class RecoverReport:
    """What :func:`recover` salvaged.

    ``bytes_ok`` is where the last record read (kept or skipped) ended [B]; ``data_complete``
    is True when the whole data section was read and nothing in it was lost (even if the
    summary after it was cut); ``orphans`` counts messages whose channel record was lost;
    ``stopped_by`` says why reading stopped early. ``chunks_lost`` damaged chunks were
    skipped, holding ``messages_lost`` messages (as far as their message indexes tell);
    ``lost`` describes each: its byte offset, log time span [s], messages (None when no
    index names them) and why it was skipped.
    """

    messages: int = 0
    channels: int = 0
    schemas: int = 0
    metadata: int = 0
    chunks: int = 0
    orphans: int = 0
    bytes_ok: int = 0
    bytes_total: int = 0
    data_complete: bool = False
    stopped_by: str | None = None
    chunks_lost: int = 0
    messages_lost: int = 0
    lost: list = field(default_factory=list)

    def summary(self) -> str:
        if self.stopped_by:
            state = f"cut at byte {self.bytes_ok} of {self.bytes_total} ({self.stopped_by})"
        else:
            state = "whole" if self.data_complete else "read to its end"
        extra = f"; {self.orphans} messages without a channel dropped" if self.orphans else ""
        return (f"recovered {self.messages} messages on {self.channels} channels, {self.metadata} "
                f"metadata, from {self.chunks} chunks; source {state}{extra}{_lost_text(self.lost)}")


def _lost_text(lost: list) -> str:
    """``; lost 2 damaged chunks (...)`` or nothing."""
    if not lost:
        return ""
    known = sum(c["messages"] or 0 for c in lost)
    unknown = any(c["messages"] is None for c in lost)
    count = f"{known}{' or more' if unknown else ''} messages"
    parts = []
    for c in lost:
        span = f", log time {c['log_time_s'][0]:.3f}-{c['log_time_s'][1]:.3f} s" if c["log_time_s"] else ""
        n = "?" if c["messages"] is None else c["messages"]
        parts.append(f"byte {c['byte']}{span}, {n} messages: {c['why']}")
    what = "chunk(s)" if all(c.get("chunk", True) for c in lost) else "chunk(s) or records between them"
    return f"; LOST {len(lost)} damaged {what} with {count} ({'; '.join(parts)})"


def _head(f) -> bytes:
    """The first bytes of ``f`` (left positioned after them); CorruptRecording if not MCAP."""
    f.seek(0)
    head = f.read(len(MAGIC))
    if head != MAGIC[:len(head)]:
        raise CorruptRecording(f"{getattr(f, 'name', '<stream>')}: not an MCAP file (bad magic)")
    return head


def _why(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _chunk_records(body: bytes) -> tuple[Chunk | None, list | None, str | None]:
    """``(chunk, records, None)`` of a chunk record's body, or ``(chunk or None, None, why)``
    when its header, size, compression or CRC is damaged."""
    chunk = None
    try:
        chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
        if chunk.uncompressed_size > _MAX_CHUNK_BYTES:
            return chunk, None, f"claims {chunk.uncompressed_size} bytes uncompressed"
        return chunk, breakup_chunk(chunk, validate_crc=True), None
    except DECODE_ERRORS as exc:
        return chunk, None, _why(exc)


def _lost_chunk(pos: int, chunk: Chunk | None, why: str) -> dict:
    span = None
    if chunk is not None and chunk.message_start_time <= chunk.message_end_time:
        span = [chunk.message_start_time / 1e9, chunk.message_end_time / 1e9]
    return {"byte": pos, "log_time_s": span, "messages": None, "why": why}


def _salvage(f, report: RecoverReport, chunks=()) -> Iterator:
    """Records of a possibly cut or damaged MCAP stream, by their framing (module docstring).

    ``chunks``: the chunks' (byte offset, record length) from an intact summary; where a record's framing
    breaks (a flipped bit in a length or opcode), the walk resumes at the next of them and the
    bytes skipped are reported lost, instead of stopping there."""
    size = f.seek(0, io.SEEK_END)
    report.bytes_total = size
    _head(f)
    pos = report.bytes_ok = len(MAGIC)
    lost = None  # the chunk just skipped: the message indexes after it count its messages
    chunk_starts = [s for s, _ in chunks]

    def resume(at: int, why: str) -> int | None:
        nxt = next((s for s in chunk_starts if s > at), None)
        if nxt is None:
            return None
        own = next((s for s, n in chunks if s <= at < s + n), None)  # the chunk the break is in
        note = f"framing lost at byte {at} ({why}); resumed at the next chunk, byte {nxt}"
        if own is None:  # between chunks: index records skipped, no message
            report.lost.append({"byte": at, "log_time_s": None, "messages": 0, "why": note, "chunk": False})
        elif not (report.lost and report.lost[-1]["byte"] == own):  # (a chunk already lost: one loss)
            report.lost.append({"byte": own, "log_time_s": None, "messages": None, "why": note})
            report.chunks_lost += 1
        f.seek(nxt)
        return nxt

    def broken(op: int, length: int) -> str | None:
        """Why this record's framing is wrong (None if it looks right): judged by the summary's
        chunk offsets when known, so a flipped bit that still fits in the file is caught too."""
        if op not in _KNOWN_OPCODES:
            return f"unknown opcode 0x{op:02x}"
        if length > size - pos - _RECORD_HEAD.size:
            return f"a {length}-byte record past the end of the file"
        if chunk_starts:
            end = pos + _RECORD_HEAD.size + length
            if any(pos < s < end for s in chunk_starts):
                return f"a {length}-byte record across the chunk at byte {next(s for s in chunk_starts if pos < s)}"
            if op == Opcode.CHUNK and pos not in chunk_starts:
                return "a chunk record where the summary has none"
            if op in (Opcode.DATA_END, Opcode.FOOTER) and pos < chunk_starts[-1]:
                return f"a {Opcode(op).name.lower()} record before the last chunk"
            if op == Opcode.MESSAGE:  # hydromon writes every message inside a chunk
                return "a message record outside any chunk"
        return None

    while True:
        head = f.read(_RECORD_HEAD.size)
        if not head:
            report.stopped_by = "end of file before the data end record"
            return
        if len(head) < _RECORD_HEAD.size:
            report.stopped_by = "end of file inside a record"
            return
        op, length = _RECORD_HEAD.unpack(head)
        why = broken(op, length)
        if why is not None:
            nxt = resume(pos, why)
            if nxt is not None:
                lost, pos = None, nxt
                continue
            report.stopped_by = (f"record at byte {pos} has unknown opcode 0x{op:02x} (framing lost)"
                                 if op not in _KNOWN_OPCODES else "end of file inside a record")
            return
        body = f.read(length)
        end = pos + _RECORD_HEAD.size + length
        if op == Opcode.CHUNK:
            chunk, records, why = _chunk_records(body)
            if records is None:
                lost = _lost_chunk(pos, chunk, why)
                report.lost.append(lost)
                report.chunks_lost += 1
            else:
                lost = None
                report.chunks += 1
                yield from records
        elif op == Opcode.MESSAGE_INDEX:
            if lost is not None:
                with contextlib.suppress(*DECODE_ERRORS):
                    n = len(MessageIndex.read(ReadDataStream(io.BytesIO(body))).records)
                    lost["messages"] = (lost["messages"] or 0) + n
                    report.messages_lost += n
        elif op in (Opcode.DATA_END, Opcode.FOOTER):
            report.data_complete = not report.lost
            report.bytes_ok = end
            return
        elif op in _KEPT or op == Opcode.MESSAGE:
            lost = None
            try:
                stream = ReadDataStream(io.BytesIO(body))
                rec = Message.read(stream, length) if op == Opcode.MESSAGE else _KEPT[op](stream)
            except DECODE_ERRORS as exc:
                report.stopped_by = f"{Opcode(op).name.lower()} record at byte {pos} does not decode: {_why(exc)}"
                return
            yield rec
        else:
            lost = None
        pos = report.bytes_ok = end


def _summary_channels(f) -> tuple[dict, dict, list]:
    """``(schemas, channels, chunk starts)`` from the summary of a file whose footer and summary
    CRC are intact (so messages after a lost chunk that declared their channel keep it, and the
    walk can resume at the next chunk where a record's framing broke), else empty."""
    try:
        size = f.seek(0, io.SEEK_END)
        f.seek(max(0, size - len(MAGIC)))
        if size < 2 * len(MAGIC) or f.read(len(MAGIC)) != MAGIC:
            return {}, {}, []
        check_summary_crc(f, "")
        summary = make_reader(f).get_summary()
    except (*DECODE_ERRORS, RecordingError):
        return {}, {}, []
    finally:
        f.seek(0)
    if summary is None:
        return {}, {}, []
    chunks = sorted((c.chunk_start_offset, c.chunk_length) for c in summary.chunk_indexes)
    return dict(summary.schemas), dict(summary.channels), chunks


def recover(src, dst) -> RecoverReport:
    """Rewrite a cut or damaged recording ``src`` into a valid one at ``dst``.

    Reads records in file order (module docstring: a damaged chunk is skipped and reported,
    reading stops where the framing breaks) and writes every schema, channel, message and
    metadata record read, times and sequence numbers unchanged. ``src``/``dst`` are paths or
    binary streams (``src`` seekable). Never overwrites ``src``; raises
    :class:`CorruptRecording` if ``src`` is not MCAP at all and :class:`EmptyRecording`
    (before ``dst`` is opened) if it is shorter than the MCAP magic.
    """
    if isinstance(src, (str, os.PathLike)) and isinstance(dst, (str, os.PathLike)) \
            and os.path.exists(dst) and os.path.samefile(src, dst):
        raise ValueError(f"recover: destination {dst} is the source")
    report = RecoverReport()
    with contextlib.ExitStack() as stack:
        fin = stack.enter_context(open(src, "rb")) if isinstance(src, (str, os.PathLike)) else src
        _head(fin)
        size = fin.seek(0, io.SEEK_END)
        if size < len(MAGIC):
            name = os.fspath(src) if isinstance(src, (str, os.PathLike)) else getattr(src, "name", "<stream>")
            raise EmptyRecording(empty_message(name, size))
        known_schemas, known_channels, known_chunks = _summary_channels(fin)
        fout = stack.enter_context(open(dst, "wb")) if isinstance(dst, (str, os.PathLike)) else dst
        writer = Writer(fout, compression=CompressionType.ZSTD)
        writer.start(profile="", library="hydromon recover")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}

        def add_schema(rec):
            schemas[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
            report.schemas += 1

        def add_channel(rec):
            if rec.schema_id not in schemas and rec.schema_id in known_schemas:
                add_schema(known_schemas[rec.schema_id])
            channels[rec.id] = writer.register_channel(rec.topic, rec.message_encoding,
                                                       schemas.get(rec.schema_id, 0), dict(rec.metadata))
            report.channels += 1

        for rec in _salvage(fin, report, known_chunks):
            if isinstance(rec, Schema) and rec.id not in schemas:
                add_schema(rec)
            elif isinstance(rec, Channel) and rec.id not in channels:
                add_channel(rec)
            elif isinstance(rec, Message):
                if rec.channel_id not in channels and rec.channel_id in known_channels:
                    add_channel(known_channels[rec.channel_id])  # its own record was in a lost chunk
                if rec.channel_id not in channels:
                    report.orphans += 1
                    continue
                writer.add_message(channels[rec.channel_id], rec.log_time, rec.data,
                                   rec.publish_time, rec.sequence)
                report.messages += 1
            elif isinstance(rec, Metadata):
                writer.add_metadata(rec.name, dict(rec.metadata))
                report.metadata += 1
        writer.finish()
        fout.flush()
    return report
