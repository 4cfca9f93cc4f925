"""Windows of MCAP recordings, and their direct replay through the monitor core.

:func:`replay_direct` feeds a recording's messages to a :class:`~hydromon.engine.core.MonitorCore`
in-process, as fast as possible. Health is a function of the message sequence only (the core
has no clock), so every direct replay of a recording gives the same health, byte for byte, and
a bus replay (``hydromon.bus.replay``) into ``hydromon monitor`` gives the same verdicts.

``keys`` are zenoh key expressions matched against topics with ``KeyExpr.intersects``
(``*`` is one chunk, ``**`` any number of chunks, ``$*`` part of a chunk), e.g.
``hydro/rig/*/sample``. ``start`` and ``duration`` [s] cut a window out of the recording,
measured in log time from its first message; a window that starts later is preceded by each
rig's last config from before it (stamped with the window's first log time), so its rigs are
graded with their recorded constants, not the defaults. A recording made by ``hydromon demo`` or
``hydromon record`` holds the monitor's verdicts too; to have a live monitor grade a
replay afresh, replay only ``<ns>/rig/*/sample``, ``.../frame`` and ``.../config`` (else the old
verdicts go out on the same keys as the new ones).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Iterator

import zenoh

from hydromon.contract import DEFAULT_NAMESPACE, SAMPLE_LEAVES, parse_rig_key, rig_key_parts
from hydromon.store.mcap_layout import rig_topic
from hydromon.store.mcap_read import read_recording, read_summary
from hydromon.store.quietgc import QuietGC

__all__ = ["KeyFilter", "recording_span", "recording_topics", "window", "read_window", "iter_window",
           "replay_direct", "health_jsonl", "NothingToReplay", "check_window", "window_problem", "sample_namespaces",
           "nothing_graded", "graded", "window_span", "ticking"]

log = logging.getLogger(__name__)


class KeyFilter:
    """``filter(key) -> bool``: does a topic match any of the key expressions?

    Parameters
    ----------
    patterns : iterable of str or None
        Zenoh key expressions; None or empty matches everything.
    """

    def __init__(self, patterns: Iterable[str] | None = None):
        self.patterns = list(patterns or [])
        self._exprs = []
        for p in self.patterns:
            try:
                self._exprs.append(zenoh.KeyExpr(p))
            except zenoh.ZError as exc:
                raise ValueError(f"--keys {p!r} is not a zenoh key expression ('*' is a whole chunk, "
                                 f"'**' any chunks, '$*' part of a chunk): {str(exc).split(' at ')[0]}") from None
        self._cache: dict[str, bool] = {}

    def __call__(self, key: str) -> bool:
        if not self._exprs:
            return True
        hit = self._cache.get(key)
        if hit is None:
            try:
                k = zenoh.KeyExpr(key)
                hit = any(e.intersects(k) for e in self._exprs)
            except zenoh.ZError:
                hit = False  # not a key expression: nothing matches it
            self._cache[key] = hit
        return hit


def recording_span(src) -> tuple[int, int, int]:
    """``(first_log_time_ns, last_log_time_ns, message_count)`` from the recording's summary."""
    st = read_summary(src).statistics
    return int(st.message_start_time), int(st.message_end_time), int(st.message_count)


def recording_topics(src) -> list[str]:
    """The topics (keys) of the recording, sorted."""
    return sorted({c.topic for c in read_summary(src).channels.values()})


def window(src, start: float | None, duration: float | None) -> tuple[int, int | None, int | None, int]:
    """``(first, lo, hi, count)``: the recording's first log time, the window [lo, hi) of ``start`` and
    ``duration`` [s] from it in log time [ns] (hi None: to the end), and the message count."""
    first, _, count = recording_span(src)
    return (first, *_bounds(first, start, duration), count)


def _bounds(first: int, start: float | None, duration: float | None) -> tuple[int, int | None]:
    """``(lo, hi)`` [ns] of the window ``start``, ``duration`` [s] from log time ``first`` [ns]."""
    for name, v in (("start", start), ("duration", duration)):
        if v is not None and not v >= 0:
            raise ValueError(f"{name} {v!r} must be >= 0 s")
    lo = first + round((start or 0.0) * 1e9)
    return lo, None if duration is None else lo + round(duration * 1e9)


