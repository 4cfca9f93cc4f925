"""The dashboard on the bus: what it follows and what it asks, read-only.

* ``<ns>/rig/<rigs>/health`` and ``<ns>/rig/<rigs>/event``: subscribed with callbacks that only
  store the payload (:class:`hydromon.dashboard.fleet.Fleet` validates it once per push period);
* ``<ns>/monitor/*``: the monitors' liveliness tokens (with history: the ones already up), so a
  rig whose monitor left shows ``no monitor`` at the next push;
* a liveliness query on ``<ns>/monitor/*``, then a query on ``<ns>/rig/<rigs>/health`` at start
  (a verdict is shown only from a monitor known to be up): every monitor answers with the latest verdict
  of each rig it holds, as for ``hydromon watch``;
* a query on ``<ns>/rig/<id>/ranges`` for each new rig, and again when its health names other
  ranges or another monitor: the monitor answers with the ``monitor.ranges.Ranges`` it grades
  the rig on (band edges and the rig's baseline). No answer leaves the rig on the dashboard's
  fallback ranges (``--ranges``), or none; it is asked again after :data:`RANGES_RETRY_S`.
"""

from __future__ import annotations

import queue
import threading
import time

import zenoh

from hydromon.contract import DEFAULT_NAMESPACE, monitor_of_token, parse_rig_key, ranges_key
from hydromon.dashboard.fleet import Fleet
from monitor.ranges import Ranges

__all__ = ["BusFeed", "RANGES_RETRY_S"]

RANGES_RETRY_S = 30.0
QUERY_TIMEOUT_S = 2.0


class BusFeed:
    """Follows the bus for ``fleet`` on an open ``session`` (not closed here) until :meth:`close`."""

    def __init__(self, session: zenoh.Session, fleet: Fleet, namespace: str = DEFAULT_NAMESPACE,
                 rigs: str = "*", clock=time.time):
        self.session, self.fleet, self.ns, self.rigs, self.clock = session, fleet, namespace, rigs, clock
        self._decls = []
        self._ranges_q: queue.Queue = queue.Queue()
        self._asked: dict[str, float] = {}
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.answered = 0  # rigs in the monitors' answers to the first health query

    def start(self, wait_s: float = QUERY_TIMEOUT_S) -> None:
        ns, fleet, clock = self.ns, self.fleet, self.clock

        def on_health(sample: zenoh.Sample) -> None:
            parsed = parse_rig_key(str(sample.key_expr), ns)
            if parsed is not None and parsed[1] == "health":
                fleet.put_health(parsed[0], sample.payload.to_bytes(), clock())

        def on_event(sample: zenoh.Sample) -> None:
            parsed = parse_rig_key(str(sample.key_expr), ns)
            if parsed is not None and parsed[1] == "event":
                fleet.put_event(parsed[0], sample.payload.to_bytes(), clock())

        def on_token(sample: zenoh.Sample) -> None:
            node = monitor_of_token(str(sample.key_expr))
            if node is not None:
                fleet.put_monitor(node, sample.kind == zenoh.SampleKind.PUT, clock())

        # subscribe first: a verdict published while the query runs is not missed
        self._decls.append(self.session.declare_subscriber(f"{ns}/rig/{self.rigs}/health", on_health))
        self._decls.append(self.session.declare_subscriber(f"{ns}/rig/{self.rigs}/event", on_event))
        self._decls.append(self.session.liveliness().declare_subscriber(f"{ns}/monitor/*", on_token, history=True))
        self._spawn("health-query", lambda: self._query_health(wait_s))
        self._spawn("ranges-query", self._ranges_loop)

    def _spawn(self, name: str, target) -> None:
        t = threading.Thread(target=target, name=f"dashboard-{name}", daemon=True)
        t.start()
        self._threads.append(t)

    def _query_health(self, wait_s: float) -> None:
        # the monitors up now first, as watch does: only a live monitor's verdict is shown
        for reply in self.session.liveliness().get(f"{self.ns}/monitor/*", timeout=min(wait_s, QUERY_TIMEOUT_S)):
            node = monitor_of_token(str(reply.ok.key_expr)) if reply.ok is not None else None
            if node is not None:
                self.fleet.put_monitor(node, True, self.clock())
        seen = set()
        for reply in self.session.get(f"{self.ns}/rig/{self.rigs}/health", timeout=wait_s):
            if self._stop.is_set():
                return
            if reply.ok is None:
                continue
            parsed = parse_rig_key(str(reply.ok.key_expr), self.ns)
            if parsed is not None and parsed[1] == "health":
                self.fleet.put_health_if_new(parsed[0], reply.ok.payload.to_bytes(), self.clock())
                seen.add(parsed[0])
        self.answered = len(seen)

    def want_ranges(self, rigs) -> None:
        """Ask the monitors for these rigs' ranges (in the background)."""
        for rig in rigs:
            self._asked.pop(rig, None)
            self._ranges_q.put(rig)

    def retry_ranges(self) -> None:
        """Ask again for the rigs whose monitor did not answer :data:`RANGES_RETRY_S` ago."""
        now = time.monotonic()
        for rig, when in list(self._asked.items()):
            if when is not None and now - when > RANGES_RETRY_S:
                self._asked[rig] = None
                self._ranges_q.put(rig)

    def _ranges_loop(self) -> None:
        while not self._stop.is_set():
            try:
                rig = self._ranges_q.get(timeout=0.2)
            except queue.Empty:
                continue
            if rig is None:
                return
            got = None
            try:
                for reply in self.session.get(ranges_key(rig, self.ns), timeout=QUERY_TIMEOUT_S):
                    if reply.ok is not None and got is None:
                        try:
                            got = Ranges.model_validate_json(reply.ok.payload.to_bytes())
                        except ValueError:
                            pass
            except zenoh.ZError:  # the session closed meanwhile
                return
            if got is not None:
                self.fleet.set_ranges(rig, got)
                self._asked.pop(rig, None)
            else:
                self._asked[rig] = time.monotonic()

    def on_tick(self, tick) -> None:
        """Every push period: ask for the ranges of the rigs that need them."""
        if tick.ranges_wanted:
            self.want_ranges(tick.ranges_wanted)
        self.retry_ranges()

    def close(self) -> None:
        self._stop.set()
        self._ranges_q.put(None)
        for d in self._decls:
            try:
                d.undeclare()
            except zenoh.ZError:
                pass
        for t in self._threads:
            t.join(5)
