"""A direct replay over several processes: the recording's rigs split between them.

Rigs are independent in the monitor core (a rig's health depends on its own messages only), so
:func:`replay_direct_jobs` gives each of ``jobs`` forked workers every ``jobs``-th rig id of the
recording (sorted), lets each read the whole window and grade its own rigs' messages (a message
that names no rig goes to the first), and merges their health by the index of the message that
ended each window. The result is the single-process :func:`hydromon.store.replay.replay_direct`'s,
byte for byte and in the same order (a test), with the counters summed.

Workers are forked (they inherit the loaded kernels: nothing is compiled or imported again), so
this needs the ``fork`` start method (Linux); elsewhere, and when one job would do, it runs in
this process. A recording with more rig ids than the core admits (``max_rigs``) runs in one
process too: which rigs are admitted then depends on all of them.
"""

from __future__ import annotations

import heapq
import io
import multiprocessing
import multiprocessing.connection
import os
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from operator import itemgetter

from hydromon.contract import DEFAULT_NAMESPACE
from hydromon.engine.counters import MonitorCounters
from hydromon.store.mcap_layout import rig_topic
from hydromon.store.replay import graded, iter_window, recording_topics, replay_direct, ticking, window_span

__all__ = ["ReplayResult", "replay_direct_jobs", "shard_rigs"]


@dataclass
class ReplayResult:
    """What the workers' cores did, together: ``counters`` summed, ``rigs`` the rig ids they
    admitted, ``latest`` each rig's latest health payload."""

    counters: MonitorCounters = field(default_factory=MonitorCounters)
    rigs: set[str] = field(default_factory=set)
    latest: dict[str, bytes] = field(default_factory=dict)

    def add(self, counters: MonitorCounters, rigs: Iterable[str], latest: dict[str, bytes]) -> None:
        c = self.counters
        for name, value in vars(counters).items():
            if name == "rejected":
                for reason, n in value.items():
                    c.rejected[reason] = c.rejected.get(reason, 0) + n
            else:
                setattr(c, name, getattr(c, name) + value)
        self.rigs.update(rigs)
        self.latest.update(latest)


def shard_rigs(rig_ids: Iterable[str], jobs: int) -> dict[str, int]:
    """Worker of each rig id: the sorted ids dealt round-robin to ``jobs`` workers."""
    return {rig: k % jobs for k, rig in enumerate(sorted(set(rig_ids)))}


def _owner(shards: dict[str, int]) -> Callable[[str], int]:
    """The worker of a message key (its rig's, under any namespace; 0 for a key of no rig),
    remembered per key (a recording has few distinct keys)."""
    seen: dict[str, int] = {}

    def owner(key: str) -> int:
        k = seen.get(key)
        if k is None:
            parsed = rig_topic(key)
            k = seen[key] = 0 if parsed is None else shards.get(parsed[0], 0)
        return k

    return owner


def _for_workers(src):
    """What each worker can read on its own: a path, an in-memory stream (each forked worker has
    its copy), or an open file's path (forked workers would share its offset); None otherwise."""
    if isinstance(src, (str, os.PathLike, io.BytesIO)):
        return src
    name = getattr(src, "name", None)
    return name if isinstance(name, (str, os.PathLike)) and os.path.isfile(name) else None


def _work(k: int, shards: dict, src, window: dict, span: tuple[int, float], make_core, conn, done) -> None:
    """Worker ``k``: grade its rigs' messages; send ``("ok", health, counters, rigs, latest)``;
    the recording seconds it has read of the window's ``span`` (``window_span``) go into ``done[k]``."""
    try:
        core = make_core()
        owner = _owner(shards)

        def progress(done_s, _total_s):
            done[k] = done_s

        messages = ticking(iter_window(src, **window), *span, progress)
        mine = ((g, (key, payload)) for g, (key, payload, _) in enumerate(messages) if owner(key) == k)
        health = graded(core, mine)
        conn.send(("ok", health, core.counters, list(core.rigs), dict(core.latest)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises
        conn.send(("error", f"{type(exc).__name__}: {exc}", traceback.format_exc()))
    finally:
        conn.close()


def replay_direct_jobs(src, *, jobs: int, keys: Iterable[str] | None = None, start: float | None = None,
                       duration: float | None = None, namespace: str = DEFAULT_NAMESPACE,
                       make_core: Callable | None = None, progress: Callable[[float, float], None] | None = None):
    """:func:`~hydromon.store.replay.replay_direct` of ``src`` (a path, an in-memory stream, or an
    open file with a path; any other stream runs in this process) over ``jobs`` processes.
    ``make_core()`` makes each worker's MonitorCore (the same way for all); ``progress(done_s,
    total_s)`` as in ``replay_direct``, of the slowest worker. Returns ``(health, result)``: the
    health ``[(key, payload)]`` in order, and a :class:`ReplayResult` (or, run in this process,
    the core). Raises RuntimeError when a worker fails or dies."""
    from hydromon.engine.core import MonitorCore

    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs {jobs!r} must be an integer >= 1")
    make_core = make_core or (lambda: MonitorCore(namespace))
    window = dict(keys=keys, start=start, duration=duration)
    rigs = {parsed[0] for t in recording_topics(src) if (parsed := rig_topic(t)) is not None}
    jobs = min(jobs, len(rigs))
    shared = _for_workers(src)
    if jobs <= 1 or shared is None or "fork" not in multiprocessing.get_all_start_methods():
        return replay_direct(src, **window, namespace=namespace, core=make_core(), progress=progress)
    src = shared
    first = make_core()
    if len(rigs) > first.max_rigs:
        return replay_direct(src, **window, namespace=namespace, core=first, progress=progress)
    shards = shard_rigs(rigs, jobs)
    ctx = multiprocessing.get_context("fork")
    done = ctx.Array("d", jobs, lock=False)  # recording seconds each worker has read
    span = window_span(src, start, duration)
    procs, conns = [], []
    for k in range(jobs):
        parent, child = ctx.Pipe(duplex=False)
        p = ctx.Process(target=_work, args=(k, shards, src, window, span, make_core, child, done), daemon=True)
        p.start()
        child.close()
        procs.append(p)
        conns.append(parent)
    results: dict[int, tuple] = {}
    try:
        while len(results) < jobs:
            ready = multiprocessing.connection.wait([c for k, c in enumerate(conns) if k not in results], 0.2)
            if progress is not None:
                progress(min(done[:]), span[1])
            for conn in ready:
                k = conns.index(conn)
                try:
                    got = conn.recv()
                except EOFError:
                    procs[k].join()
                    raise RuntimeError(f"replay worker {k + 1} of {jobs} died (exit status {procs[k].exitcode})") \
                        from None
                if got[0] != "ok":
                    raise RuntimeError(f"replay worker {k + 1} of {jobs} failed: {got[1]}\n{got[2]}")
                results[k] = got[1:]
    finally:
        for p in procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join()
    out = ReplayResult()
    for k in range(jobs):
        out.add(*results[k][1:])
    merged = heapq.merge(*(results[k][0] for k in range(jobs)), key=itemgetter(0))
    return [(key, payload) for _, key, payload in merged], out