def read_window(src, lo: int | None, hi: int | None, first: int) -> Iterator[tuple[str, bytes, int, int]]:
    """``read_recording`` of the window [lo, hi), preceded by each rig's last config logged
    before ``lo`` (log time: the window's first message's); nothing for an empty window."""
    carried: dict[str, tuple[bytes, int]] = {}
    if lo is not None and lo > first:
        configs = [t for t in recording_topics(src) if (rt := rig_topic(t)) is not None and rt[1] == "config"]
        if configs:
            for key, payload, _, pub_ns in read_recording(src, topics=configs, end_ns=lo):
                carried[key] = (payload, pub_ns)
    window = read_recording(src, start_ns=lo, end_ns=hi)
    head = next(window, None)
    if head is None:
        return
    for key, (payload, pub_ns) in carried.items():
        yield key, payload, head[2], pub_ns
    yield head
    yield from window


class NothingToReplay(ValueError):
    """The recording, the window or the key filter leaves nothing to replay or to grade."""


def sample_namespaces(topics: Iterable[str]) -> list[str]:
    """The namespaces ``<ns>`` of the rig sample topics ``<ns>/rig/<id>/sample`` (and ``.../frame``)
    among ``topics``."""
    return sorted({p[0] for t in topics if not isinstance(p := rig_key_parts(t, None), str) and p[0]
                   and p[2] in SAMPLE_LEAVES})


def _listed(items: list[str], n: int = 5) -> str:
    return ", ".join(items[:n]) + (f" and {len(items) - n} more" if len(items) > n else "")


def window_problem(name: str, topics: list[str], span_s: float, count: int, *, keys: Iterable[str] | None,
                   start: float | None, namespace: str | None = None) -> str | None:
    """Why the window of a recording holds nothing to replay (or, with ``namespace``, to grade); None if it may.

    ``topics`` are the recording's, ``span_s`` the log time from its first to its last message [s],
    ``count`` its messages. Pure: the checks :func:`check_window` makes on a file.
    """
    if count == 0:
        return f"{name}: the recording holds no messages"
    if start is not None and start * 1e9 > round(span_s * 1e9):
        return (f"{name}: --start {start:g} s is past the recording's end (its messages span "
                f"{span_s:.3f} s from the first)")
    match = KeyFilter(keys)
    hit = [t for t in topics if match(t)]
    if not hit:
        return (f"{name}: no topic matches --keys {' '.join(repr(k) for k in match.patterns)}; "
                f"the recording's topics: {_listed(topics)}")
    if namespace is None:
        return None
    mine = [t for t in hit if (p := parse_rig_key(t, namespace)) and p[1] in SAMPLE_LEAVES]
    if mine:
        return None
    others = sample_namespaces(hit)
    if len(others) == 1:
        return (f"{name}: recorded under namespace {others[0]}, not {namespace}; "
                f"use --namespace {others[0]}")
    if others:
        return (f"{name}: no rig samples under namespace {namespace}; the recording's are under "
                f"{_listed(others)}: choose one with --namespace")
    return (f"{name}: no rig samples (<ns>/rig/<id>/sample or .../frame) among the replayed topics "
            f"({_listed(hit)}): nothing to grade")


def check_window(src, *, keys: Iterable[str] | None = None, start: float | None = None,
                 namespace: str | None = None) -> None:
    """Raise :class:`NothingToReplay` (naming the file and why) when the window holds nothing to
    replay, or with ``namespace`` no sample of that namespace to grade. Damaged files raise as
    :func:`~hydromon.store.mcap_read.read_summary` does."""
    summary = read_summary(src)
    st = summary.statistics
    name = os.fspath(src) if isinstance(src, (str, os.PathLike)) else getattr(src, "name", "<stream>")
    topics = sorted({c.topic for c in summary.channels.values()})
    span_s = (int(st.message_end_time) - int(st.message_start_time)) / 1e9
    why = window_problem(name, topics, span_s, int(st.message_count), keys=keys, start=start, namespace=namespace)
    if why:
        raise NothingToReplay(why)


def nothing_graded(name: str, health: list, counters) -> str | None:
    """Why a direct replay graded nothing (no health message), from the core's counters; None if it did."""
    if health:
        return None
    rejected = {k: v for k, v in counters.rejected.items() if v}
    if counters.accepted == 0 and rejected:
        return (f"{name}: no sample was accepted (rejected: "
                f"{', '.join(f'{k} {v}' for k, v in sorted(rejected.items()))}): nothing graded")
    if counters.accepted == 0:
        return f"{name}: no sample in the window (--start, --duration, --keys): nothing graded"
    return (f"{name}: {counters.accepted} samples accepted but no health message: too few samples "
            "for a verdict (the monitor grades every 10th sample of a rig)")


