"""The recorder's files: the open MCAP file, its successors (rotation by size or age), and what
happens when the disk fills up (:class:`Rotation`)."""

from __future__ import annotations

import errno
import logging
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path

from pydantic import ValidationError

from hydromon.contract import RigConfig
from hydromon.store.mcap_layout import rig_topic
from hydromon.store.mcap_write import RecordingWriter

__all__ = ["Rotation", "names_a_directory", "space_needed", "DISK_FULL"]

log = logging.getLogger("hydromon.bus.recorder")  # the recorder's log: these lines are its
DISK_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
"""The errors of a write that found no room."""
_SPACE_CHECK_S = 0.1  # [s] of receive time between two looks at the free space


def _valid_config(payload: bytes) -> bool:
    """A config payload the monitor would take (a valid RigConfig; its sample rate is not known here)."""
    try:
        RigConfig.model_validate_json(payload)
    except ValidationError:
        return False
    return True


def names_a_directory(out) -> bool:
    """``out`` (a path) is a directory for time-stamped files: it is one, or ends with a ``/``;
    anything else names the file (``.mcap`` added if missing), whose directory is created."""
    out_s = os.fspath(out)
    return out_s.endswith(("/", os.sep)) or os.path.isdir(out_s)


def space_needed(chunk_size: int, max_payload_bytes: int) -> int:
    """Free space [B] below which a recorder stops writing: room for the chunk being built, one
    more payload, and the file's summary, so that the file it closes is complete."""
    return 2 * chunk_size + max_payload_bytes + (1 << 20)


