"""Recorder node: everything under ``<ns>/**`` on an open zenoh session, into MCAP files.

The node takes an open session (its caller owns it) and never opens one. Samples arrive through a
FIFO channel handler (zenoh forbids blocking or calling its API inside callbacks) that the
worker loop drains; between batches the loop closes the open chunk once it is
``flush_interval_ns`` old, so a killed recorder loses well under a second, and rotates
files by size or age. ``log_time`` is the receive time (``clock()``: by default the wall
clock read once at the start, advanced by the monotonic clock, see :func:`steady_wall_clock`);
``publish_time`` is the payload's sample time ``t`` [s] in ns when the payload is a JSON
object with a numeric ``t``, else the receive time. Rigs publish their config once at their
start, so at its start the recorder asks the running ones for theirs (``<ns>/rig/*/config``,
which the sim node answers), as the monitor does, and records the replies.

File names never contain a rig id: ``out`` is either a ``.mcap`` path, whose parts after
the first get ``-1``, ``-2``... before the suffix, or a directory, where parts are named
``<namespace>-<UTC time>.mcap`` (``/`` in the namespace becomes ``_``).
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh
from pydantic import ValidationError

from hydromon.bus.session import loads
from hydromon.contract import DEFAULT_NAMESPACE, RigConfig, check_namespace
from hydromon.store.mcap_write import RecordingWriter
from hydromon.store.mcap_layout import rig_topic

__all__ = ["record", "RecordResult", "publish_time_ns", "Rotation", "names_a_directory", "steady_wall_clock"]

log = logging.getLogger(__name__)
_BATCH = 1000  # messages drained between timer checks
_WARN_KEYS = 20  # keys whose non-JSON payloads are logged (one line each); the rest are counted


def steady_wall_clock(wall_ns: Callable[[], int] = time.time_ns,
                      monotonic_ns: Callable[[], int] = time.monotonic_ns) -> Callable[[], int]:
    """A clock [ns since the Unix epoch] that reads the wall clock once, now, and then advances
    with the monotonic clock: a wall-clock step (NTP setting a clock that was off, an operator)
    during a recording does not move its log times back, which readers order by (the samples
    after the step then read as a rig restart), nor forward, which a paced replay waits out and
    which would end --duration or rotate a file at once."""
    offset = wall_ns() - monotonic_ns()
    return lambda: offset + monotonic_ns()


class _ConfigQuery:
    """Asks the running rigs for their configs (``<ns>/rig/*/config``, which the sim node
    answers): at the start, and again (at most every ``min_interval_s``) once a sample comes
    from a rig whose config has not been seen, as each rig id at most once: the first query can
    find no route (the session's links or the peers' declarations not yet up) or the rig can
    start later. Replies already recorded (the same payload on the key) are not recorded again."""

    def __init__(self, session, namespace: str, timeout_s: float, min_interval_s: float = 1.0,
                 clock=time.monotonic):
        self.session, self.selector = session, f"{namespace}/rig/*/config"
        self.timeout_s, self.min_interval_s, self.clock = timeout_s, min_interval_s, clock
        self.configured: set[str] = set()  # rigs whose config was seen
        self.asked: set[str] = set()  # rigs a query was sent or is due for
        self.due = True
        self.replies = None
        self.until = self.last = -math.inf

    def saw(self, key: str) -> None:
        """Note a message's key: a config configures its rig; a sample of a rig not configured
        (and not asked about yet) makes a query due."""
        head, _, leaf = key.rpartition("/")
        if leaf == "config":
            self.configured.add(head.rpartition("/")[2])
        elif leaf == "sample":
            rig = head.rpartition("/")[2]
            if rig not in self.configured and rig not in self.asked:
                self.asked.add(rig)
                self.due = True

    def drain(self, handle: Callable, recorded: dict[str, bytes]) -> int:
        """Send a due query, and pass the replies in so far to ``handle``; returns how many."""
        now = self.clock()
        if self.replies is not None and now > self.until:
            self.replies = None
        if self.replies is None and self.due and now - self.last >= self.min_interval_s:
            self.due, self.last, self.until = False, now, now + self.timeout_s + 1.0
            self.replies = self.session.get(self.selector, zenoh.handlers.FifoChannel(4096), timeout=self.timeout_s)
        n = 0
        if self.replies is not None:
            try:
                while (reply := self.replies.try_recv()) is not None:
                    if reply.ok is not None and recorded.get(str(reply.ok.key_expr)) != reply.ok.payload.to_bytes():
                        handle(reply.ok)
                        n += 1
            except zenoh.ZError:  # the query is over (zenoh closes the reply channel)
                self.replies = None
        return n


@dataclass
class RecordResult:
    """Where a recording went: ``files`` in order, message counts."""

    files: list[Path] = field(default_factory=list)
    messages: int = 0
    not_json: int = 0


def publish_time_ns(obj, receive_time_ns: int) -> int:
    """``t`` [s] of a decoded payload as integer ns, or ``receive_time_ns`` if it has none."""
    t = obj.get("t") if isinstance(obj, dict) else None
    if isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t):
        ns = round(t * 1e9)
        if 0 <= ns < 2**64:
            return ns
    return receive_time_ns


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

    A file that is due is closed at once (complete, readable); its successor is opened by
    the next message, so a bus that goes quiet leaves no empty part behind.
    """

    def __init__(self, out, namespace: str, rotate_bytes: int | None, rotate_ns: int | None,
                 writer_kwargs: dict, on_file: Callable[[Path], None] | None, now_ns: int):
        for name, v in (("rotate_bytes", rotate_bytes), ("rotate_ns", rotate_ns)):
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
        self.files: list[Path] = []
        self._configs: dict[str, bytes] = {}
        self._file = self.writer = None
        self._first_ns: int | None = None
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
        self.writer = RecordingWriter(f, **self._kwargs)
        self.files.append(path)
        if self._on_file:
            self._on_file(path)

    def write(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        if self.writer is None:  # the last part was closed when due: this message starts the next
            self._open()
            # every part carries the rigs' configs, as messages ahead of its first one (and so as
            # metadata too): a replay or evaluation of this part alone grades with the rigs' constants,
            # and sees where they were in force from, as the live monitor did
            for ckey, cpayload in self._configs.items():
                if ckey != key:
                    self.writer.write(ckey, cpayload, log_time_ns, log_time_ns)
        self.writer.write(key, payload, log_time_ns, publish_time_ns)
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
        message opens the next one)."""
        if self.writer is None:
            return
        self.writer.flush_if_due(now_ns)
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


