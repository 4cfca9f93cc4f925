"""A node's line in its log when it is cut off from the zenoh network, and when it is back.

Zenoh reconnects a client to its router (and a peer to its peers) by itself and says nothing,
so a recorder or monitor cut off for a while would leave a gap in a recording or in the health
with nothing to explain it. :class:`ConnectivityLog` follows the session's transports (zenoh's
transport events): once the last router or peer is gone it says so, with the time, and once one
is reached again it says so with how long the node was cut off. Clients connected to a router
are not counted (a router whose clients come and go is not cut off).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

import zenoh

__all__ = ["ConnectivityLog", "utc_now"]


def utc_now() -> str:
    """The wall-clock time as ``YYYY-MM-DDTHH:MM:SS.mmmZ`` (UTC)."""
    t = time.time()
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t)) + f".{int(t * 1000) % 1000:03d}Z"


def _whatami(transport) -> str:
    return str(transport.whatami).rsplit(".", 1)[-1].lower()


class ConnectivityLog:
    """Say when ``session`` loses its last zenoh router or peer, and when it reaches one again.

    Parameters
    ----------
    session : zenoh.Session
        An open session; :meth:`close` before closing it (a session's own close drops its
        transports, which is not a loss).
    say : callable
        Gets each line (default: ``hydromon NAME: ...`` on stderr).
    clock : callable
        Monotonic seconds, for how long the node was cut off.

    ``lost`` and ``regained`` count the events; ``cut_off_s`` lists how long each cut lasted [s].
    """

    def __init__(self, session: zenoh.Session, name: str = "node", say: Callable[[str], None] | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self._say = say or (lambda line: print(f"hydromon {name}: {line}", file=sys.stderr, flush=True))
        self._clock = clock
        self._lock = threading.Lock()
        self._open: dict[str, str] = {}  # zid -> router | peer
        self._lost_at: float | None = None
        self._closing = False
        self.reached = False  # a router or peer was reached at some time
        self.lost = self.regained = 0
        self.cut_off_s: list[float] = []
        self._listener = session.info.declare_transport_events_listener(self._on_event, history=True)

    def _on_event(self, event) -> None:  # zenoh's thread: no zenoh call here
        transport = event.transport
        kind = _whatami(transport)
        if kind not in ("router", "peer"):
            return
        zid = str(transport.zid)
        with self._lock:
            if self._closing:
                return
            now = self._clock()
            if event.kind == zenoh.SampleKind.PUT:
                self._open[zid] = kind
                self.reached = True
                if self._lost_at is not None and len(self._open) == 1:
                    cut = now - self._lost_at
                    self._lost_at = None
                    self.regained += 1
                    self.cut_off_s.append(cut)
                    self._say(f"reconnected to zenoh {kind} {zid} at {utc_now()}, after {cut:.1f} s cut off")
            elif self._open.pop(zid, None) is not None and not self._open:
                self._lost_at = now
                self.lost += 1
                self._say(f"cut off: lost zenoh {kind} {zid} at {utc_now()}; no zenoh router or peer is "
                          "reachable now (zenoh keeps trying to reconnect; nothing is sent or received meanwhile)")

    @property
    def connected(self) -> int:
        """Routers and peers this node has a transport to now."""
        with self._lock:
            return len(self._open)

    def close(self) -> None:
        """Stop following (before the session closes: its close is not a loss)."""
        with self._lock:
            self._closing = True
        try:
            self._listener.undeclare()
        except zenoh.ZError:  # the session was closed already
            pass
