"""The dashboard's own event log: the grade and status changes it heard, the monitors it saw leave,
and people's acknowledgements with their comments, as JSON lines in one file that survives a
restart.

Each line is one record: an event ``{"id", "wall", "rig", "kind", "from", "to", "reason", "t",
"seq", "node", "epoch"}`` (``kind`` is ``grade`` or ``status`` as on the bus, or ``monitor`` for a
monitor that left or came back; ``wall`` is when the dashboard heard it, Unix time [s]), or an
acknowledgement ``{"ack": id, "wall", "comment", "by"}``. A line that is not valid JSON (a file cut
short by a crash) is skipped and counted. Without a file the log is kept in memory only.
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque
from pathlib import Path

import orjson

__all__ = ["EventLog", "AlreadyAcknowledged", "COMMENT_MAX", "BY_MAX"]

COMMENT_MAX = 500
BY_MAX = 64
KEEP = 5000
"""Events held in memory (the file keeps every one)."""


class AlreadyAcknowledged(ValueError):
    """The event was acknowledged before (the message says by whom and when)."""


class EventLog:
    """Events, newest last, with their acknowledgements; appended to ``path`` (None: memory only)."""

    def __init__(self, path: str | os.PathLike | None = None, keep: int = KEEP):
        self.path = None if path is None else Path(path)
        self.events: deque[dict] = deque(maxlen=keep)
        self.by_id: dict[int, dict] = {}
        self.skipped = 0
        self.next_id = 1
        self._lock = threading.Lock()
        self._file = None
        if self.path is not None:
            self._load()
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "ab")

    def _load(self) -> None:
        if not self.path.exists():
            return
        with open(self.path, "rb") as f:
            for line in f:
                if not line.strip():
                    continue
                try:
                    rec = orjson.loads(line)
                except orjson.JSONDecodeError:
                    self.skipped += 1
                    continue
                if not isinstance(rec, dict):
                    self.skipped += 1
                elif "ack" in rec:
                    ev = self.by_id.get(rec["ack"])
                    if ev is not None:
                        ev["ack"] = {k: rec.get(k) for k in ("wall", "comment", "by")}
                elif isinstance(rec.get("id"), int):
                    self._hold(rec)
                    self.next_id = max(self.next_id, rec["id"] + 1)
                else:
                    self.skipped += 1

    def _hold(self, ev: dict) -> None:
        if len(self.events) == self.events.maxlen:
            self.by_id.pop(self.events[0]["id"], None)
        self.events.append(ev)
        self.by_id[ev["id"]] = ev

    def _write(self, rec: dict) -> None:
        if self._file is not None:
            self._file.write(orjson.dumps(rec) + b"\n")
            self._file.flush()

    def add(self, fields: dict) -> dict:
        """Append an event (``fields`` without ``id``); returns it with its id."""
        with self._lock:
            ev = {"id": self.next_id, **fields}
            self.next_id += 1
            self._hold(ev)
            self._write(ev)
            return ev

    def ack(self, event_id: int, comment: str, by: str, wall: float) -> dict:
        """Acknowledge event ``event_id`` with ``comment``, by the person named ``by``; returns the
        event. KeyError if it is not held; ValueError if the comment or name is not text or too
        long, or no name is given; :class:`AlreadyAcknowledged` if someone did so before (an
        acknowledgement is a record of who looked: a second one must not replace the first)."""
        if not isinstance(comment, str) or len(comment) > COMMENT_MAX:
            raise ValueError(f"comment: text of at most {COMMENT_MAX} characters")
        if not isinstance(by, str) or len(by) > BY_MAX:
            raise ValueError(f"by: text of at most {BY_MAX} characters")
        if not by.strip():
            raise ValueError("by: give the name of who acknowledges it")
        with self._lock:
            ev = self.by_id[event_id]
            if ev.get("ack") is not None:
                a = ev["ack"]
                raise AlreadyAcknowledged(f"already acknowledged by {a['by'] or 'someone'} at "
                                          f"{time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime(a['wall']))}")
            ev["ack"] = {"wall": wall, "comment": comment, "by": by}
            self._write({"ack": event_id, **ev["ack"]})
            return ev

    def last_of(self, rig: str, kind: str) -> dict | None:
        """The newest held event of ``rig`` of ``kind`` (None: none), without copying the log."""
        with self._lock:
            return next((e for e in reversed(self.events) if e.get("rig") == rig and e.get("kind") == kind), None)

    def recent(self, n: int | None = None, rig: str | None = None) -> list[dict]:
        """The held events, newest first (only rig ``rig``'s when given)."""
        with self._lock:
            out = [e for e in reversed(self.events) if rig is None or e.get("rig") == rig]
        return out if n is None else out[:n]

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
