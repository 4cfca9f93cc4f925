"""Recovery of cut or damaged MCAP recordings (e.g. the recorder was SIGKILLed).

A killed recorder leaves a file without summary or footer and with a partial last chunk.
:func:`recover` reads records in file order with the mcap stream reader, over a view that
turns short reads into EndOfFile and with lengths bounded by the file size, stops at the
first record that is incomplete or does not decode, and rewrites everything before it
into a valid recording.
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator
from dataclasses import dataclass

from mcap.exceptions import EndOfFile
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from hydromon.mcap_io import _DECODE_ERRORS, MAGIC, CorruptRecording

__all__ = ["recover", "RecoverReport"]

_MAX_CHUNK_BYTES = 1 << 30  # a chunk claiming more than 1 GiB uncompressed is corrupt


@dataclass
class RecoverReport:
    """What :func:`recover` salvaged.

    ``bytes_ok`` is where the last good record ended [B]; ``data_complete`` is True when the
    whole data section was read (nothing lost, even if the summary after it was cut);
    ``orphans`` counts messages whose channel record was lost; ``stopped_by`` says why
    reading stopped early.
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

    def summary(self) -> str:
        state = "whole" if self.data_complete else f"cut at byte {self.bytes_ok} of {self.bytes_total}"
        extra = f"; {self.orphans} messages without a channel dropped" if self.orphans else ""
        why = f" ({self.stopped_by})" if self.stopped_by else ""
        return (f"recovered {self.messages} messages on {self.channels} channels, {self.metadata} "
                f"metadata, from {self.chunks} chunks; source {state}{why}{extra}")


class _Exact:
    """A read-only view that raises EndOfFile instead of returning short reads."""

    def __init__(self, f, size: int):
        self._f, self._size, self.pos = f, size, f.tell()

    def read(self, n: int = -1) -> bytes:
        if n < 0 or n > self._size - self.pos:
            raise EndOfFile()
        data = self._f.read(n)
        if len(data) != n:
            raise EndOfFile()
        self.pos += n
        return data


def _head(f) -> bytes:
    """The first bytes of ``f`` (left positioned after them); CorruptRecording if not MCAP."""
    f.seek(0)
    head = f.read(len(MAGIC))
    if head != MAGIC[:len(head)]:
        raise CorruptRecording(f"{getattr(f, 'name', '<stream>')}: not an MCAP file (bad magic)")
    return head


def _salvage(f, report: RecoverReport) -> Iterator:
    """Records of a possibly cut MCAP stream up to the first one that does not decode."""
    size = f.seek(0, io.SEEK_END)
    report.bytes_total = size
    head = _head(f)
    if len(head) < len(MAGIC):
        report.stopped_by = "file shorter than the MCAP magic"
        return
    exact = _Exact(f, size)
    report.bytes_ok = exact.pos
    records = StreamReader(exact, skip_magic=True, emit_chunks=True, record_size_limit=size).records
    try:
        for record in records:
            if isinstance(record, Chunk):
                if record.uncompressed_size > _MAX_CHUNK_BYTES:
                    raise CorruptRecording(f"chunk claims {record.uncompressed_size} bytes")
                inner = breakup_chunk(record, validate_crc=True)
                report.chunks += 1
                report.bytes_ok = exact.pos
                yield from inner
                continue
            if isinstance(record, (DataEnd, Footer)):
                report.data_complete = True
                report.bytes_ok = exact.pos
                return
            report.bytes_ok = exact.pos
            yield record
    except EndOfFile:
        report.stopped_by = "end of file inside a record"
    except _DECODE_ERRORS as exc:
        report.stopped_by = f"{type(exc).__name__}: {exc}"


def recover(src, dst) -> RecoverReport:
    """Rewrite a cut or damaged recording ``src`` into a valid one at ``dst``.

    Reads records in file order until the first that is incomplete or does not decode
    (a chunk whose CRC fails counts as not decoding) and writes every schema, channel,
    message and metadata record before it, times and sequence numbers unchanged.
    ``src``/``dst`` are paths or binary streams (``src`` seekable). Never overwrites
    ``src``; raises :class:`CorruptRecording` only if ``src`` is not MCAP at all.
    """
    if isinstance(src, (str, os.PathLike)) and isinstance(dst, (str, os.PathLike)) \
            and os.path.exists(dst) and os.path.samefile(src, dst):
        raise ValueError(f"recover: destination {dst} is the source")
    report = RecoverReport()
    with contextlib.ExitStack() as stack:
        fin = stack.enter_context(open(src, "rb")) if isinstance(src, (str, os.PathLike)) else src
        _head(fin)
        fout = stack.enter_context(open(dst, "wb")) if isinstance(dst, (str, os.PathLike)) else dst
        writer = Writer(fout, compression=CompressionType.ZSTD)
        writer.start(profile="", library="hydromon recover")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for rec in _salvage(fin, report):
            if isinstance(rec, Schema) and rec.id not in schemas:
                schemas[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
                report.schemas += 1
            elif isinstance(rec, Channel) and rec.id not in channels:
                sid = schemas.get(rec.schema_id, 0)
                channels[rec.id] = writer.register_channel(rec.topic, rec.message_encoding, sid,
                                                           dict(rec.metadata))
                report.channels += 1
            elif isinstance(rec, Message):
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