def iter_window(src, *, keys: Iterable[str] | None = None, start: float | None = None,
                duration: float | None = None) -> Iterator[tuple[str, bytes, int]]:
    """Messages ``(key, payload, log_time_ns)`` of the window, in log-time order."""
    match = KeyFilter(keys)
    first, lo, hi, count = window(src, start, duration)
    if count == 0:
        return
    for key, payload, log_ns, _ in read_window(src, lo, hi, first):
        if match(key):
            yield key, payload, log_ns


def replay_direct(src, *, keys: Iterable[str] | None = None, start: float | None = None,
                  duration: float | None = None, namespace: str = DEFAULT_NAMESPACE, core=None,
                  batch: int = 1000, batch_bytes: int = 256 * 1024,
                  progress: Callable[[float, float], None] | None = None):
    """Run a MonitorCore over the recording as fast as possible.

    Messages go to the core in batches of at most ``batch`` messages and about ``batch_bytes``
    bytes of payload (a frame holds many samples: the byte budget keeps a batch's samples about
    even either way; measured at 10 rigs, 60 s of frames of 10: 352,000 samples/s in batches of
    500 frames, 232,000 in batches of 10,000, the rigs' configs and first frames then sharing
    a batch with all the others and taking the per-message path). Garbage is collected between
    batches (``hydromon.store.quietgc``). Returns ``(health, core)``: the health messages
    ``[(key, payload bytes)]`` in order, and the core (counters, latest health per rig).
    ``progress(done_s, total_s)``, if given, is called now and then with the recording seconds
    read of the window's. ``hydromon.store.replay_jobs`` splits the rigs between processes.
    """
    from hydromon.engine.core import MonitorCore

    core = core or MonitorCore(namespace)
    messages = iter_window(src, keys=keys, start=start, duration=duration)
    if progress is not None:
        messages = ticking(messages, *window_span(src, start, duration), progress)
    health = graded(core, enumerate((key, payload) for key, payload, _ in messages), batch, batch_bytes)
    return [(key, payload) for _, key, payload in health], core


def window_span(src, start: float | None, duration: float | None) -> tuple[int, float]:
    """``(lo, total_s)``: the window's first log time [ns] and its length [s] (for progress)."""
    first, last, _ = recording_span(src)
    lo, hi = _bounds(first, start, duration)
    end = last if hi is None else min(last, hi)
    return lo, max(end - lo, 0) / 1e9


def ticking(messages: Iterable[tuple[str, bytes, int]], lo: int, total_s: float,
            progress: Callable[[float, float], None], every: int = 2000) -> Iterator[tuple[str, bytes, int]]:
    """``messages`` ``(key, payload, log_ns)`` as they come, calling ``progress(done_s, total_s)``
    every ``every`` messages and at the end (``done_s`` from ``lo`` [ns], at most ``total_s``)."""
    n = 0
    for m in messages:
        yield m
        n += 1
        if n % every == 0:
            progress(min(max(m[2] - lo, 0) / 1e9, total_s), total_s)
    progress(total_s, total_s)


def graded(core, messages: Iterable[tuple[int, tuple[str, bytes]]], batch: int = 1000,
           batch_bytes: int = 256 * 1024) -> list[tuple[int, str, bytes]]:
    """The health of ``messages`` ``(index, (key, payload))`` through ``core``, in batches (see
    :func:`replay_direct`): ``(index of the message that ended the window, key, payload)`` in order."""
    health: list[tuple[int, str, bytes]] = []
    buf: list[tuple[str, bytes]] = []
    index: list[int] = []
    size = 0
    with QuietGC(collect_first=False) as quiet:
        for g, message in messages:
            buf.append(message)
            index.append(g)
            size += len(message[1])
            if len(buf) >= batch or size >= batch_bytes:
                health += [(index[i], key, payload) for i, key, payload in core.process_indexed(buf)]
                buf, index, size = [], [], 0
                quiet.idle()
        health += [(index[i], key, payload) for i, key, payload in core.process_indexed(buf)]
    return health


def health_jsonl(health: Iterable[tuple[str, bytes]]) -> Iterator[bytes]:
    """JSON lines ``{"key": ..., "health": {...}}`` of health messages (payload bytes kept)."""
    for key, payload in health:
        yield b'{"key":"' + key.encode() + b'","health":' + payload + b"}\n"


