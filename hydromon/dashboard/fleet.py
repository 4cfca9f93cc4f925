"""What the dashboard knows about the fleet, without I/O: each rig's latest verdict, the monitors
that are up, each rig's ranges, its history, and the events; and, every push period, what
changed for the browsers.

Health arrives ten times a second per rig; a browser wants a few updates a second. So the bus
side only stores each rig's latest raw payload with its arrival time (:meth:`Fleet.put_health`,
a dict assignment in zenoh's callback), and :meth:`Fleet.tick`, every push period, validates
the latest payload of each rig that sent one (``contract.Health``; an invalid one is counted,
never shown), keeps it in the rig's history when a ring is due, and returns the rows that
changed. A row says the rig's grade, confidence, status, why in words
(``hydromon.engine.words.why_words`` with the rig's ranges when known), since when it has its
grade, and a flag when its verdict cannot be trusted to be current: ``no monitor`` (the monitor
that said it, health's ``node``, has left the bus: its liveliness token is gone; for a verdict
without ``node``, no monitor is up at all) or ``silent`` (no verdict for :data:`SILENT_S`).
Which verdicts are shown follows ``hydromon watch``'s rule (``hydromon.engine.board.Board.claim``):
not one from an earlier start of the rig's monitor, nor, once a monitor's liveliness token has been
heard, one from a monitor that is not up or from another monitor while the rig's own is up.
"""

from __future__ import annotations

import threading
from collections import Counter
from dataclasses import dataclass, field

from pydantic import ValidationError

from hydromon.contract import GRADES, PARAM_UNITS, PARAM_WORDS, UNKNOWN, Event, Health
from hydromon.dashboard.eventlog import EventLog
from hydromon.dashboard.history import RigHistory
from hydromon.engine.board import NO_MONITOR, Board, attention_order
from hydromon.engine.words import why_words

__all__ = ["Fleet", "Tick", "SILENT_S", "SILENT", "row_order", "ranges_view"]

SILENT_S = 2.0
"""A rig with no verdict for this long [s] is flagged ``silent`` (its monitor sends ten a second)."""
SILENT = "silent"


def row_order(row: dict) -> tuple:
    """Sort key of a row: flagged rigs last, the others as ``hydromon.engine.board.attention_order``
    (bad input first, then the worst grade, stale last)."""
    return (row["flag"] is not None, *attention_order((row["rig"], row)))


def ranges_view(ranges) -> dict | None:
    """A ``monitor.ranges.Ranges`` as the rig page draws it: per graded parameter its direction,
    its four band edges in grade order (or its fault threshold), baseline, unit and words."""
    if ranges is None:
        return None
    out = {}
    for name, pr in ranges.params.items():
        est = ranges.baseline.get(name)
        out[name] = {"direction": pr.direction, "edges": list(pr.edges) if pr.edges is not None else None,
                     "threshold": pr.fault_threshold, "baseline": est.value if est is not None else None,
                     "unit": PARAM_UNITS.get(name, ""), "words": PARAM_WORDS.get(name, name)}
    return out


@dataclass
class Tick:
    """What changed in one push period."""

    now: float
    rows: list[dict] = field(default_factory=list)          # changed rows
    counts: dict = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)        # new events, oldest first
    points: dict[str, dict] = field(default_factory=dict)   # rig -> new history points (watched rigs)
    ranges_wanted: list[str] = field(default_factory=list)  # rigs whose ranges to ask the monitors for
    resnap: set[str] = field(default_factory=set)  # rigs whose page needs a whole snapshot (first verdict, ranges)


