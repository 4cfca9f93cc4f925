"""What the monitor node watches besides its input, by a clock the caller passes in.

:class:`RateLimitedLog` keeps the rejection log readable under a flood of bad messages, and
:class:`RigWarningLog` the rigs' warnings under a rig that changes its config every message;
:class:`SilenceWatch` finds rigs that went silent (their latest health re-sent ``stale``, and
forgotten after a longer silence); :class:`BacklogWatch` says when the node falls behind its
input. No I/O but logging, no clock of their own: the node (``hydromon.bus.monitor``) calls them.
"""

from __future__ import annotations

import logging
import re
import time

import numpy as np

from hydromon.engine.core import MonitorCore

__all__ = ["RateLimitedLog", "RigWarningLog", "SilenceWatch", "BacklogWatch"]

log = logging.getLogger("hydromon.bus.monitor")  # the node's log: these lines are its


class _Throttle:
    """Per key: the first at once, then at most one every ``interval`` [s], with how many were
    held back between (the shared rule of the node's two rate-limited logs)."""

    def __init__(self, interval: float, clock):
        self.interval, self.clock = float(interval), clock
        self._last: dict = {}
        self._suppressed: dict = {}

    def admit(self, key) -> int | None:
        """None: held back (counted); else say it now, with this many held back before it."""
        now = self.clock()
        last = self._last.get(key)
        if last is not None and now - last < self.interval:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)

    def due(self, final: bool = False) -> list:
        """``(key, count)`` of the held-back counts whose interval has passed (every one if
        ``final``); keys quiet for longer than the interval are forgotten (rigs come and go)."""
        now, out = self.clock(), []
        for key in list(self._suppressed):
            if final or now - self._last[key] >= self.interval:
                out.append((key, self._suppressed.pop(key)))
                self._last[key] = now
        for key in [k for k, last in self._last.items() if now - last >= self.interval and k not in self._suppressed]:
            del self._last[key]
        return out


class RateLimitedLog:
    """``__call__(reason, key, detail)`` logs the first rejection of each reason at once,
    then at most one line per reason every ``interval`` [s] with how many were suppressed.

    ``flush()`` reports the suppressed counts that are due even when no further rejection
    comes (the node calls it from its loop, and with ``final=True`` when it stops): without
    it, the last burst of a reason would never be counted in the log.
    """

    def __init__(self, logger: logging.Logger = log, interval: float = 5.0, clock=time.monotonic):
        self.logger, self._throttle = logger, _Throttle(interval, clock)

    def __call__(self, reason: str, key: str, detail: str) -> None:
        n = self._throttle.admit(reason)
        if n is not None:
            more = f" (+{n} more since the last report)" if n else ""
            self.logger.warning("rejected %s on %s: %s%s", reason, key[:200], detail[:200], more)

    def flush(self, final: bool = False) -> None:
        """Log each reason's suppressed count whose interval has passed (every one if ``final``)."""
        for reason, n in self._throttle.due(final):
            self.logger.warning("rejected %s: %d more since the last report", reason, n)


_NUMBER = re.compile(r"[-+]?[0-9][0-9.eE+-]*")


class RigWarningLog:
    """``__call__(rig_id, message)`` (``MonitorCore(on_warning=...)``) logs a rig's warning of
    each kind (the message up to its first ':' or '(', its numbers left out) at once, then at
    most one line per rig and kind every ``interval`` [s] with how many were suppressed;
    ``flush`` as :class:`RateLimitedLog`'s. Most warnings come once per rig and restart of its
    estimates, but a rig whose config flips with every message would write two lines a message."""

    def __init__(self, logger: logging.Logger = log, interval: float = 5.0, clock=time.monotonic):
        self.logger, self._throttle = logger, _Throttle(interval, clock)

    def __call__(self, rig_id: str, message: str) -> None:
        # numbers (a seq, a reading) differ from one warning of a kind to the next: not the kind
        n = self._throttle.admit((rig_id, _NUMBER.sub("#", message.split(":", 1)[0].split("(", 1)[0]).strip()[:60]))
        if n is not None:
            more = f" (+{n} more like it since the last report)" if n else ""
            self.logger.warning("rig %s: %s%s", rig_id, message, more)

    def flush(self, final: bool = False) -> None:
        """Log each suppressed count whose interval has passed (every one if ``final``)."""
        for (rig_id, kind), n in self._throttle.due(final):
            self.logger.warning("rig %s: %d more warnings '%s...' since the last report", rig_id, n, kind)


REFUSED_STREAM = 10
"""Rejected messages of a rig during its silence from which it is re-sent ``bad-input``, not
``stale``: its messages keep coming (a rig at 100 Hz sends 200 in 2 s), while a link that died
mid-message leaves one cut-off message."""


