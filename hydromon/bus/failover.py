"""Which monitor of a failover group publishes: one at a time, the one that claimed first.

The monitors of a group (the same rigs: a primary and its standbys) each follow the group's
liveliness tokens ``<ns>/failover/<group>/<claim>-<node>``. A monitor that publishes holds such
a token, named by when it claimed (wall clock [ns], zero-padded, so the names sort by claim
time). The rules, applied on every :meth:`Failover.poll`:

- a monitor publishes only while it holds a token and no older token is alive: of two that
  claimed at once, the younger sees the older's token and stands back;
- a monitor without a token claims one when no token of the group is alive, at once for a
  primary, after ``grace_s`` for a monitor started as a standby (a primary starting at the same
  time is given the first word);
- zenoh deletes the token of a node that dies (its session's transport closes; of a node cut
  off by the network, after the lease), so a standby claims within one poll of that.

So a primary that comes back after its standby took over finds the standby's token and stands
by itself: it never fights for the rigs. The standby runs hot (it takes every sample and keeps
its estimates current) and publishes nothing until it claims; see ``hydromon.bus.monitor``.
"""

from __future__ import annotations

import hashlib
import re
import time

import zenoh

from hydromon.contract import RIG_ID_RE, failover_key

__all__ = ["Failover", "group_name"]


def group_name(rigs: str) -> str:
    """The default failover group of monitors grading rigs ``rigs`` (a key-expression chunk):
    ``all`` for ``*``, else a digest of the pattern (a key chunk whatever the pattern holds)."""
    return "all" if rigs == "*" else "rigs-" + hashlib.sha256(rigs.encode()).hexdigest()[:12]


_CLAIM = re.compile(rf"[0-9]{{20}}-({RIG_ID_RE.pattern})")  # <claim time [ns], 20 digits>-<node>


def _node_of(token: str) -> str:
    return _CLAIM.fullmatch(token.rsplit("/", 1)[1]).group(1)


def _is_claim(token: str) -> bool:
    """Whether ``token`` is a claim as monitors make them: a token of another shape (a peer's
    mistake, or a forgery) claims nothing, and must not stop a monitor that reads it."""
    return _CLAIM.fullmatch(token.rsplit("/", 1)[1]) is not None


class Failover:
    """This node's part in its failover group (see the module doc).

    Parameters
    ----------
    session : zenoh.Session
        An open session.
    namespace, group, node : str
        The group's key prefix ``<namespace>/failover/<group>`` and this node's name.
    standby : bool
        Started as a standby: claim only after ``grace_s`` [s] without any token of the group.
    probe_s : float
        How long [s] the start waits for the group's live tokens.
    clock, wall_ns : callables
        Monotonic clock [s] for the grace; wall clock [ns] naming the claims.
    """

    def __init__(self, session, namespace: str, group: str, node: str, standby: bool = False,
                 grace_s: float = 2.0, probe_s: float = 1.0, clock=time.monotonic, wall_ns=time.time_ns):
        self.session, self.node, self.standby = session, node, bool(standby)
        self.prefix = failover_key(group, namespace)
        self.clock, self.wall_ns = clock, wall_ns
        self.others: set[str] = set()  # the group's live tokens, this node's own excepted
        self.mine: str | None = None
        self._token = None
        self._sub = session.liveliness().declare_subscriber(f"{self.prefix}/*", zenoh.handlers.FifoChannel(1000),
                                                            history=True)
        for reply in session.liveliness().get(f"{self.prefix}/*", timeout=probe_s):
            if reply.ok is not None and _is_claim(str(reply.ok.key_expr)):
                self.others.add(str(reply.ok.key_expr))
        self._not_before = clock() + (grace_s if self.standby else 0.0)

    @property
    def active(self) -> bool:
        """This node publishes."""
        return self._token is not None

    def holder(self) -> str | None:
        """The node whose token is oldest of the group's (None: none alive)."""
        keys = self.others | ({self.mine} if self.mine else set())
        return _node_of(min(keys)) if keys else None

    def poll(self) -> str | None:
        """Follow the group's tokens and claim or stand back by the rules; a line for the log
        when this node's role changed, else None."""
        try:
            while (s := self._sub.try_recv()) is not None:
                key = str(s.key_expr)
                if key == self.mine or not _is_claim(key):
                    continue
                if s.kind == zenoh.SampleKind.PUT:
                    self.others.add(key)
                else:
                    self.others.discard(key)
        except zenoh.ZError:  # the session is closing
            return None
        if self._token is not None:
            older = sorted(k for k in self.others if k < self.mine)
            if older:
                self._release()
                return f"monitor {_node_of(older[0])} claimed these rigs first: standing by"
            return None
        if not self.others and self.clock() >= self._not_before:
            self.mine = f"{self.prefix}/{self.wall_ns():020d}-{self.node}"
            self._token = self.session.liveliness().declare_token(self.mine)
            return "no other monitor publishes for these rigs: publishing"
        return None

    def _release(self) -> None:
        token, self._token, self.mine = self._token, None, None
        try:
            token.undeclare()
        except zenoh.ZError:
            pass

    def close(self) -> None:
        if self._token is not None:
            self._release()
        try:
            self._sub.undeclare()
        except zenoh.ZError:
            pass