class Fleet:
    """The dashboard's state. ``put_*`` may be called from any thread; :meth:`tick` and the
    snapshots take the state's lock."""

    def __init__(self, events: EventLog | None = None, fallback_ranges=None, live: bool = True):
        self.events = events if events is not None else EventLog()
        self.fallback_ranges = fallback_ranges
        self.live = live  # False: a recording (no monitors to follow, no silence)
        self.latest: dict[str, dict] = {}
        self.arrived: dict[str, float] = {}
        self.since: dict[str, float] = {}
        self.history: dict[str, RigHistory] = {}
        self.ranges: dict[str, object] = {}
        # the monitors (node -> up) and whose verdict each rig shows; followed from the first
        # liveliness token heard, as watch does
        self.board = Board()
        self.invalid = 0                         # health or event payloads that are not the contract's
        self.not_shown = 0                       # verdicts Board.claim does not show
        self.history_shape: tuple | None = None  # (fine, coarse) of new rigs' histories
        self._raw: dict[str, tuple[bytes, float]] = {}
        self._resnap: set[str] = set()  # rigs whose ranges changed since the last tick
        self._raw_events: list[tuple[str, bytes, float]] = []
        self._monitor_changes: list[tuple[str, bool, float]] = []
        self._rows: dict[str, dict] = {}
        self._ranges_tag: dict[str, object] = {}
        self._pushed: dict[str, float] = {}
        self.lock = threading.Lock()

    # -- intake (any thread) ---------------------------------------------------------------
    def put_health(self, rig: str, payload: bytes, wall: float) -> None:
        self._raw[rig] = (payload, wall)

    def put_health_if_new(self, rig: str, payload: bytes, wall: float) -> None:
        """A verdict from a query's answer: taken unless one arrived on the subscription first."""
        if rig not in self._raw and rig not in self.latest:
            self._raw[rig] = (payload, wall)

    def put_event(self, rig: str, payload: bytes, wall: float) -> None:
        self._raw_events.append((rig, payload, wall))

    def put_monitor(self, node: str, up: bool, wall: float) -> None:
        self._monitor_changes.append((node, up, wall))

    @property
    def monitors(self) -> dict[str, bool]:
        """The monitors seen, by node name: up or gone."""
        return self.board.monitors

    def set_ranges(self, rig: str, ranges) -> None:
        with self.lock:
            self.ranges[rig] = ranges
            self._rows.pop(rig, None)  # the words change with the baseline
            self._resnap.add(rig)  # an open rig page draws the bands anew

    def ranges_for(self, rig: str):
        return self.ranges.get(rig) or self.fallback_ranges

    def take_recorded(self, rig: str, leaf: str, payload: bytes, wall: float) -> None:
        """One message of a recording, in order (every verdict goes through the history rings)."""
        with self.lock:
            if leaf == "health":
                self._take_health(rig, payload, wall, Tick(now=wall))
            elif leaf == "event":
                self._take_event(rig, payload, wall, Tick(now=wall))

    # -- one push period ---------------------------------------------------------------------
    def tick(self, now: float, watched: set[str] = frozenset()) -> Tick:
        """Take what arrived since the last tick; the rows that changed, new events and the new
        history points of the ``watched`` rigs (rig pages open)."""
        raw, self._raw = self._raw, {}
        raw_events, self._raw_events = self._raw_events, []
        changes, self._monitor_changes = self._monitor_changes, []
        out = Tick(now=now)
        with self.lock:
            out.resnap, self._resnap = self._resnap, set()
            for node, up, wall in changes:
                self._monitor(node, up, wall, out)
            for rig, (payload, wall) in raw.items():
                self._take_health(rig, payload, wall, out)
            for rig, payload, wall in raw_events:
                self._take_event(rig, payload, wall, out)
            for rig in self.latest:
                row = self._row(rig, now)
                if row != self._rows.get(rig):
                    self._rows[rig] = row
                    out.rows.append(row)
            for rig in watched:
                hist = self.history.get(rig)
                if hist is not None and hist.last_wall > self._pushed.get(rig, -1.0):
                    out.points[rig] = hist.points(since=self._pushed.get(rig))
                    self._pushed[rig] = hist.last_wall
            out.counts = self._counts()
        return out

    def _take_health(self, rig: str, payload: bytes, wall: float, out: Tick) -> None:
        try:
            h = Health.model_validate_json(payload).model_dump()
        except ValidationError:
            self.invalid += 1
            return
        if not self.board.claim(rig, h["node"], h["epoch"]):
            self.not_shown += 1
            return
        prev = self.latest.get(rig)
        if prev is None:
            out.resnap.add(rig)  # a rig page opened before it: its graded parameters and ranges come now
            # since when: the event log's (kept across a restart of the dashboard) if its newest
            # grade change of the rig led to this grade, else from now
            self.since[rig] = self._grade_since(rig, h["grade"], wall)
        elif prev["grade"] != h["grade"]:
            self.since[rig] = wall
        if prev is None or prev["ranges"] != h["ranges"] or prev["node"] != h["node"]:
            out.ranges_wanted.append(rig)
        self.latest[rig], self.arrived[rig] = h, wall
        hist = self.history.get(rig)
        if hist is None:
            hist = self.history[rig] = RigHistory(*self.history_shape) if self.history_shape else RigHistory()
        hist.take(wall, h)

    def _grade_since(self, rig: str, grade: str, wall: float) -> float:
        """When the rig took ``grade`` by the event log's newest grade change of it [s since the
        epoch], or ``wall`` when the log says nothing of it or of another grade since."""
        e = self.events.last_of(rig, "grade")
        return float(e["wall"]) if e is not None and e.get("to") == grade and e["wall"] <= wall else wall

    def _take_event(self, rig: str, payload: bytes, wall: float, out: Tick) -> None:
        try:
            ev = Event.model_validate_json(payload).model_dump(by_alias=True)
        except ValidationError:
            self.invalid += 1
            return
        out.events.append(self.events.add({"wall": wall, "rig": rig, **ev}))

    def _monitor(self, node: str, up: bool, wall: float, out: Tick) -> None:
        was = self.monitors.get(node)
        self.board.monitor(node, up)
        if up and was is False:
            out.events.append(self.events.add({"wall": wall, "rig": None, "kind": "monitor", "from": "gone",
                                               "to": "up", "node": node, "reason": f"monitor {node} is back"}))
        elif not up and was:
            rigs = [r for r, h in self.latest.items() if h["node"] == node]
            reason = f"monitor {node} left the bus" + (f": {len(rigs)} rig(s) without a monitor" if rigs else "")
            out.events.append(self.events.add({"wall": wall, "rig": None, "kind": "monitor", "from": "up",
                                               "to": "gone", "node": node, "reason": reason}))

    def _flag(self, rig: str, now: float) -> str | None:
        if not self.live:
            return None
        if self.board.monitor_gone(rig):
            return NO_MONITOR
        if self.latest[rig]["node"] is None and self.monitors and not any(self.monitors.values()):
            return NO_MONITOR
        if now - self.arrived[rig] > SILENT_S:
            return SILENT
        return None

    def _row(self, rig: str, now: float) -> dict:
        h = self.latest[rig]
        why = why_words(h, self.ranges_for(rig))
        return {"rig": rig, "grade": h["grade"], "level": h["level"], "confidence": round(h["confidence"], 2),
                "status": h["status"], "why": why, "t": h["t"], "arrived": self.arrived[rig],
                "since": self.since[rig], "node": h["node"], "ranges": h["ranges"], "flag": self._flag(rig, now)}

    def _counts(self) -> dict:
        n = Counter(h["grade"] for h in self.latest.values())
        flags = Counter(r["flag"] for r in self._rows.values() if r["flag"] is not None)
        return {"rigs": len(self.latest), "grades": {g: n[g] for g in (*reversed(GRADES), UNKNOWN) if n[g]},
                "bad_input": sum(1 for h in self.latest.values() if h["status"] == "bad-input"),
                "stale": sum(1 for h in self.latest.values() if h["status"] == "stale"),
                "flags": dict(flags), "invalid": self.invalid,
                "monitors": sorted(n for n, up in self.monitors.items() if up)}

    # -- snapshots (a page that opens) ---------------------------------------------------------
    def fleet_snapshot(self, now: float) -> dict:
        with self.lock:
            rows = [self._rows.get(r) or self._row(r, now) for r in self.latest]
            return {"type": "fleet", "now": now, "rows": sorted(rows, key=row_order), "counts": self._counts(),
                    "live": self.live}

    def rig_snapshot(self, rig: str, now: float) -> dict:
        with self.lock:
            h = self.latest.get(rig)
            hist = self.history.get(rig)
            return {"type": "rig", "now": now, "rig": rig, "live": self.live,
                    "row": None if h is None else (self._rows.get(rig) or self._row(rig, now)),
                    "health": h, "points": hist.points() if hist is not None else None,
                    "ranges": ranges_view(self.ranges_for(rig)),
                    "ranges_from": "monitor" if self.ranges.get(rig) is not None else
                    ("fallback" if self.fallback_ranges is not None else None),
                    "params": list(PARAM_UNITS), "units": PARAM_UNITS, "words": PARAM_WORDS,
                    "events": self.events.recent(200, rig=rig)}