class SilenceWatch:
    """Rigs that have sent no sample for a while, by the node's clock ``now`` [s].

    ``check(core, now)`` returns the latest health of rigs silent for ``after`` [s] re-sent as
    ``stale`` (``MonitorCore.stale``), once per silence (None: never). ``forget_due(core, now)``
    returns the ids of rigs silent for ``forget_after`` [s] (None: never), for
    ``MonitorCore.forget``.

    Health is computed from samples, so a rig that stops publishing (its PC off, its cable out)
    would otherwise keep its last ``ok`` for good: on the health query and on every dashboard
    that shows the latest message. Each call compares each rig's last seq with the one it had at
    the previous call (one array comparison for the whole fleet).
    """

    def __init__(self, after: float | None, forget_after: float | None = None):
        for name, v in (("stale after", after), ("forget after", forget_after)):
            if v is not None and not v > 0:
                raise ValueError(f"{name} {v!r} s must be > 0")
        if after is not None and forget_after is not None and forget_after <= after:
            raise ValueError(f"forget after {forget_after!r} s must be longer than stale after {after!r} s")
        self.after = None if after is None else float(after)
        self.forget_after = None if forget_after is None else float(forget_after)
        self._seqs = np.empty(0, dtype=np.int64)
        self._since = np.empty(0)
        self._told = np.empty(0, dtype=np.bool_)
        self._refused = np.empty(0, dtype=np.int64)  # each row's rejected messages when it last took a sample

    def _observe(self, core: MonitorCore, now: float) -> None:
        seqs = core.last_seqs()
        new = len(seqs) - len(self._seqs)
        if new > 0:  # rigs seen since the last check: silent from now at the earliest
            self._seqs = np.concatenate([self._seqs, np.full(new, -2, dtype=np.int64)])
            self._since = np.concatenate([self._since, np.full(new, now)])
            self._told = np.concatenate([self._told, np.zeros(new, dtype=np.bool_)])
            self._refused = np.concatenate([self._refused, np.zeros(new, dtype=np.int64)])
        moved = seqs != self._seqs  # a forgotten rig's row (seq back to -1) counts as moved
        self._since[moved], self._told[moved], self._seqs = now, False, seqs
        self._refused[moved] = core._refused_n[:len(seqs)][moved]

    def check(self, core: MonitorCore, now: float) -> list[tuple[str, bytes]]:
        self._observe(core, now)
        if self.after is None:
            return []
        due = ~self._told & (now - self._since >= self.after)
        if not due.any():
            return []
        self._told |= due
        ids = core.fleet.ids
        rows = np.flatnonzero(due)
        # messages that keep coming, all rejected: not silent (a stray cut-off message is no stream)
        refused = rows[core._refused_n[rows] - self._refused[rows] >= REFUSED_STREAM]
        return core.stale([ids[r] for r in rows.tolist()], [ids[r] for r in refused.tolist()])

    def forget_due(self, core: MonitorCore, now: float) -> list[str]:
        self._observe(core, now)
        if self.forget_after is None:
            return []
        ids = core.fleet.ids
        return [ids[r] for r in np.flatnonzero(now - self._since >= self.forget_after).tolist() if ids[r]]


class BacklogWatch:
    """Says when the node falls behind its input, and when it has caught up.

    ``observe(n, now)`` takes the size of each drained batch and the node's clock ``now`` [s];
    it returns a line to log, or None. A batch drained full (``max_batch`` messages) means more
    than a batch was queued; batches full for ``after`` [s] in a row mean arrivals outpace
    processing, so every health message comes later than the one before: the node says so once
    (with the rate it takes messages at, so an operator can size shards), and once more when a
    batch is no longer full. A start-up burst (routes coming up, a queue that filled while the
    kernels loaded) drains within that time and says nothing. Without it, an overloaded
    monitor's only symptom was health arriving ever later, with nothing in its log.
    """

    def __init__(self, max_batch: int, after: float = 2.0):
        if max_batch < 1 or not after > 0:
            raise ValueError(f"max batch {max_batch!r} must be >= 1 and after {after!r} s > 0")
        self.max_batch, self.after = int(max_batch), float(after)
        self._since: float | None = None  # when the current run of full batches began
        self._taken = 0                     # messages taken in it
        self._told = False
        self.episodes = 0                   # runs of full batches reported
        self.seconds = 0.0                  # their total length [s] (the current one once it ends)

    def observe(self, n: int, now: float) -> str | None:
        if n >= self.max_batch:
            if self._since is None:
                self._since, self._taken, self._told = now, 0, False
            self._taken += n
            behind = now - self._since
            if not self._told and behind >= self.after:
                self._told = True
                self.episodes += 1
                return (f"monitor: behind its input for {behind:.1f} s: every batch drained full ({self.max_batch} "
                        f"messages) while it took {self._taken / behind:.0f} a second, so health comes later "
                        "and later; too many rigs for this process (shard them over monitors with --rigs PATTERN)")
            return None
        return self._end(now)

    def _end(self, now: float, how: str = "caught up") -> str | None:
        since, told, self._since = self._since, self._told, None
        if since is None or not told:
            return None
        self.seconds += now - since
        return f"monitor: {how} after {now - since:.1f} s behind its input"

    def close(self, now: float) -> str | None:
        """The line for a node that stops while behind (None if it is not)."""
        return self._end(now, "stopped while still behind")
