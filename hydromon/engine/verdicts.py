"""A rig's verdicts: the ranges it is graded on, the status and payload of each evaluation, and
the changes worth an event.

:class:`Verdicts` is the part of the monitor core that turns the fleet's evaluations into health
payloads (``hydromon.engine.health_json``) and event payloads (``hydromon.engine.events``): it
asks the :class:`~hydromon.engine.ranges_book.RangesBook` which ranges grade each rig (a rig
without ranges made for its constants is ``uncalibrated``: its parameters reported, its grade
unknown), says each verdict's status (``hydromon.engine.status``), names the monitor that said it
(``node``, ``epoch``) and announces grade and status changes once they hold, with the reason in
words (``hydromon.engine.words``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import orjson

from hydromon.contract import GRADES, UNKNOWN, RigConfig, event_key
from hydromon.engine.events import Announcer, event_payload
from hydromon.engine.health_json import HealthWriter
from hydromon.engine.ranges_book import RangesBook
from hydromon.engine.status import health_status
from hydromon.engine.words import why_words
from monitor.ranges import Ranges

__all__ = ["Verdicts"]

_GRADE = GRADES + (UNKNOWN,)  # level -1 -> unknown


def _status_reason(status: str, why_uncalibrated: str | None) -> str:
    return {
        "bad-input": "its input is bad: a message rejected, physically impossible estimates, x1 beyond a "
                     "chamber's end, readings its config cannot hold (a channel in other units), or "
                     "readings that stopped changing",
        "stale": "no recent samples (the rig went silent, or the filters restart after a gap)",
        "commissioning": "the monitor is commissioning it from its first samples",
        "uncalibrated": why_uncalibrated or "no ranges were made for it",
        "converging": "too few samples yet to place its grade",
        "ok": "graded",
    }.get(status, status)


class Verdicts:
    """Ranges, statuses, payloads and events of a fleet's rigs (by row).

    Parameters
    ----------
    fleet : monitor.pipeline.Fleet
        The rigs' estimators and grading arrays.
    namespace : str
        Key prefix of the events.
    book : RangesBook or None
        Which ranges grade which rig (default: the default ranges, for the rigs they were made for).
    node, epoch : str, int or None
        Who says the verdicts: the monitor node's name and its start count (None: left out).
    on_warning : callable or None
        ``on_warning(rig_id, message)`` when a rig is left ungraded, and why.
    """

    def __init__(self, fleet, namespace: str, book: RangesBook | None = None, node: str | None = None,
                 epoch: int | None = None, on_warning: Callable[[str, str], None] | None = None):
        self.fleet, self.namespace = fleet, namespace
        self.book = book or RangesBook(fleet.ranges)
        self.node, self.epoch = node, epoch
        self.on_warning = on_warning
        self.announcer = Announcer()
        self._writer = HealthWriter()
        self.events: list[tuple[str, bytes]] = []   # announced, not yet taken
        self._ranges: dict[int, Ranges | None] = {}  # by row: the ranges in force
        self._event_keys: dict[int, str] = {}
        self.commissioning: set[int] = set()  # rows the monitor is commissioning

    # -- ranges -------------------------------------------------------------------------------
    def apply(self, row: int, config: RigConfig | None) -> None:
        """Grade the rig in ``row`` (constants ``config``) on the ranges the book gives it."""
        rig_id = self.fleet.ids[row]
        rr = self.book.for_rig(rig_id, config)
        before = self.fleet.ranges_tag(row), self.fleet.why[row]
        self.fleet.set_ranges(row, rr.ranges, rr.tag, rr.why)
        self._ranges[row] = rr.ranges
        self._event_keys[row] = event_key(rig_id, self.namespace)
        if rr.ranges is None and self.on_warning is not None and before != (None, rr.why):
            self.on_warning(rig_id, f"not graded: {rr.why}")

    def ranges_of(self, row: int) -> tuple[Ranges | None, str | None]:
        """The ranges the rig in ``row`` is graded on and their tag (None, None: none)."""
        return self._ranges.get(row), self.fleet.ranges_tag(row)

    def forget(self, row: int) -> None:
        self._ranges.pop(row, None)
        self.commissioning.discard(row)
        self.announcer.reset(row)

    # -- one batch's evaluations ----------------------------------------------------------------
    def payloads(self, ev, seqs: list, t: np.ndarray, flagged: list) -> list[bytes]:
        """Health payloads of the fleet's evaluations ``ev`` (``monitor.evaluations.Events``), with
        the seq and t [s] of the sample each follows and the status the core flagged for it
        (``bad-input`` for a rejected message, ``stale`` after a gap, or None); announces the
        changes (:attr:`events`)."""
        rows = ev.rig.tolist()
        levels = ev.level.tolist()
        # a rig whose x1 went beyond a chamber's end has a wrong config or x1: its input is bad
        bad_input = (ev.implausible | (ev.clamped > 0)).tolist()  # as of each event: batching-independent
        counts = self.fleet.g_count
        statuses = [health_status(bad or st == "bad-input", st == "stale", conv, level, counts[r] > 0,
                                  r in self.commissioning)
                    for r, level, conv, bad, st in zip(rows, levels, ev.converged.tolist(), bad_input, flagged)]
        fleet = self.fleet
        payloads = self._writer.payloads(seqs, t, ev.level, ev.confidence, ev.params, ev.std_errors, ev.grades,
                                         statuses, [fleet.graded(r) for r in rows],
                                         [fleet.ranges_tag(r) for r in rows], self.node, self.epoch)
        observe = self.announcer.observe
        for j, (r, level, status) in enumerate(zip(rows, levels, statuses)):
            change = observe(r, level, status)
            if change is not None:
                self._announce(r, change, seqs[j], float(t[j]), payloads[j])
        return payloads

    def stale(self, row: int, seq: int, t: float, level: int, payload: bytes, status: str = "stale") -> None:
        """The rig in ``row`` took no sample for a while: its latest verdict re-sent with ``status``
        (``stale``, or ``bad-input`` when its messages are refused) is announced at once."""
        change = self.announcer.observe(row, level, status, now=True)
        if change is not None:
            self._announce(row, change, seq, t, payload)

    def _announce(self, row: int, change, seq: int, t: float, payload: bytes) -> None:
        (l0, s0), (l1, s1) = change
        key = self._event_keys[row]
        if l0 != l1:
            words = why_words(orjson.loads(payload), self._ranges.get(row))
            if l1 < 0:
                reason = _status_reason(s1, self.fleet.why[row]) if s1 != "ok" else "no parameter could be placed"
            elif l1 == 0:
                reason = "every graded parameter within its health band"
            else:
                reason = "; ".join(words) or f"graded {_GRADE[l1]}"
            self.events.append((key, event_payload(seq, t, "grade", _GRADE[l0], _GRADE[l1], reason, self.node,
                                                   self.epoch)))
        if s0 != s1:
            self.events.append((key, event_payload(seq, t, "status", s0, s1, _status_reason(s1, self.fleet.why[row]),
                                                   self.node, self.epoch)))

    def take_events(self) -> list[tuple[str, bytes]]:
        """The events announced since the last call, in order (and forget them)."""
        out, self.events = self.events, []
        return out