def record(session: zenoh.Session, out, *, namespace: str = DEFAULT_NAMESPACE,
           rotate_bytes: int | None = None, rotate_seconds: float | None = None,
           stop_event: threading.Event | None = None, duration_s: float | None = None,
           flush_interval_ns: int = 500_000_000, chunk_size: int = 4 * 1024 * 1024,
           capacity: int = 65536, poll_s: float = 0.005,
           on_file: Callable[[Path], None] | None = None,
           on_message: Callable[[str], None] | None = None,
           clock: Callable[[], int] | None = None, config_query_s: float = 5.0) -> RecordResult:
    """Record ``<namespace>/**`` from ``session`` until ``stop_event`` is set or ``duration_s``.

    Parameters
    ----------
    session : zenoh.Session
        An open session; not closed here.
    out : str or Path
        A ``.mcap`` path or a directory (see the module docstring for file names).
    rotate_bytes, rotate_seconds : int [B], float [s] or None
        Start a new file when the current one passes this size or age.
    stop_event : threading.Event or None
        Set it (from another thread or a signal handler) to stop; the files are closed
        with their summaries.
    duration_s : float or None
        Stop after this long [s].
    flush_interval_ns : int
        Longest a received message waits in memory before it is in the file [ns].
    capacity : int
        Samples the FIFO channel holds before zenoh back-pressures the transport.
    poll_s : float
        Sleep when the channel is empty [s].
    on_file : callable or None
        Called with the path of each file as it is opened.
    on_message : callable or None
        Called with the key of each message once it is handed to the writer (progress).
    clock : callable or None
        Receive time source [ns since the Unix epoch] (None: :func:`steady_wall_clock`).
    config_query_s : float
        How long to wait for the replies to the query that asks the rigs already running for
        their configs [s] (a rig publishes its config once at its start: a recorder started
        after it would otherwise record none, and the recording would be graded with the
        default constants).
    """
    check_namespace(namespace)
    if rotate_seconds is not None and not (isinstance(rotate_seconds, (int, float)) and rotate_seconds > 0):
        raise ValueError(f"rotate_seconds={rotate_seconds!r} must be > 0 [s]")
    if duration_s is not None and not (isinstance(duration_s, (int, float)) and duration_s >= 0):
        raise ValueError(f"duration_s={duration_s!r} must be >= 0 [s]")
    stop = stop_event if stop_event is not None else threading.Event()
    clock = clock or steady_wall_clock()
    start = clock()
    deadline = None if duration_s is None else start + round(duration_s * 1e9)
    rotation = Rotation(out, namespace, rotate_bytes,
                        None if rotate_seconds is None else round(rotate_seconds * 1e9),
                        {"chunk_size": chunk_size, "flush_interval_ns": flush_interval_ns},
                        on_file, start)
    result = RecordResult(files=rotation.files)
    warned: set[str] = set()
    query = _ConfigQuery(session, namespace, config_query_s)

    def handle(sample) -> None:
        now = clock()
        key = str(sample.key_expr)
        payload = sample.payload.to_bytes()
        try:
            obj = loads(payload)
        except ValueError:
            result.not_json += 1
            # bounded: a burst of distinct bogus keys must not flood the log (50,000 keys gave
            # 50,000 lines) nor grow this set without end; the exit summary has the count
            if key not in warned and len(warned) <= _WARN_KEYS:
                warned.add(key)
                if len(warned) <= _WARN_KEYS:
                    log.warning("not recording non-JSON payloads on %s (first of them)", key[:200])
                else:
                    log.warning("not recording non-JSON payloads on more keys: counted, not logged")
            return
        rotation.write(key, payload, now, publish_time_ns(obj, now))
        query.saw(key)
        result.messages += 1
        if on_message is not None:
            on_message(key)

    try:
        with session.declare_subscriber(f"{namespace}/**", zenoh.handlers.FifoChannel(capacity)) as sub:
            try:
                while True:
                    # rigs that published their config before we subscribed: replies to the
                    # query are recorded as config messages, ahead of the samples drained with them
                    n = query.drain(handle, rotation.recorded_configs)
                    while n < _BATCH and (sample := sub.try_recv()) is not None:
                        handle(sample)
                        n += 1
                    now = clock()
                    rotation.tick(now)
                    if stop.is_set() or (deadline is not None and now >= deadline):
                        break
                    if n == 0:
                        stop.wait(poll_s)
                while (sample := sub.try_recv()) is not None:  # what is already queued
                    handle(sample)
            except zenoh.ZError as exc:  # the session was closed under us: end the recording
                log.warning("recorder stopping: %s", exc)
    finally:
        rotation.close()
    return result
