"""The monitor's rigs' keys declared on its zenoh session, so that zenoh routes them from a cache."""

from __future__ import annotations

import logging

import zenoh

from hydromon.contract import event_key, frame_key, health_key, sample_key
from hydromon.engine.core import MonitorCore

__all__ = ["RigKeys"]

log = logging.getLogger("hydromon.bus.monitor")  # the node's log: these lines are its


class RigKeys:
    """The sample (a framing rig's: frame), health and event keys of the monitor's rigs, declared on its
    session (``session.declare_keyexpr``), so that zenoh routes them from a cache.

    zenoh keeps a routing-table resource, with its routes computed once, for each declared key
    expression; a message on an undeclared key has its route computed afresh, matched against
    every resource of the table. Measured (loopback, 500 rigs at 100 Hz, a bare subscriber that
    also puts one health message per 10 samples): the subscriber's receive thread 2.9-3.4 ->
    1.2-2.2 us a sample, its main thread 1.9-2.3 -> 1.4-2.1 us.

    The catch: once N keys are declared, a message on any *other* key is matched against all of
    them (about 0.15 us each: a health put of an undeclared key with 500 sample keys declared
    cost 76 us). So the health and event keys are declared with the sample keys (measured at 1000
    rigs with undeclared event keys: the rigs' first grades, two events each, held the monitor's
    publishing up for 0.3-0.4 s twice, every health of those seconds late), and the declarations
    are all dropped for good (``off``) when the monitor holds more than ``max_rigs`` rigs (each
    declaration also costs a walk over the others: 0.06 s for the first 1000 rigs, 12 s for
    10,000) or when messages on undeclared keys come at more than ``max_rejects`` per
    :meth:`check` (rejected ones: bad keys, rigs beyond ``--max-rigs``, rigs whose every sample
    is refused). Call :meth:`sync` after each ``MonitorCore.process`` (before publishing its
    health), :meth:`forget` with the rigs ``MonitorCore.forget`` forgot, :meth:`check` now and
    then, :meth:`close` at the end.
    """

    def __init__(self, session, namespace: str, max_rigs: int = 2000, max_rejects: int = 100, per_sync: int = 200):
        self.session, self.namespace = session, namespace
        self.per_sync = int(per_sync)  # most rigs declared a call: a fleet starting at once is spread over batches
        self.max_rigs, self.max_rejects = int(max_rigs), int(max_rejects)
        self.rigs: dict[str, tuple] = {}        # rig id -> (sample or frame KeyExpr, health KeyExpr, event KeyExpr)
        self.health: dict[str, object] = {}     # health key -> its declared KeyExpr
        self.events: dict[str, object] = {}     # event key -> its declared KeyExpr
        self.off = False
        self._rejected = None

    def sync(self, core: MonitorCore) -> None:
        """Declare the keys of the core's rigs that are new since the last call, at most
        ``per_sync`` rigs' a call (the rest at the next calls: declaring 1000 rigs' keys at once
        held a starting monitor up for 0.16 s)."""
        if self.off or len(core.rigs) == len(self.rigs):
            return
        if len(core.rigs) > self.max_rigs:
            self.close(f"more than {self.max_rigs} rigs")
            return
        declare = self.session.declare_keyexpr
        budget = self.per_sync
        for rig_id in core.rigs:
            if rig_id not in self.rigs:
                if budget == 0:
                    break
                budget -= 1
                hkey, ekey = health_key(rig_id, self.namespace), event_key(rig_id, self.namespace)
                # the key its samples come on: its frame key if it sends frames, else its sample key
                # (each declaration costs a walk over the others: not both)
                skey = (frame_key if core.sends_frames(rig_id) else sample_key)(rig_id, self.namespace)
                kes = self.rigs[rig_id] = (declare(skey), declare(hkey), declare(ekey))
                self.health[hkey], self.events[ekey] = kes[1], kes[2]

    def forget(self, rig_ids) -> None:
        for rig_id in rig_ids:
            kes = self.rigs.pop(rig_id, None)
            if kes is not None:
                del self.health[health_key(rig_id, self.namespace)]
                del self.events[event_key(rig_id, self.namespace)]
                self._undeclare(kes)

    def check(self, core: MonitorCore) -> None:
        """Give up the declarations if rejected messages came at more than ``max_rejects``
        since the last call."""
        n = core.counters.rejected_total
        if self._rejected is not None and n - self._rejected > self.max_rejects and not self.off:
            self.close(f"{n - self._rejected} messages rejected in a check interval")
        self._rejected = n

    def close(self, why: str | None = None) -> None:
        """Undeclare every key (and declare no more if ``why`` is given)."""
        if why is not None:
            self.off = True
            if self.rigs:
                log.info("monitor: rig keys no longer declared on the session (%s)", why)
        rigs, self.rigs, self.health, self.events = self.rigs, {}, {}, {}
        for kes in rigs.values():
            self._undeclare(kes)

    def _undeclare(self, kes) -> None:
        for ke in kes:
            try:
                self.session.undeclare(ke)
            except zenoh.ZError:  # the session is closed
                pass
