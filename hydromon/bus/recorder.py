"""Recorder node: everything under ``<ns>/**`` on an open zenoh session, into MCAP files.

The node takes an open session (its caller owns it) and never opens one. Samples arrive through a
FIFO channel handler (zenoh forbids blocking or calling its API inside callbacks) that the
worker loop drains; between batches the loop closes the open chunk once it is
``flush_interval_ns`` old, so a killed recorder loses well under a second, and rotates
files by size or age. ``log_time`` is the receive time (``clock()``: by default the wall
clock read once at the start, advanced by the monotonic clock, see :func:`steady_wall_clock`);
``publish_time`` is the payload's sample time ``t`` [s] in ns when the payload is a JSON
object with a numeric ``t`` (a frame: its first sample's, ``t[0]``), else the receive time.
Rigs publish their config once at their start, so at its start the recorder asks the running
ones for theirs (``<ns>/rig/*/config``, which the sim node answers), as the monitor does, and
records the replies.

Nothing on the bus stops the recorder: a payload that is not JSON is counted and skipped (a
JSON one is recorded as received on its key, valid or not: a replay shows what the monitor was
sent), a time ``t`` that is not a plausible time stamp is not used as one (:func:`publish_time_ns`),
a payload over ``max_payload_bytes`` is counted and skipped, and an error in handling one
message is counted and logged, never fatal. A disk that fills up is met before it is full
(:class:`Rotation`): the open file is closed complete, what arrives is counted, not written,
and writing resumes in a new file once there is room again.

File names never contain a rig id: ``out`` is either a ``.mcap`` path, whose parts after
the first get ``-1``, ``-2``... before the suffix, or a directory, where parts are named
``<namespace>-<UTC time>.mcap`` (``/`` in the namespace becomes ``_``).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from hydromon.bus.rotation import DISK_FULL as _DISK_FULL
from hydromon.bus.rotation import Rotation, names_a_directory, space_needed
from hydromon.bus.session import loads
from hydromon.contract import DEFAULT_NAMESPACE, SAMPLE_LEAVES, check_namespace

__all__ = ["record", "RecordResult", "publish_time_ns", "Rotation", "names_a_directory", "steady_wall_clock",
           "MAX_PAYLOAD_BYTES", "space_needed"]

log = logging.getLogger(__name__)
_BATCH = 1000  # messages drained between timer checks
_WARN_KEYS = 20  # keys whose non-JSON payloads are logged (one line each); the rest are counted
_WARN_OTHER = 20  # oversized payloads, and messages whose handling failed, logged; the rest are counted
MAX_PAYLOAD_BYTES = 1_000_000
"""Payloads larger than this [B] are counted and skipped (a contract payload is under 2 kB, a frame
of FRAME_MAX samples with the drive about 130 kB)."""


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
        """Note a message's key: a config configures its rig; a sample or frame of a rig not
        configured (and not asked about yet) makes a query due."""
        head, _, leaf = key.rpartition("/")
        if leaf == "config":
            self.configured.add(head.rpartition("/")[2])
        elif leaf in SAMPLE_LEAVES:
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
    too_large: int = 0  # payloads over max_payload_bytes, skipped
    failed: int = 0  # messages whose handling raised (logged), skipped
    unwritten: int = 0  # messages received while the disk was full
    disk_full: int = 0  # times writing stopped for a full disk


_T_MAX_S = (2**64 - 1) / 1e9  # the last second an MCAP time stamp (uint64 ns) holds


def publish_time_ns(obj, receive_time_ns: int) -> int:
    """``t`` [s] of a decoded payload (a frame's: its first, ``t[0]``) as integer ns, or
    ``receive_time_ns`` if it has none or it is not a time an MCAP record can hold: not a number
    (a string such as ``"nan"``, a bool), not finite, negative, or past 2**64 ns (``1e300``, a
    huge integer)."""
    t = obj.get("t") if isinstance(obj, dict) else None
    if type(t) is list and t:
        t = t[0]
    if isinstance(t, bool) or not isinstance(t, (int, float)):
        return receive_time_ns
    if isinstance(t, float) and not math.isfinite(t):
        return receive_time_ns
    if not 0 <= t < _T_MAX_S:  # compared before scaling: 1e300 * 1e9 is inf, a huge int no float
        return receive_time_ns
    ns = t * 1_000_000_000 if isinstance(t, int) else round(t * 1e9)  # an integer exactly
    return ns if 0 <= ns < 2**64 else receive_time_ns


def record(session: zenoh.Session, out, *, namespace: str = DEFAULT_NAMESPACE,
           rotate_bytes: int | None = None, rotate_seconds: float | None = None,
           stop_event: threading.Event | None = None, duration_s: float | None = None,
           flush_interval_ns: int = 500_000_000, chunk_size: int = 4 * 1024 * 1024,
           capacity: int = 65536, poll_s: float = 0.005,
           on_file: Callable[[Path], None] | None = None,
           on_message: Callable[[str], None] | None = None,
           on_skip: Callable[[str, str], None] | None = None,
           clock: Callable[[], int] | None = None, config_query_s: float = 5.0,
           max_payload_bytes: int = MAX_PAYLOAD_BYTES, low_space_bytes: int | None = None,
           free_bytes: Callable[[Path], int] | None = None) -> RecordResult:
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
    on_skip : callable or None
        Called with the key and the reason (``not-json``, ``too-large``, ``unwritten``: the disk
        was full, ``failed``) of each message not recorded.
    clock : callable or None
        Receive time source [ns since the Unix epoch] (None: :func:`steady_wall_clock`).
    config_query_s : float
        How long to wait for the replies to the query that asks the rigs already running for
        their configs [s] (a rig publishes its config once at its start: a recorder started
        after it would otherwise record none, and the recording would be graded with the
        default constants).
    max_payload_bytes : int
        Larger payloads are counted (``too_large``) and skipped [B].
    low_space_bytes : int or None
        Stop writing below this much free space [B] (:class:`Rotation`; None:
        :func:`space_needed` of ``chunk_size`` and ``max_payload_bytes``).
    free_bytes : callable or None
        ``free_bytes(directory)`` [B], for :class:`Rotation`.
    """
    check_namespace(namespace)
    if rotate_seconds is not None and not (isinstance(rotate_seconds, (int, float)) and rotate_seconds > 0):
        raise ValueError(f"rotate_seconds={rotate_seconds!r} must be > 0 [s]")
    if duration_s is not None and not (isinstance(duration_s, (int, float)) and duration_s >= 0):
        raise ValueError(f"duration_s={duration_s!r} must be >= 0 [s]")
    if isinstance(max_payload_bytes, bool) or not isinstance(max_payload_bytes, int) or max_payload_bytes <= 0:
        raise ValueError(f"max_payload_bytes={max_payload_bytes!r} must be a positive integer [B]")
    stop = stop_event if stop_event is not None else threading.Event()
    clock = clock or steady_wall_clock()
    start = clock()
    deadline = None if duration_s is None else start + round(duration_s * 1e9)
    rotation = Rotation(out, namespace, rotate_bytes,
                        None if rotate_seconds is None else round(rotate_seconds * 1e9),
                        {"chunk_size": chunk_size, "flush_interval_ns": flush_interval_ns},
                        on_file, start, space_needed(chunk_size, max_payload_bytes) if low_space_bytes is None
                        else low_space_bytes, free_bytes)
    result = RecordResult(files=rotation.files)
    warned: set[str] = set()
    query = _ConfigQuery(session, namespace, config_query_s)

    def handle(sample) -> None:
        key = "?"
        try:
            key = str(sample.key_expr)
            record_one(key, sample.payload)
        except Exception as exc:  # noqa: BLE001 (one message must not end the recording)
            if isinstance(exc, OSError) and exc.errno not in _DISK_FULL:
                raise  # the file system refuses (permissions, I/O errors): the command says so
            result.failed += 1
            if on_skip is not None:
                on_skip(key, "failed")
            if result.failed <= _WARN_OTHER:
                more = "" if result.failed < _WARN_OTHER else " (further ones are counted, not logged)"
                log.warning("recorder: could not record a message on %s, skipped: %s: %s%s", key[:200],
                            type(exc).__name__, str(exc)[:200], more)

    def record_one(key: str, zbytes) -> None:
        now = clock()
        size = len(zbytes)
        if size > max_payload_bytes:
            result.too_large += 1
            if on_skip is not None:
                on_skip(key, "too-large")
            if result.too_large <= _WARN_OTHER:
                more = "" if result.too_large < _WARN_OTHER else " (further ones are counted, not logged)"
                log.warning("recorder: not recording a payload of %d B on %s (over --max-payload-mb, %d B)%s",
                            size, key[:200], max_payload_bytes, more)
            return
        payload = zbytes.to_bytes()
        try:
            obj = loads(payload)
        except ValueError:
            result.not_json += 1
            if on_skip is not None:
                on_skip(key, "not-json")
            # bounded: a burst of distinct bogus keys must not flood the log (50,000 keys gave
            # 50,000 lines) nor grow this set without end; the exit summary has the count
            if key not in warned and len(warned) <= _WARN_KEYS:
                warned.add(key)
                if len(warned) <= _WARN_KEYS:
                    log.warning("not recording non-JSON payloads on %s (first of them)", key[:200])
                else:
                    log.warning("not recording non-JSON payloads on more keys: counted, not logged")
            return
        written = rotation.write(key, payload, now, publish_time_ns(obj, now))
        query.saw(key)
        if not written:
            if on_skip is not None:
                on_skip(key, "unwritten")
            return
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
        try:
            rotation.close()
        finally:
            result.unwritten, result.disk_full = rotation.unwritten, rotation.disk_full
    return result
