"""A recording's window published back onto the bus, paced as it was recorded.

Pacing is drift-free: message i is due at ``t0 + (log_time_i - first) / rate``, a deadline
computed from the recording, never by adding up sleeps; a late message goes at once and the
next deadlines stay put. ``rate`` = 0 sends as fast as possible. With ``loop`` the window plays
again, each pass starting one mean message spacing after the previous pass's last message (the
rigs' seq restarts at the start of the window; the monitor treats seq 0 after a higher seq as a
restart). The window and key filter are ``hydromon.store.replay``'s.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import zenoh

from hydromon.bus.session import JSON
from hydromon.store.replay import KeyFilter, read_window, recording_span, recording_topics, window

__all__ = ["ReplayStats", "replay_bus"]

log = logging.getLogger(__name__)


@dataclass
class ReplayStats:
    """What a bus replay did: messages put, whole passes, lateness of the sends [s], wall time
    [s]; ``stopped_at``: where in its pass the stop event cut the replay short [s of recording
    from the window's start], None if it was not; ``not_keys``: messages skipped per topic that
    cannot be a zenoh key (``/tf``, a ROS topic: a leading slash), which no bus can carry."""

    published: int = 0
    passes: int = 0
    not_keys: dict = field(default_factory=dict)  # topic that is not a zenoh key -> messages skipped
    stopped_at: float | None = None
    max_late: float = 0.0
    wall: float = 0.0
    keys: set = field(default_factory=set)


def _is_key(topic: str) -> bool:
    """Whether ``topic`` is a valid zenoh key expression (so it can be published)."""
    try:
        zenoh.KeyExpr(topic)
    except Exception:  # zenoh's own verdict (ZError and kin)
        return False
    return True


def replay_bus(session: zenoh.Session, src, *, rate: float = 1.0, keys: Iterable[str] | None = None,
               start: float | None = None, duration: float | None = None, loop: bool = False,
               max_passes: int | None = None, wait_s: float = 0.0, stop_event: threading.Event | None = None,
               progress: Callable[[float, float], None] | None = None,
               congestion: zenoh.CongestionControl = zenoh.CongestionControl.BLOCK,
               clock=time.monotonic) -> ReplayStats:
    """Publish a recording's window on ``session`` (see the module docstring for pacing).

    Parameters
    ----------
    rate : float
        Speed relative to the recording (1 = as recorded, 0 = as fast as possible).
    loop : bool
        Play the window again and again until ``stop_event`` (or ``max_passes`` passes).
    wait_s : float
        Before sending, wait up to this long [s] for a subscriber to match one of the
        replayed keys (a peer that has just connected may not have heard the others'
        subscriptions yet, and zenoh drops what has no route); go on without after that.
    progress : callable or None
        Called as ``progress(done_s, total_s)`` in recording seconds of the current pass.
    congestion : zenoh.CongestionControl
        BLOCK (default) never drops: a slow subscriber slows the replay.
    """
    if not rate >= 0:
        raise ValueError(f"rate {rate!r} must be >= 0")
    first, lo, hi, count = window(src, start, duration)
    last = recording_span(src)[1]
    end = last if hi is None else min(hi, last)  # the window's end, for the progress of a pass
    stop = stop_event if stop_event is not None else threading.Event()
    match = KeyFilter(keys)
    stats = ReplayStats()
    pubs: dict[str, zenoh.Publisher] = {}
    not_keys = {key for key in recording_topics(src) if not _is_key(key)}
    if wait_s > 0:
        for key in recording_topics(src):
            if match(key) and key not in pubs and key not in not_keys:
                pubs[key] = session.declare_publisher(key, encoding=JSON, congestion_control=congestion)
        deadline = clock() + wait_s
        while not any(p.matching_status.matching for p in pubs.values()) and clock() < deadline:
            if stop.wait(0.01):
                break
        else:
            if pubs and not any(p.matching_status.matching for p in pubs.values()):
                log.warning("no subscriber for the replayed keys after %.1f s; replaying anyway", wait_s)
    t0 = clock()
    base_ns = 0  # recording time of the start of this pass, relative to the first pass
    try:
        while not stop.is_set() and count:
            first_ns = last_ns = None
            n = 0
            for key, payload, log_ns, _ in read_window(src, lo, hi, first):
                if first_ns is None:
                    first_ns = log_ns
                last_ns = log_ns
                n += 1
                if not match(key):
                    continue
                if key in not_keys:
                    stats.not_keys[key] = stats.not_keys.get(key, 0) + 1
                    continue
                offset = (base_ns + log_ns - first_ns) / 1e9
                if rate > 0:
                    wait = t0 + offset / rate - clock()
                    if (stop.wait(wait) if wait > 0 else stop.is_set()):
                        stats.stopped_at = (log_ns - first_ns) / 1e9
                        break
                    stats.max_late = max(stats.max_late, -wait)
                elif stop.is_set():
                    stats.stopped_at = (log_ns - first_ns) / 1e9
                    break
                pub = pubs.get(key)
                if pub is None:
                    pub = pubs[key] = session.declare_publisher(key, encoding=JSON, congestion_control=congestion)
                pub.put(payload)
                stats.published += 1
                stats.keys.add(key)
                if progress is not None and stats.published % 200 == 0:
                    progress((log_ns - first_ns) / 1e9, (end - first_ns) / 1e9)
            if first_ns is None or stats.stopped_at is not None:
                break  # an empty window, or stopped mid-pass: not a pass, and its progress stays where it was
            stats.passes += 1
            if progress is not None:
                progress((last_ns - first_ns) / 1e9, (last_ns - first_ns) / 1e9)
            if not loop or (max_passes is not None and stats.passes >= max_passes):
                break
            span = last_ns - first_ns
            base_ns += span + (span // max(n - 1, 1) if n > 1 else 10_000_000)
    finally:
        stats.wall = clock() - t0
        for p in pubs.values():
            p.undeclare()
    return stats
