"""The monitor node: the zenoh shell around :class:`hydromon.engine.core.MonitorCore`.

The core takes raw ``(key, payload bytes)`` messages in arrival order and returns the
``(health key, health payload)`` pairs to publish; it has no clock, no threads and no I/O, so
the live node, ``hydromon replay`` over the bus and ``hydromon replay --direct`` all give the
same health for the same message sequence. :func:`run_monitor` is the node: subscribers with
FIFO channel handlers (zenoh forbids blocking or calling its API inside callbacks), a loop that
drains everything queued into one batch (``try_recv`` until empty; the 1.x handlers have no
``recv`` with a timeout, so an empty channel waits ``poll_s`` on the stop event), health
published with ``session.put``, each rig's sample and health keys declared on the session so
zenoh routes them from a cache (``hydromon.bus.rig_keys``), a liveliness token ``<ns>/monitor/<node>``
and a queryable on ``<ns>/rig/*/health`` that answers with each rig's latest health.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Callable

import zenoh

from hydromon.bus.checkpoints import Saver, restore_from
from hydromon.bus.failover import Failover
from hydromon.bus.live_commission import LiveCommissioning
from hydromon.store.quietgc import QuietGC
from hydromon.bus.rig_keys import RigKeys
from hydromon.bus.session import JSON
from hydromon.contract import DEFAULT_NAMESPACE, check_namespace, health_key, liveliness_key, ranges_key
from hydromon.engine.core import MonitorCore
from hydromon.engine.validate import PAYLOAD_MAX
from hydromon.engine.watches import BacklogWatch, RateLimitedLog, RigWarningLog, SilenceWatch
from hydromon.store.ranges_dir import RangesDir
from hydromon.store.state_dir import StateDir
from hydromon.engine.warm import warm_up

__all__ = ["rig_pattern", "run_monitor"]

log = logging.getLogger(__name__)


_RIG_PATTERN_RE = re.compile(r"\*|\$\*|[A-Za-z0-9_$*-]{1,64}")


def rig_pattern(pattern: str) -> str:
    """Validate a rig-id key-expression chunk (``*``, ``line1-*``, ``a$*b``) for sharding."""
    if not isinstance(pattern, str) or not _RIG_PATTERN_RE.fullmatch(pattern) or "**" in pattern:
        raise ValueError(f"rig pattern {pattern!r}: one key-expression chunk of [A-Za-z0-9_-], '*' or '$*'")
    if pattern != "*" and "*" in pattern:
        pattern = re.sub(r"(?<!\$)\*", "$*", pattern)  # inside a chunk zenoh spells the wildcard $*
    try:
        zenoh.KeyExpr(f"x/{pattern}")
    except Exception as exc:  # zenoh's own verdict on the expression
        raise ValueError(f"rig pattern {pattern!r}: {exc}") from None
    return pattern


def run_monitor(session: zenoh.Session, *, namespace: str = DEFAULT_NAMESPACE, node_name: str = "monitor",
                stop_event: threading.Event | None = None, duration: float | None = None,
                core: MonitorCore | None = None, capacity: int = 65536, max_batch: int = 3000,
                poll_s: float = 0.005, on_health: Callable[[str, bytes], None] | None = None,
                congestion: zenoh.CongestionControl = zenoh.CongestionControl.BLOCK,
                config_query_s: float = 5.0, clock=time.monotonic, rigs: str = "*",
                stale_after_s: float | None = 2.0, forget_after_s: float | None = None,
                behind_after_s: float = 2.0, ranges_dir: RangesDir | None = None,
                ranges_scan_s: float = 2.0, state_dir: StateDir | None = None, checkpoint_s: float = 2.0,
                group: str | None = None, standby: bool = False, commission_new_s: float | None = None,
                commission_runs: int = 60) -> MonitorCore:
    """Run the monitor node on an open session until ``stop_event`` is set or ``duration`` [s].

    Parameters
    ----------
    session : zenoh.Session
        An open session (not closed here).
    node_name : str
        Name of the liveliness token ``<ns>/monitor/<node_name>``.
    core : MonitorCore or None
        The core to run (default: a fresh one with a rate-limited rejection log and rig warnings logged).
    capacity : int
        Messages each FIFO channel holds before zenoh back-pressures the transport.
    max_batch : int
        Most messages drained into one batch. A monitor behind (its start, with every rig's first
        messages at once) catches up in batches of this many; their health goes out batch by
        batch. Measured at 1500 rigs sending frames of 10 (three 30 s ``live_step`` runs each,
        load 1-1.5, near this machine's limit): with 3000 the start's lateness ended 3-4 s after
        the first verdict in all three (two had late bursts later), with 20,000 after 12 s, 13 s
        and more than 17 s.
    poll_s : float
        Wait after each drained batch [s]: arrivals accumulate into the next batch (adds at
        most this much latency; saves the fixed cost of many tiny batches).
    on_health : callable or None
        Called with ``(key, payload)`` of each health message after it is published.
    rigs : str
        Which rigs this monitor grades: one key-expression chunk matched against the rig id
        (``*`` all, ``line1-*`` a prefix, ``$*`` wildcards inside a chunk). Several monitors with
        disjoint patterns shard a plant: each rig's state lives in exactly one of them.
    config_query_s : float
        At start, the monitor queries ``<ns>/rig/*/config`` for the configs of rigs that
        are already running; replies count as config messages for this long [s].

    stale_after_s : float or None
        A rig that has sent no sample for this long [s] has its latest health re-sent with
        status ``stale`` (:class:`SilenceWatch`; None: never).
    forget_after_s : float or None
        A rig that has sent no sample for this long [s] is forgotten (``MonitorCore.forget``:
        its estimates, latest health and row go; it starts afresh if it comes back), and logged.
        None: never.
    behind_after_s : float
        Batches drained full for this long [s] are logged as the node falling behind its
        input, and the catch-up after (:class:`BacklogWatch`).
    ranges_dir : RangesDir or None
        A directory of per-rig ranges files (``<rig-id>.json``), scanned every ``ranges_scan_s``
        [s]: a new or changed file grades its rig from then on (logged); a bad one is refused
        (logged) and the rig keeps the ranges it had; a removed one leaves the rig to the
        default ranges, if they were made for it.
    state_dir : StateDir or None
        Where the node keeps its checkpoint (``hydromon.engine.checkpoint``): restored at start
        (before the first sample; a checkpoint it cannot use is refused whole, logged), written
        every ``checkpoint_s`` [s] while the node publishes (in a background thread; the state
        is copied between two batches) and at stop.
    group, standby : str or None, bool
        Join failover group ``group`` (``hydromon.bus.failover``): the node takes and grades
        every sample but publishes health and events, answers health queries and writes
        checkpoints only while it holds the group's oldest claim; ``standby`` starts it
        waiting for a primary. None: the node always publishes.
    commission_new_s : float or None
        Commission a rig the node has no ranges for from its first this many seconds
        (``hydromon.bus.live_commission``, with ``commission_runs`` twin runs) and write its
        ranges into ``ranges_dir``; its health says ``commissioning`` meanwhile. None: never.

    Returns the core (its ``counters``, ``latest`` health per rig).
    """
    check_namespace(namespace)
    core = core or MonitorCore(namespace, on_reject=RateLimitedLog(), on_warning=RigWarningLog())
    if core.namespace != namespace:
        raise ValueError(f"core namespace {core.namespace!r} != {namespace!r}")
    if state_dir is not None:
        restore_from(core, state_dir)
    warm_up()  # compile before subscribing: the first samples must not queue behind the compiler
    if group is not None and any(r.ok is not None for r in session.liveliness().get(
            liveliness_key(node_name, namespace), timeout=1.0)):
        # two nodes under one name share one token: one of them dying would go unseen
        raise ValueError(f"a monitor named {node_name!r} is already running on {namespace}: give each monitor "
                         "its own --node")
    stop = stop_event if stop_event is not None else threading.Event()
    deadline = None if duration is None else clock() + duration
    watch = None if stale_after_s is None and forget_after_s is None else SilenceWatch(stale_after_s, forget_after_s)
    watch_every = 0.25 if stale_after_s is None else min(0.25, stale_after_s / 4)
    backlog = BacklogWatch(max_batch, behind_after_s)  # checks its arguments before anything is declared
    flushes = [f for f in (getattr(core.on_reject, "flush", None), getattr(core.on_warning, "flush", None))
               if f is not None]  # a RateLimitedLog's and a RigWarningLog's due counts

    failover: Failover | None = None
    if commission_new_s is not None and ranges_dir is None:
        raise ValueError("commissioning new rigs writes their ranges into the ranges directory: give one")
    live = None
    saver = Saver(state_dir) if state_dir is not None else None

    def publishing() -> bool:
        return failover is None or failover.active

    def answer(query: zenoh.Query) -> None:
        if not publishing():  # a standby's verdicts are not the rigs' verdicts
            return
        qk = query.key_expr
        for rig_id, payload in list(core.latest.items()):
            key = health_key(rig_id, namespace)
            if qk.intersects(zenoh.KeyExpr(key)):
                query.reply(key, payload, encoding=JSON)

    def answer_ranges(query: zenoh.Query) -> None:
        qk = query.key_expr
        for rig_id in list(core.rigs):
            key = ranges_key(rig_id, namespace)
            if qk.intersects(zenoh.KeyExpr(key)):
                ranges, _ = core.ranges_of(rig_id)
                if ranges is not None:
                    query.reply(key, ranges.model_dump_json(exclude_none=True), encoding=JSON)

    def rescan_ranges() -> None:
        for ch in ranges_dir.scan():
            if ch.error is not None:
                log.error("ranges for rig %s refused, the rig keeps the ranges it had: %s", ch.rig_id or "?", ch.error)
            elif ch.removed:
                core.verdicts.book.remove(ch.rig_id)
                core.ranges_changed(ch.rig_id)
                log.warning("rig %s: its ranges file %s is gone; the default ranges grade it if they were made "
                            "for it", ch.rig_id, ch.path)
            else:
                core.verdicts.book.set(ch.rig_id, ch.ranges, ch.tag)
                core.ranges_changed(ch.rig_id)
                log.warning("rig %s: graded on %s from now on", ch.rig_id, ch.path)

    keys = RigKeys(session, namespace)
    if commission_new_s is not None:
        live = LiveCommissioning(ranges_dir, commission_new_s, commission_runs, on_written=rescan_ranges)

    def publish(items) -> None:
        # session.put, not a declared publisher per rig: declared publishers add resources to the
        # session's routing tables without their routes being cached for the samples (measured:
        # 300 health publishers put the receive thread at 99 % of a core for 30k samples/s;
        # without them, 12 %). The keys declared by RigKeys are cached both ways.
        put, declared = session.put, keys.health
        for key, payload in items:
            put(declared.get(key, key), payload, encoding=JSON, congestion_control=congestion)
            if on_health is not None:
                on_health(key, payload)

    def publish_events() -> None:
        put, declared = session.put, keys.events
        for key, payload in core.take_events():
            put(declared.get(key, key), payload, encoding=JSON, congestion_control=zenoh.CongestionControl.BLOCK)

    if group is not None:  # its role first: the probe waits up to a second, with no samples queueing meanwhile
        failover = Failover(session, namespace, group, node_name, standby=standby)
        log.warning("monitor %s: %s", node_name, failover.poll() or
                    f"monitor {failover.holder()} publishes for these rigs: standing by (taking every sample)")
    rig_chunk = rig_pattern(rigs)
    sub_c = session.declare_subscriber(f"{namespace}/rig/{rig_chunk}/config", zenoh.handlers.FifoChannel(capacity))
    sub_s = session.declare_subscriber(f"{namespace}/rig/{rig_chunk}/sample", zenoh.handlers.FifoChannel(capacity))
    sub_f = session.declare_subscriber(f"{namespace}/rig/{rig_chunk}/frame", zenoh.handlers.FifoChannel(capacity))
    queryable = session.declare_queryable(f"{namespace}/rig/*/health", answer)
    ranges_queryable = session.declare_queryable(f"{namespace}/rig/*/ranges", answer_ranges)
    if ranges_dir is not None:
        rescan_ranges()  # before the first sample: a rig is graded on its own ranges from its start
    # last: a peer that sees the token has seen the subscribers declared before it
    token = session.liveliness().declare_token(liveliness_key(node_name, namespace))

    # rigs that published their config before we came up: ask their nodes (the sim node
    # answers on <ns>/rig/*/config); replies are handled as config messages
    replies = session.get(f"{namespace}/rig/{rig_chunk}/config", zenoh.handlers.FifoChannel(4096),
                          timeout=config_query_s)
    replies_until = clock() + config_query_s + 1.0

    def take(batch: list) -> None:
        out = core.process(batch)
        keys.sync(core)
        if live is not None and len(core.rigs) > live.seen:
            live.check(core)  # a new rig's first verdict already says commissioning
        if publishing():
            publish(out)
            publish_events()
        else:
            core.take_events()  # a standby's: its grade changes are announced by the publishing node

    def drain() -> int:
        nonlocal replies
        batch, n = [], 0
        if replies is not None:
            try:
                while (r := replies.try_recv()) is not None:
                    if r.ok is not None:
                        batch.append((str(r.ok.key_expr), r.ok.payload.to_bytes()))
            except zenoh.ZError:  # the query is over (zenoh closes the reply channel)
                replies = None
            if clock() > replies_until:
                replies = None
        # configs first: a config queued with samples applies to them
        for sub in (sub_c, sub_s, sub_f):  # frames last: many samples each
            while n + len(batch) < max_batch and (m := sub.try_recv()) is not None:
                p = m.payload
                if len(p) > PAYLOAD_MAX:
                    # too large to be one of ours: counted unread (copying megabytes of garbage would
                    # hold up every rig), in its place among the messages before and after it
                    if batch:
                        take(batch)
                        n, batch = n + len(batch), []
                    core.refuse_unread(str(m.key_expr), len(p))
                    n += 1
                else:
                    batch.append((str(m.key_expr), p.to_bytes()))
        if batch:
            take(batch)
        return n + len(batch)

    def tell(line: str | None) -> None:
        if line is not None:
            log.warning(line)

    quiet = QuietGC()
    quiet.__enter__()  # left in the finally below
    next_watch = clock()
    next_scan = clock() + ranges_scan_s
    next_save = clock() + checkpoint_s
    try:
        while True:
            started = time.perf_counter()
            n = drain()
            tell(backlog.observe(n, clock()))
            if clock() >= next_watch:
                now = clock()
                if watch is not None:
                    stale = watch.check(core, now)
                    if publishing():
                        publish(stale)
                        publish_events()
                    else:
                        core.take_events()
                    forgotten = core.forget(watch.forget_due(core, now))
                    keys.forget(forgotten)
                    for rig_id in forgotten:
                        log.warning("rig %s: forgotten after %g s without a sample (its next sample starts "
                                    "it afresh)", rig_id, forget_after_s)
                keys.check(core)
                if live is not None:
                    live.check(core)
                for flush in flushes:
                    flush()
                next_watch = now + watch_every
            if failover is not None and (line := failover.poll()) is not None:
                log.warning("monitor %s: %s", node_name, line)
            if saver is not None and publishing() and clock() >= next_save:
                saver.save(core)
                next_save = clock() + checkpoint_s
            if ranges_dir is not None and clock() >= next_scan:
                rescan_ranges()
                next_scan = clock() + ranges_scan_s
            if stop.is_set() or (deadline is not None and clock() >= deadline):
                break
            if n < max_batch:
                quiet.idle()  # garbage collection between batches, not inside one
                # let arrivals accumulate: one batch per poll_s amortises the per-batch cost
                # (measured: 9 samples a batch cost 36 us a sample live, against 5 us offline);
                # a batch that took longer than that is followed at once (we are behind)
                rest = poll_s - (time.perf_counter() - started)
                if rest > 0:
                    stop.wait(rest)
        for _ in range(100):  # what is already queued (bounded: a producer may still be sending)
            if drain() < max_batch:
                break
    except zenoh.ZError as exc:  # the session was closed under us
        log.warning("monitor stopping: %s", exc)
    finally:
        if saver is not None:
            saver.close(core if publishing() else None)
        if failover is not None:
            failover.close()
        quiet.__exit__()
        tell(backlog.close(clock()))
        keys.close()
        for flush in flushes:
            flush(final=True)
        for obj in (sub_s, sub_f, sub_c, queryable, ranges_queryable, token):
            try:
                obj.undeclare()
            except zenoh.ZError:
                pass
    return core


