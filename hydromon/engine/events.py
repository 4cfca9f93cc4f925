"""Grade and status changes, announced as ``<ns>/rig/<id>/event`` messages.

A rig's verdict comes ten times a second; a dashboard or an alarm wants to hear only when it
changes. :class:`Announcer` keeps, per rig, the grade and status last announced and announces a
new one once it has held for ``hold`` evaluations in a row (after the grading's own hysteresis):
an estimate that wavers across an edge for one evaluation, or a parameter that drops out of the
SE gate for a moment, makes no event. A rig's first verdict is taken as its state, not announced.
``stale`` (a rig gone silent) is announced at once: it comes as one re-sent verdict, not a run.
"""

from __future__ import annotations

import orjson

from hydromon.contract import GRADES, UNKNOWN

__all__ = ["Announcer", "event_payload", "HOLD"]

HOLD = 3
"""Evaluations a new grade or status must hold before it is announced (0.3 s at 10 per second)."""
_NONE = -2  # no verdict yet
_GRADE_NAMES = GRADES + (UNKNOWN,)


def event_payload(seq: int, t: float, kind: str, before: str, after: str, reason: str, node: str | None,
                  epoch: int | None) -> bytes:
    """The JSON of a ``contract.Event`` (``from`` is a keyword in Python, so not the model's dump)."""
    out = {"seq": seq, "t": t, "kind": kind, "from": before, "to": after, "reason": reason[:400]}
    if node is not None:
        out["node"] = node
    if epoch is not None:
        out["epoch"] = epoch
    return orjson.dumps(out)


class Announcer:
    """Per rig (by row): the announced (level, status) and the candidate that is holding.

    Levels are -1 (unknown) .. 4; statuses are the contract's names.
    """

    def __init__(self, hold: int = HOLD):
        if hold < 1:
            raise ValueError(f"hold {hold!r} must be >= 1")
        self.hold = int(hold)
        self._announced: list[tuple[int, str] | None] = []
        self._candidate: list[tuple[int, str] | None] = []
        self._count: list[int] = []

    def reset(self, row: int) -> None:
        """Row ``row`` holds a new rig (or a forgotten one): its next verdict is its state."""
        self._grow(row)
        self._announced[row], self._candidate[row], self._count[row] = None, None, 0

    def _grow(self, row: int) -> None:
        while len(self._announced) <= row:
            self._announced.append(None)
            self._candidate.append(None)
            self._count.append(0)

    def observe(self, row: int, level: int, status: str, now: bool = False) -> tuple[tuple[int, str], tuple[int, str]] | None:
        """Take the rig's new verdict; ``(announced before, announced now)`` when it changes what
        is announced (``now``: at once, without holding), else None."""
        self._grow(row)
        cur = (level, status)
        ann = self._announced[row]
        if ann is None:
            self._announced[row] = cur
            return None
        if cur == ann:
            self._candidate[row], self._count[row] = None, 0
            return None
        if cur == self._candidate[row]:
            self._count[row] += 1
        else:
            self._candidate[row], self._count[row] = cur, 1
        if now or self._count[row] >= self.hold:
            self._announced[row], self._candidate[row], self._count[row] = cur, None, 0
            return ann, cur
        return None


def grade_name(level: int) -> str:
    return _GRADE_NAMES[level] if level >= 0 else UNKNOWN