class Rotation:
    """The open MCAP file and its successors.

    Parameters
    ----------
    out : str or Path
        A ``.mcap`` file path, or a directory (existing, or given with a trailing ``/``).
    namespace : str
        Used in file names when ``out`` is a directory.
    rotate_bytes : int or None
        Start a new file once the current one reaches this size [B].
    rotate_ns : int or None
        Start a new file once the current one spans this much log time [ns] (from its
        first message, so a quiet bus makes no empty files).
    writer_kwargs : dict
        Passed to :class:`~hydromon.store.mcap_write.RecordingWriter`.
    on_file : callable or None
        Called with each new file's path.
    low_space_bytes : int or None
        Stop writing once the file system of ``out`` has less free space than this [B] (None: never
        look); :func:`space_needed`.
    free_bytes : callable or None
        ``free_bytes(directory)`` [B] (default: :func:`shutil.disk_usage`'s free space).

    A file that is due is closed at once (complete, readable); its successor is opened by
    the next message, so a bus that goes quiet leaves no empty part behind.

    A disk that fills up: once less than ``low_space_bytes`` is free, the open file is closed
    (complete: the room kept back holds its last chunk and summary), said in the log, and
    :meth:`write` counts in ``unwritten`` what it is given instead of writing it; once twice that
    is free again, the next message opens a new part, and the log says how many were not
    written. Should the disk fill all the same (another writer took the room), the file is cut
    back to its last complete chunk and closed: ``hydromon recover`` makes it whole.
    """

    def __init__(self, out, namespace: str, rotate_bytes: int | None, rotate_ns: int | None,
                 writer_kwargs: dict, on_file: Callable[[Path], None] | None, now_ns: int,
                 low_space_bytes: int | None = None, free_bytes: Callable[[Path], int] | None = None):
        for name, v in (("rotate_bytes", rotate_bytes), ("rotate_ns", rotate_ns), ("low_space_bytes", low_space_bytes)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v <= 0):
                raise ValueError(f"{name}={v!r} must be a positive integer or None")
        out_s = os.fspath(out)
        if names_a_directory(out_s):
            stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(now_ns / 1e9))
            self._base = Path(out_s) / f"{namespace.replace('/', '_')}-{stamp}"
        else:
            path = Path(out_s)
            self._base = path.with_suffix("") if path.suffix == ".mcap" else path
        self._base.parent.mkdir(parents=True, exist_ok=True)
        self.rotate_bytes, self.rotate_ns = rotate_bytes, rotate_ns
        self._kwargs, self._on_file = writer_kwargs, on_file
        self.low_space_bytes = low_space_bytes
        self._free_bytes = free_bytes or (lambda d: shutil.disk_usage(d).free)
        self.files: list[Path] = []
        self._configs: dict[str, bytes] = {}
        self._file = self.writer = None
        self._first_ns: int | None = None
        self.full = False  # not writing: the disk is (nearly) full
        self.unwritten = 0  # messages given while full
        self.disk_full = 0  # times writing stopped
        self._full_since_unwritten = 0
        self._checked_ns: int | None = None
        self._since_check = 0  # bytes handed to the writer since the free space was last looked at
        self._good = 0  # file offset up to which every record is complete
        self._open()

    def _open(self) -> None:
        part = len(self.files)
        while True:
            path = self._base.with_name(self._base.name + (f"-{part}" if part else "") + ".mcap")
            try:
                f = open(path, "xb")
                break
            except FileExistsError:
                if not self.files:
                    raise ValueError(f"{path} exists; refusing to overwrite a recording") from None
                part += 1
        self._file, self._first_ns = f, None
        self._good = 0
        self.files.append(path)
        self.writer = RecordingWriter(f, **self._kwargs)
        if self._on_file:
            self._on_file(path)

    # -- space ------------------------------------------------------------------------------------
    def _free(self) -> int | None:
        try:
            return self._free_bytes(self._base.parent)
        except OSError:
            return None

    def _look(self, now_ns: int, force: bool = False) -> int | None:
        """The free space, when it is time to look again (else None)."""
        if self.low_space_bytes is None:
            return None
        due = (force or self._checked_ns is None or now_ns - self._checked_ns >= _SPACE_CHECK_S * 1e9
               or self._since_check >= self.low_space_bytes // 4)
        if not due:
            return None
        self._checked_ns, self._since_check = now_ns, 0
        return self._free()

    def _stop_for_space(self, free: int | None, cut: bool = False, exc: OSError | None = None) -> None:
        """Close the open file (complete, or cut back to its last whole chunk when the disk filled
        under it) and stop writing."""
        path = self.files[-1] if self.files else None
        self.full, self._full_since_unwritten = True, 0
        self.disk_full += 1
        room = "no room left" if free is None else f"{free / 1e6:.1f} MB free"
        if cut:
            self._abandon()
            log.error("recorder: the disk filled (%s) on %s: cut back to its last complete chunk and closed "
                      "(hydromon recover %s makes it a complete recording); not writing until there is room, "
                      "counting what arrives", exc.strerror if exc else room, path, path)
            return
        try:
            self.close()
        except OSError as err:  # the room kept back was taken meanwhile
            if err.errno not in DISK_FULL:
                raise
            self._abandon()
            log.error("recorder: the disk filled while closing %s: cut back to its last complete chunk "
                      "(hydromon recover %s makes it a complete recording)", path, path)
        else:
            log.error("recorder: disk nearly full (%s in %s, below the %.1f MB kept to close a file complete): "
                      "closed %s (complete); not writing until there is room, counting what arrives",
                      room, self._base.parent, self.low_space_bytes / 1e6, path)
        self._file = self.writer = None

    def _abandon(self) -> None:
        """Close the file after a failed write, cut back to its last complete record."""
        f, path, good = self._file, self.files[-1], self._good
        self._file = self.writer = None
        if f is not None:
            try:
                f.close()
            except OSError:
                pass
        try:
            os.truncate(path, good)
        except OSError:
            pass

    def _resume_if_room(self, now_ns: int) -> bool:
        if self.low_space_bytes is None:  # stopped by a failed write, with no margin set: 2 MiB will do
            if self._checked_ns is not None and now_ns - self._checked_ns < _SPACE_CHECK_S * 1e9:
                return False
            self._checked_ns = now_ns
            free, need = self._free(), 2 << 20
        else:
            free, need = self._look(now_ns), 2 * self.low_space_bytes
        if free is None or free < need:
            return False
        self.full = False
        log.warning("recorder: disk has room again (%.1f MB free): writing a new file; %d message(s) received "
                    "meanwhile were not recorded", free / 1e6, self._full_since_unwritten)
        return True

    # -- messages ---------------------------------------------------------------------------------
    def write(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> bool:
        """Write one message; False if it was not written (the disk is full: counted in ``unwritten``)."""
        if self.full and not self._resume_if_room(log_time_ns):
            self.unwritten += 1
            self._full_since_unwritten += 1
            return False
        try:
            self._write(key, payload, log_time_ns, publish_time_ns)
        except OSError as exc:
            if exc.errno not in DISK_FULL:
                raise
            self._stop_for_space(self._free(), cut=True, exc=exc)
            self.unwritten += 1
            self._full_since_unwritten += 1
            return False
        self._since_check += len(payload)
        free = self._look(log_time_ns)
        if free is not None and free < self.low_space_bytes:
            self._stop_for_space(free)
        return True

    def _write(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        if self.writer is None:  # the last part was closed when due: this message starts the next
            self._open()
            # every part carries the rigs' configs, as messages ahead of its first one (and so as
            # metadata too): a replay or evaluation of this part alone grades with the rigs' constants,
            # and sees where they were in force from, as the live monitor did
            for ckey, cpayload in self._configs.items():
                if ckey != key:
                    self.writer.write(ckey, cpayload, log_time_ns, log_time_ns)
        self.writer.write(key, payload, log_time_ns, publish_time_ns)
        self._good = self.writer.durable_offset
        if self._first_ns is None:
            self._first_ns = log_time_ns
        parsed = rig_topic(key)
        if parsed is not None and parsed[1] == "config" and _valid_config(payload):
            self._configs[key] = payload  # carried into the next parts (an invalid one the monitor rejects: not)

    @property
    def recorded_configs(self) -> dict[str, bytes]:
        """The last valid config recorded on each config key (what each new part starts with)."""
        return self._configs

    def tick(self, now_ns: int) -> None:
        """Flush the open chunk if due; close the file if it is big or old enough (the next
        message opens the next one); look at the free space."""
        if self.writer is None:
            return
        try:
            self.writer.flush_if_due(now_ns)
            self._good = self.writer.durable_offset
        except OSError as exc:
            if exc.errno not in DISK_FULL:
                raise
            self._stop_for_space(self._free(), cut=True, exc=exc)
            return
        free = self._look(now_ns)
        if free is not None and free < self.low_space_bytes:
            self._stop_for_space(free)
            return
        if self._first_ns is None:
            return
        if (self.rotate_bytes is not None and self._file.tell() >= self.rotate_bytes) or \
                (self.rotate_ns is not None and now_ns - self._first_ns >= self.rotate_ns):
            self.close()
            self._file = self.writer = None

    def close(self) -> None:
        if self._file is not None and not self._file.closed:
            try:
                self.writer.close()
            finally:
                self._file.close()
