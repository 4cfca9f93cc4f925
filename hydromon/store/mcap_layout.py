"""MCAP recordings of the bus: the layout, and what reading, writing and recovery share.

Layout (docs/contract.md, "Recordings"): one channel per key expression (topic = the key),
``message encoding: json``; the channel's schema is the JSON Schema of the payload model for the
key's leaf (``contract.LEAF_MODELS``; anything else a permissive ``{}``), ``schema encoding:
jsonschema``. Each rig's config is also stored as metadata ``rig_config/<id>`` (fields as JSON
text) when it is first seen and whenever it changes. ``log_time`` is when the recorder received
the message, ``publish_time`` the payload's sample time ``t``; both integer nanoseconds.
Every open chunk is closed and written out at most ``flush_interval_ns`` of log time after its
first message, so a recorder that is killed loses at most about that much; such a file has no
summary and ``hydromon.store.mcap_recover`` rewrites what survived into a valid one.
Readers and writers take binary streams as well as paths, so tests run in memory.
"""

from __future__ import annotations

import contextlib
import os
import struct

import numpy as np
import zstandard
from mcap.exceptions import McapError
from mcap.stream_reader import CRCValidationError
from mcap.writer import CompressionType

from hydromon.contract import LEAF_MODELS, parse_rig_key

__all__ = [
    "MAGIC", "U64", "LEAF_MODELS", "COMPRESSION", "DECODE_ERRORS", "RecordingError", "TruncatedRecording",
    "CorruptRecording", "EmptyRecording", "recover_hint", "damaged", "rig_topic", "time_ns", "opened",
    "empty_message",
]

MAGIC = b"\x89MCAP0\r\n"
COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
U64 = 2**64  # time stamps are unsigned 64-bit nanoseconds

# what the mcap library raises on damaged bytes (a flipped bit in a length field gives an
# OverflowError from its stream reader, or a MemoryError for a huge allocation)
DECODE_ERRORS = (McapError, ValueError, KeyError, struct.error, EOFError, zstandard.ZstdError,
                  RuntimeError, OverflowError, MemoryError)


class RecordingError(ValueError):
    """A recording cannot be read or written as asked (a ValueError: bad input)."""


class TruncatedRecording(RecordingError):
    """The recording has no footer (its recorder was killed); ``hydromon recover`` fixes it."""


class CorruptRecording(RecordingError):
    """The recording is not MCAP, or its content does not decode."""


class EmptyRecording(RecordingError):
    """The file is empty or shorter than the MCAP magic: nothing to read or recover."""


def recover_hint(name: str) -> str:
    """The advice every damaged-recording message ends with."""
    return f"run `hydromon recover {name}` to salvage the intact chunks"


def damaged(name: str, exc: BaseException, where: str = "") -> CorruptRecording:
    """A :class:`CorruptRecording` naming the file (and ``where`` in it) for a decode error ``exc``."""
    if isinstance(exc, CRCValidationError):
        what = "fails its CRC check (its bytes changed on disk or in transit)"
    elif isinstance(exc, zstandard.ZstdError):
        what = f"does not decompress ({exc})"
    else:
        what = f"does not decode ({type(exc).__name__}: {exc})"
    return CorruptRecording(f"{name}: damaged recording: {where or 'a record'} {what}; {recover_hint(name)}")


def rig_topic(key: str) -> tuple[str, str] | None:
    """``(rig_id, leaf)`` for a topic ``<ns>/rig/<id>/<sample|health|config>`` under any
    namespace, else None (the contract's key codec)."""
    return parse_rig_key(key, ns=None)


def time_ns(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < U64:
        raise ValueError(f"{name}={value!r} must be an integer number of nanoseconds in [0, 2**64)")
    return int(value)


@contextlib.contextmanager
def opened(src):
    """``(binary file, name)`` of a path (opened and closed here) or a stream (rewound when seekable).

    A path that cannot be opened raises FileNotFoundError (missing) or :class:`RecordingError`
    (a directory, no permission...), each naming the path: what the commands report as a
    one-line error, not a traceback."""
    if isinstance(src, (str, os.PathLike)):
        name = os.fspath(src)
        try:
            f = open(src, "rb")
        except FileNotFoundError:
            raise FileNotFoundError(f"{name}: no such file") from None
        except IsADirectoryError:
            raise RecordingError(f"{name}: is a directory; give an MCAP recording (a .mcap file)") from None
        except OSError as exc:
            raise RecordingError(f"{name}: cannot be read ({exc.strerror or exc})") from None
        with f:
            yield f, name
    else:
        if src.seekable():
            src.seek(0)
        yield src, getattr(src, "name", "<stream>")


def empty_message(name: str, size: int) -> str:
    """What to say about a file of ``size`` < len(MAGIC) bytes."""
    what = "0 bytes" if size == 0 else f"{size} bytes, shorter than the MCAP magic"
    return f"{name}: empty recording ({what}): nothing to read or recover"
