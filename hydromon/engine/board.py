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

from collections import Counter
from dataclasses import dataclass, field

from pydantic import ValidationError

from hydromon.contract import DEFAULT_NAMESPACE, Health, split_rig_key

__all__ = ["Board", "attention_order"]

_ATTENTION = {"bad-input": 0, "ok": 1, "converging": 1, "stale": 1}


@dataclass
class Board:
    """Latest valid health per rig of namespace ``ns``, with its arrival time [s]."""

    ns: str = DEFAULT_NAMESPACE
    latest: dict[str, dict] = field(default_factory=dict)
    arrived: dict[str, float] = field(default_factory=dict)
    invalid: int = 0   # health payloads that are not the contract's Health
    foreign: int = 0   # messages on keys that are not <ns>/rig/<id>/health

    def update(self, key: str, payload: bytes, now: float) -> bool:
        """Take one health message; False (and counted) if its key or payload is not valid."""
        parts = split_rig_key(key, self.ns)
        if isinstance(parts, str) or parts[1] != "health":
            self.foreign += 1
            return False
        try:
            health = Health.model_validate_json(payload)
        except ValidationError:
            self.invalid += 1
            return False
        self.latest[parts[0]] = health.model_dump(exclude_unset=True)  # as published
        self.arrived[parts[0]] = now
        return True

    def grade_counts(self) -> Counter:
        """Rigs per grade name (``unknown`` included)."""
        return Counter(h["grade"] for h in self.latest.values())


def attention_order(item) -> tuple:
    """Sort key of a ``(rig id, health dict)``: the rigs that need attention first."""
    rig, h = item
    level = h["level"] if h["level"] is not None else -1
    return (_ATTENTION.get(h["status"], 1), -level, h["status"] == "stale", rig)


