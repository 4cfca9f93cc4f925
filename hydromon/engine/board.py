"""The latest health of every rig on the bus, for ``hydromon watch``: what the board knows.

A maintenance engineer beside a running monitor wants to see which rigs need attention; the
health topics carry it, one message per rig every few tenths of a second. :class:`Board` keeps
the latest valid health per rig (``contract.Health``; an invalid payload is counted, never shown
as a grade) and the time it arrived by the caller's clock, so a rig whose monitor went quiet
shows its age. :func:`attention_order` orders the rigs: ``bad-input`` first (its numbers cannot
be trusted, whatever the grade), then by level, worst first, then ``stale``; unknown grades last.

No I/O and no clock here: the command (``hydromon.cli.commands.watch``) subscribes, queries the
monitors' latest health and draws (``hydromon.report.board``).
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass, field

from pydantic import ValidationError

from hydromon.contract import DEFAULT_NAMESPACE, Event, Health, split_rig_key

__all__ = ["NO_MONITOR", "EVENTS_KEPT", "Board", "attention_order"]

EVENTS_KEPT = 8
"""The latest events (``<ns>/rig/<id>/event``: grade and status changes) a board keeps."""

NO_MONITOR = "no monitor"
"""What a rig shows when the monitor that graded it is gone (its liveliness token undeclared)."""

_ATTENTION = {"bad-input": 0, "uncalibrated": 1, "ok": 2, "converging": 2, "commissioning": 2, "stale": 2,
              NO_MONITOR: 2}


@dataclass
class Board:
    """Latest valid health per rig of namespace ``ns``, with its arrival time [s]."""

    ns: str = DEFAULT_NAMESPACE
    latest: dict[str, dict] = field(default_factory=dict)
    arrived: dict[str, float] = field(default_factory=dict)
    invalid: int = 0   # health (or event) payloads that are not the contract's
    foreign: int = 0   # messages on keys that are not <ns>/rig/<id>/health
    # the monitors by node name, alive or gone (their liveliness tokens), when the reader follows them
    monitors: dict[str, bool] = field(default_factory=dict)
    following: bool = False
    owner: dict[str, tuple] = field(default_factory=dict)  # rig -> (node, epoch) of its verdict shown
    not_shown: int = 0  # verdicts from a node that is not the rig's current, live monitor
    # the latest events, newest last: (rig, event as published, arrival time [s])
    events: deque = field(default_factory=lambda: deque(maxlen=EVENTS_KEPT))

    def monitor(self, node: str, alive: bool) -> None:
        """A monitor's liveliness token came (``alive``) or went; following them from now on."""
        self.following = True
        self.monitors[node] = alive

    def update(self, key: str, payload: bytes, now: float) -> bool:
        """Take one health message; False (and counted) if its key or payload is not valid, or
        :meth:`claim` does not show it."""
        got = self._parse(key, payload, "health", Health)
        if got is None:
            return False
        rig, health = got
        if not self.claim(rig, health.node, health.epoch):
            self.not_shown += 1
            return False
        self.latest[rig] = health.model_dump(exclude_unset=True)  # as published
        self.arrived[rig] = now
        return True

    def event(self, key: str, payload: bytes, now: float) -> bool:
        """Take one event message (``contract.Event``); False (and counted) if its key or payload
        is not valid."""
        got = self._parse(key, payload, "event", Event)
        if got is not None:
            self.events.append((got[0], got[1].model_dump(by_alias=True, exclude_unset=True), now))
        return got is not None

    def _parse(self, key: str, payload: bytes, leaf: str, model):
        """``(rig id, model instance)`` of a message on ``<ns>/rig/<id>/<leaf>``, else None and
        counted (``foreign`` key or ``invalid`` payload)."""
        parts = split_rig_key(key, self.ns)
        if isinstance(parts, str) or parts[1] != leaf:
            self.foreign += 1
            return None
        try:
            return parts[0], model.model_validate_json(payload)
        except ValidationError:
            self.invalid += 1
            return None

    def claim(self, rig: str, node: str | None, epoch: int | None) -> bool:
        """Whether a verdict on ``rig`` from monitor ``node`` (its start ``epoch``) is shown; if so
        it becomes the rig's. Not one from an older start of the rig's monitor (late, not current),
        nor (while following the monitors) one from no live monitor or from another node than the
        rig's current live monitor."""
        if not self.shown(rig, node, epoch):
            return False
        self.owner[rig] = (node, epoch)
        return True

    def shown(self, rig: str, node: str | None, epoch: int | None) -> bool:
        """Whether :meth:`claim` would show that verdict, without making it the rig's (for a
        second view of the same bus that must agree with the first)."""
        cur = self.owner.get(rig)
        if node is not None and cur is not None and cur[0] == node and (epoch or 0) < (cur[1] or 0):
            return False
        return not (node is not None and self.following and (not self.monitors.get(node, False) or cur is not None
                                                             and cur[0] != node and self.monitors.get(cur[0], False)))

    def monitor_gone(self, rig: str) -> bool:
        """True once the monitor that gave the rig's verdict shown has left the bus."""
        node = self.owner.get(rig, (None,))[0]
        return self.following and node is not None and not self.monitors.get(node, False)

    def status(self, rig: str) -> str:
        """The rig's status as shown: its verdict's, or ``no monitor`` once the monitor that gave
        it is gone."""
        return NO_MONITOR if self.monitor_gone(rig) else self.latest[rig]["status"]

    def grade_counts(self) -> Counter:
        """Rigs per grade name (``unknown`` included)."""
        return Counter(h["grade"] for h in self.latest.values())


def attention_order(item, status: str | None = None) -> tuple:
    """Sort key of a ``(rig id, health dict)`` (``status``: as shown, default the verdict's): the
    rigs that need attention first, stale and monitor-less ones last."""
    rig, h = item
    status = status or h["status"]
    level = h["level"] if h["level"] is not None else -1
    return (_ATTENTION.get(status, 2), -level, status in ("stale", NO_MONITOR), rig)


