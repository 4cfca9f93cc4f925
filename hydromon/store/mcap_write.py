"""The MCAP writer of bus messages (layout: ``hydromon.store.mcap_layout``'s docstring, docs/contract.md
"Recordings"): one channel per key, JSON Schemas of the payload models, each rig's config also
as metadata, chunks flushed by log time so a killed recorder loses at most about a second.
"""

from __future__ import annotations

import json
import logging

from mcap.writer import Writer
from pydantic import ValidationError

from hydromon.contract import RigConfig
from hydromon.store.mcap_layout import COMPRESSION, LEAF_MODELS, rig_topic, time_ns

__all__ = ["RecordingWriter"]

log = logging.getLogger("hydromon.store.mcap_read")  # one logger for the recordings' messages
_WARN_CONFIGS = 20  # invalid configs logged per file (one line each); the rest are counted


class RecordingWriter:
    """Write bus messages into one MCAP stream (see the module docstring for the layout).

    Parameters
    ----------
    stream : binary file object
        Where the recording goes (a file opened ``"wb"``, an ``io.BytesIO``...). Not closed.
    chunk_size : int
        Close a chunk when its uncompressed records pass this many bytes [B].
    compression : {"zstd", "lz4", "none"}
        Chunk compression.
    flush_interval_ns : int
        Close and write out the open chunk once the log time of a new message (or of
        :meth:`flush_if_due`) is this far past the chunk's first message [ns].
    """

    def __init__(self, stream, *, chunk_size: int = 4 * 1024 * 1024, compression: str = "zstd",
                 flush_interval_ns: int = 1_000_000_000):
        if compression not in COMPRESSION:
            raise ValueError(f"compression {compression!r}: choose one of {', '.join(COMPRESSION)}")
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size <= 0:
            raise ValueError(f"chunk_size={chunk_size!r} must be a positive integer [B]")
        if isinstance(flush_interval_ns, bool) or not isinstance(flush_interval_ns, int) \
                or flush_interval_ns <= 0:
            raise ValueError(f"flush_interval_ns={flush_interval_ns!r} must be a positive integer [ns]")
        self.chunk_size = chunk_size
        self.compression = compression
        self.flush_interval_ns = flush_interval_ns
        self._stream = stream
        self._writer = Writer(stream, chunk_size=chunk_size, compression=COMPRESSION[compression])
        self._writer.start(profile="", library="hydromon")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._configs: dict[str, bytes] = {}
        self._chunk_first_ns: int | None = None
        self._closed = False
        self.durable_offset = 0  # stream offset up to which every record is written out (flushed)
        self.message_count = 0
        self.invalid_configs = 0

    # -- channels -------------------------------------------------------------------------
    def _schema_id(self, leaf: str | None) -> int:
        model = LEAF_MODELS.get(leaf)
        name = f"hydromon.{model.__name__}" if model else "hydromon.Any"
        if name not in self._schemas:
            schema = model.model_json_schema(by_alias=True) if model else {}
            self._schemas[name] = self._writer.register_schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode())
        return self._schemas[name]

    def _channel_id(self, key: str) -> int:
        cid = self._channels.get(key)
        if cid is None:
            parsed = rig_topic(key)
            sid = self._schema_id(parsed[1] if parsed else None)
            cid = self._writer.register_channel(topic=key, message_encoding="json", schema_id=sid)
            self._channels[key] = cid
            self._sequence[cid] = 0
        return cid

    # -- messages -------------------------------------------------------------------------
    def write(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        """Add one message: ``payload`` (JSON bytes) received at ``log_time_ns`` on ``key``."""
        if self._closed:
            raise ValueError("write() on a closed RecordingWriter")
        if not isinstance(key, str) or not key:
            raise ValueError(f"key {key!r} must be a non-empty string")
        if not isinstance(payload, (bytes, bytearray, memoryview)):
            raise ValueError(f"payload for {key!r} must be bytes, got {type(payload).__name__}")
        log_time_ns = time_ns("log_time_ns", log_time_ns)
        publish_time_ns = time_ns("publish_time_ns", publish_time_ns)
        self.flush_if_due(log_time_ns)
        cid = self._channel_id(key)
        seq = self._sequence[cid]
        self._sequence[cid] = (seq + 1) % 2**32
        payload = bytes(payload)
        self._writer.add_message(channel_id=cid, log_time=log_time_ns, data=payload,
                                 publish_time=publish_time_ns, sequence=seq)
        self.message_count += 1
        if self._chunk_first_ns is None:
            self._chunk_first_ns = log_time_ns
        parsed = rig_topic(key)
        if parsed is not None and parsed[1] == "config":
            self.store_config(key, payload)

    def store_config(self, key: str, payload: bytes) -> bool:
        """Store a rig's config (from its config ``key``) as metadata ``rig_config/<id>``.

        Done by :meth:`write` for config messages; call it directly to carry a config into
        a new file. Returns False if the payload equals the last one stored for the rig, or
        is not a valid RigConfig (then it is logged and counted in ``invalid_configs``).
        """
        if self._closed:
            raise ValueError("store_config() on a closed RecordingWriter")
        parsed = rig_topic(key)
        if parsed is None or parsed[1] != "config":
            raise ValueError(f"key {key!r} is not a <ns>/rig/<id>/config key")
        rig, payload = parsed[0], bytes(payload)
        if self._configs.get(rig) == payload:
            return False
        try:
            cfg = RigConfig.model_validate_json(payload)
        except ValidationError as exc:
            self.invalid_configs += 1
            if self.invalid_configs <= _WARN_CONFIGS:  # bounded: a flood of bad configs must not flood the log
                more = "" if self.invalid_configs < _WARN_CONFIGS else " (further ones are counted, not logged)"
                log.warning("config on %s is not a valid RigConfig; recorded, not stored as metadata: %s%s",
                            key[:200], exc.errors()[0].get("msg"), more)
            return False
        self._writer.add_metadata(f"rig_config/{rig}",
                                  {k: json.dumps(v) for k, v in cfg.model_dump(mode="json").items()})
        self._configs[rig] = payload
        return True

    def flush_if_due(self, now_ns: int) -> bool:
        """Write out the open chunk if its first message is ``flush_interval_ns`` before ``now_ns``."""
        first = self._chunk_first_ns
        if first is not None and now_ns - first >= self.flush_interval_ns:
            self.flush()
            return True
        return False

    def flush(self) -> None:
        """Close the open chunk (if any), write it out and flush the stream."""
        if not self._closed:
            self._writer.flush()
            self._chunk_first_ns = None
            self._note_durable()

    def close(self) -> None:
        """Write the last chunk and the summary (indexes, statistics). The stream stays open."""
        if not self._closed:
            self._writer.finish()
            self._writer.flush()  # flushes the stream, also a BufferedWriter mcap wrapped around it
            self._closed = True
            self._note_durable()

    def _note_durable(self) -> None:
        try:
            self.durable_offset = self._stream.tell()
        except (OSError, ValueError, AttributeError):  # a stream that cannot tell
            pass

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
