"""The simulator node: a fleet of simulated rigs publishing on the bus.

Each rig publishes contract ``Sample`` JSON on ``<ns>/rig/<id>/sample`` (seq from 0,
t = seq h on the rig's clock), or with ``frame`` N a contract ``Frame`` of N consecutive
samples on ``<ns>/rig/<id>/frame`` once every N samples (sent when its last sample is due; each
rig's frames end at its own phase, ``hydromon.bus.framer``),
and its ``RigConfig`` on ``<ns>/rig/<id>/config`` once at the start and again whenever it
changes; a queryable on ``<ns>/rig/*/config`` answers late joiners with the current configs
(``session.get``).

Pacing is drift-free: sample k goes out at ``t0 + k h / rate`` (:func:`sample_deadline`),
a deadline computed from k, never by adding up sleeps; a late sample is sent at once and
the next deadlines stay where they were. ``rate`` > 1 runs faster than real time,
``rate`` = 0 as fast as possible. All rigs step together in blocks of ``block`` samples;
a worker thread computes the next block (the numba kernel releases the GIL) while this
one publishes the current block in deadline order.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Sequence

import orjson
import zenoh

from hydromon.bus.session import JSON
from hydromon.contract import DEFAULT_NAMESPACE, FRAME_MAX, check_namespace, config_key, frame_key, sample_key
from hydromon.bus.framer import Framer
from hydromon.engine.samples import sample_payload
from hydromon.store.fleetfile import FleetSpec, RigSpec
from hydromon.store.quietgc import QuietGC
from plant_sim.live import PlantFleet

__all__ = ["sample_deadline", "wait_time", "SimStats", "SimNode", "run_sim", "DEFAULT_BLOCK"]

DEFAULT_BLOCK = 10
"""Samples per rig computed per step (10 = 0.1 s at 100 Hz)."""


def sample_deadline(t0: float, k: int, h: float, rate: float) -> float:
    """Clock time [s] at which sample k is due: ``t0 + k h / rate`` (``t0`` when rate = 0).

    Computed from k alone, so errors never accumulate however long the run.
    """
    if rate < 0:
        raise ValueError(f"rate {rate!r} must be >= 0")
    if rate == 0:
        return t0
    return t0 + k * h / rate


def wait_time(now: float, t0: float, k: int, h: float, rate: float) -> float:
    """Seconds to wait at clock time ``now`` before sending sample k (0 if it is due or late)."""
    return max(0.0, sample_deadline(t0, k, h, rate) - now)


@dataclass
class SimStats:
    """What a run did: samples per rig, messages put, lateness of the sends [s], wall time [s]."""

    samples: int = 0
    published: int = 0
    configs_published: int = 0
    max_late: float = 0.0
    wall: float = 0.0


class SimNode:
    """Publishes a ``PlantFleet`` of rigs ``ids`` on an open session.

    Parameters
    ----------
    session : zenoh.Session
        An open session (the caller owns and closes it).
    ids : list of str
        Rig ids, one per rig of ``fleet``.
    fleet : PlantFleet
        The simulated rigs (fresh, or continuing: seq follows ``fleet.k``).
    namespace : str
        Key prefix.
    rate : float
        Speed relative to real time (0 = as fast as possible).
    block : int
        Samples per rig per step.
    congestion : zenoh.CongestionControl
        For the sample publishers; BLOCK (default) never drops: a slow network slows the
        simulation (the lateness shows in the stats) instead of losing samples.
    publish_u : sequence of bool, optional
        Per rig: publish its valve drive ``u`` [V] in every sample (default: none does).
    frame : int or None
        Publish frames of this many samples (1..FRAME_MAX) instead of one message per sample,
        each rig's ending at its own phase (``hydromon.bus.framer``).
    """

    def __init__(self, session: zenoh.Session, ids: Sequence[str], fleet: PlantFleet, *,
                 namespace: str = DEFAULT_NAMESPACE, rate: float = 1.0, block: int = DEFAULT_BLOCK,
                 congestion: zenoh.CongestionControl = zenoh.CongestionControl.BLOCK,
                 publish_u: Sequence[bool] | None = None, frame: int | None = None):
        if len(ids) != fleet.n_rigs:
            raise ValueError(f"{len(ids)} ids for {fleet.n_rigs} rigs")
        if len(set(ids)) != len(ids):
            raise ValueError("rig ids must be unique")
        if not rate >= 0:
            raise ValueError(f"rate {rate!r} must be >= 0")
        if block < 1:
            raise ValueError(f"block {block!r} must be >= 1")
        if frame is not None and not 1 <= frame <= FRAME_MAX:
            raise ValueError(f"frame {frame!r} must be 1..{FRAME_MAX} samples")
        self.frame = frame
        self.session, self.ids, self.fleet = session, list(ids), fleet
        self.ns, self.rate, self.block = check_namespace(namespace), float(rate), int(block)
        key_of = sample_key if frame is None else frame_key
        self._sample_keys = [key_of(i, namespace) for i in self.ids]  # validates the ids
        self._config_keys = [config_key(i, namespace) for i in self.ids]
        self._congestion = congestion
        self._with_u = frozenset(i for i, on in enumerate(publish_u or ()) if on)
        if publish_u is not None and len(publish_u) != fleet.n_rigs:
            raise ValueError(f"publish_u: {len(publish_u)} given for {fleet.n_rigs} rigs")
        self._changes: queue.SimpleQueue = queue.SimpleQueue()
        self._config_payloads: dict[str, bytes] = {}

    def change_rig(self, rig_id: str, **changes) -> None:
        """Ask for ``PlantFleet.set_rig`` changes (config, params, effects, profile) on a rig.

        Thread-safe; applied before the next block is computed, so from a block boundary on.
        """
        if rig_id not in self.ids:
            raise ValueError(f"no rig {rig_id!r} in this node")
        self._changes.put((self.ids.index(rig_id), changes))

    def _step(self, k: int):
        changed = set()
        while True:
            try:
                i, changes = self._changes.get_nowait()
            except queue.Empty:
                break
            before = int(self.fleet.config_rev[i])
            self.fleet.set_rig(i, **changes)
            if self.fleet.config_rev[i] != before:
                changed.add(i)
        return changed, self.fleet.step(k)

    def _answer_config_query(self, query: zenoh.Query) -> None:
        qk = query.key_expr
        for key, payload in list(self._config_payloads.items()):
            if qk.intersects(zenoh.KeyExpr(key)):
                query.reply(key, payload, encoding=JSON)

    def run(self, duration: float | None = None, stop_event: threading.Event | None = None,
            clock=time.monotonic) -> SimStats:
        """Publish until ``duration`` [s of rig time] is done or ``stop_event`` is set."""
        fleet, h = self.fleet, self.fleet.h
        if duration is not None and not (math.isfinite(duration) and duration > 0):
            raise ValueError(f"duration {duration!r} must be a finite number > 0 s")
        total = None if duration is None else int(round(duration / h))
        stop = stop_event or threading.Event()
        stats = SimStats()
        sample_pubs = [self.session.declare_publisher(k, encoding=JSON, congestion_control=self._congestion)
                       for k in self._sample_keys]
        config_pubs = [self.session.declare_publisher(k, encoding=JSON,
                                                      congestion_control=zenoh.CongestionControl.BLOCK)
                       for k in self._config_keys]
        queryable = self.session.declare_queryable(f"{self.ns}/rig/*/config", self._answer_config_query)
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plant-step")
        framer = None if self.frame is None else Framer(self.ids, self.frame, self._with_u)
        k_first = fleet.k
        t_start = clock()
        done = 0  # samples per rig computed so far

        def submit():
            nonlocal done
            k = self.block if total is None else min(self.block, total - done)
            if k <= 0:
                return None
            done += k
            return pool.submit(self._step, k)

        def publish_config(i: int) -> None:
            payload = orjson.dumps(fleet.configs[i].model_dump(mode="json"))
            self._config_payloads[self._config_keys[i]] = payload
            config_pubs[i].put(payload)
            stats.configs_published += 1

        quiet = QuietGC()
        quiet.__enter__()  # left in the finally below (the loop's own try)
        try:
            for i in range(fleet.n_rigs):
                publish_config(i)
            future = submit()
            first = True
            while future is not None and not stop.is_set():
                changed, blk = future.result()
                if first:  # the clock starts once the first block is ready
                    t_start, first = clock(), False
                for i in sorted(changed):  # read before the worker may change the fleet again
                    publish_config(i)
                future = submit()
                if framer is not None:
                    framer.block(blk)
                for j, (seq, t) in enumerate(zip(blk.seq.tolist(), blk.t.tolist())):
                    if self.rate > 0:
                        wait = wait_time(clock(), t_start, seq - k_first, h, self.rate)
                        if wait > 0.002:  # slack before this tick's deadline: collect garbage now
                            quiet.idle()
                            wait = wait_time(clock(), t_start, seq - k_first, h, self.rate)
                        if wait > 0 and stop.wait(wait):
                            break
                    else:
                        quiet.idle()
                        late = clock() - sample_deadline(t_start, seq - k_first, h, self.rate)
                        stats.max_late = max(stats.max_late, late)
                    stats.samples += 1
                    if framer is not None:  # the frames that end with this tick's samples
                        for i, payload in framer.due(j):
                            sample_pubs[i].put(payload)
                            stats.published += 1
                        continue
                    # one tick's rows at a time: converting the whole block at its start held
                    # the first tick back by ~10 ms at 500 rigs
                    if self._with_u:
                        rows, us = blk.samples[:, j].tolist(), blk.u[:, j].tolist()
                        for i, (pub, row) in enumerate(zip(sample_pubs, rows)):
                            pub.put(sample_payload(seq, t, row, us[i] if i in self._with_u else None))
                    else:
                        for pub, row in zip(sample_pubs, blk.samples[:, j].tolist()):
                            pub.put(sample_payload(seq, t, row))
                    stats.published += len(sample_pubs)
            if future is not None:
                future.cancel()
            elif framer is not None:  # the run is done: the samples since each rig's last frame
                for i, payload in framer.rest():
                    sample_pubs[i].put(payload)
                    stats.published += 1
        finally:
            quiet.__exit__()
            pool.shutdown(wait=True)
            stats.wall = clock() - t_start
            queryable.undeclare()
            for p in sample_pubs + config_pubs:
                p.undeclare()
        return stats


def run_sim(session: zenoh.Session, rigs: FleetSpec | Sequence[RigSpec], *, namespace: str = DEFAULT_NAMESPACE,
            rate: float = 1.0, duration: float | None = None, stop_event: threading.Event | None = None,
            block: int = DEFAULT_BLOCK, frame: int | None = None) -> SimStats:
    """Simulate ``rigs`` and publish them on ``session`` (see :class:`SimNode`).

    Parameters
    ----------
    rigs : FleetSpec or list of RigSpec
        The rigs (a bare list uses the default RigConfig and fleet seed 0).
    rate : float
        Speed relative to real time; 0 = as fast as possible.
    duration : float, optional
        Rig time to simulate [s]; None = until ``stop_event`` is set.
    block : int
        Samples per rig computed per step.
    frame : int or None
        Publish frames of this many samples (``<ns>/rig/<id>/frame``) instead of samples.
    """
    spec = rigs if isinstance(rigs, FleetSpec) else FleetSpec(rigs=list(rigs))
    node = SimNode(session, spec.ids, spec.build(), namespace=namespace, rate=rate, block=block,
                   publish_u=[r.publishes_u for r in spec.rigs], frame=frame)
    return node.run(duration=duration, stop_event=stop_event)
