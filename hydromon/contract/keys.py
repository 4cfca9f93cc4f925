"""Key expressions of the bus: ``<ns>/rig/<id>/<leaf>`` and ``<ns>/monitor/<node>``.

One codec builds and parses every key; MCAP topics are the keys, so recordings use it too.
A rig id (and a monitor's node name) is 1-64 chars of ``[A-Za-z0-9_-]``: safe in keys and
file names; anything else is rejected at the edge. A namespace is ``/``-separated chunks of
the same characters.
"""

from __future__ import annotations

import re

__all__ = [
    "DEFAULT_NAMESPACE", "LEAVES", "SAMPLE_LEAVES", "RIG_ID_RE", "valid_rig_id", "check_namespace", "rig_key", "sample_key",
    "frame_key", "monitor_of_token",
    "health_key", "config_key", "event_key", "ranges_key", "liveliness_key", "rig_key_parts", "split_rig_key", "parse_rig_key",
]

DEFAULT_NAMESPACE = "hydro"
LEAVES = ("sample", "frame", "health", "config", "event", "ranges")
"""The leaves of a rig's keys (``ranges`` is only queried: a monitor answers with the health ranges
it grades the rig on)."""
SAMPLE_LEAVES = ("sample", "frame")
"""The leaves that carry a rig's samples: one per message, or a frame of consecutive ones."""
RIG_ID_RE = re.compile(r"[A-Za-z0-9_-]{1,64}")
_NS_RE = re.compile(r"[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*")


def valid_rig_id(rig_id: str) -> bool:
    """True if ``rig_id`` is 1-64 chars of ``[A-Za-z0-9_-]`` (safe in keys and file names)."""
    return isinstance(rig_id, str) and RIG_ID_RE.fullmatch(rig_id) is not None


def check_namespace(ns: str) -> str:
    """``ns`` if it is a valid namespace, else ValueError naming it."""
    if not isinstance(ns, str) or not _NS_RE.fullmatch(ns):
        raise ValueError(f"namespace {ns!r} must be /-separated chunks of [A-Za-z0-9_-]")
    return ns


def rig_key(rig_id: str, leaf: str, ns: str = DEFAULT_NAMESPACE) -> str:
    """``<ns>/rig/<rig_id>/<leaf>``; ValueError for an id or namespace outside the contract."""
    if not valid_rig_id(rig_id):
        raise ValueError(f"rig id {rig_id!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return f"{check_namespace(ns)}/rig/{rig_id}/{leaf}"


def sample_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "sample", ns)


def frame_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "frame", ns)


def health_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "health", ns)


def config_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "config", ns)


def event_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "event", ns)


def ranges_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return rig_key(rig_id, "ranges", ns)


def liveliness_key(node: str, ns: str = DEFAULT_NAMESPACE) -> str:
    """``<ns>/monitor/<node>``: a monitor's liveliness token."""
    if not valid_rig_id(node):
        raise ValueError(f"node name {node!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return f"{check_namespace(ns)}/monitor/{node}"


def monitor_of_token(key: str) -> str | None:
    """The node name of a liveliness token ``<ns>/monitor/<node>`` (the key as heard), or None when
    its last chunk is no node name (``liveliness_key``'s rule): such a token is no monitor."""
    node = key.rsplit("/", 1)[-1]
    return node if valid_rig_id(node) else None


def failover_key(group: str, ns: str = DEFAULT_NAMESPACE) -> str:
    """``<ns>/failover/<group>``: under it, a liveliness token ``<claim>-<node>`` of the monitor of
    failover group ``group`` that publishes (``hydromon.bus.failover``)."""
    if not valid_rig_id(group):
        raise ValueError(f"failover group {group!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return f"{check_namespace(ns)}/failover/{group}"


def rig_key_parts(key: str, ns: str | None = DEFAULT_NAMESPACE) -> tuple[str, str, str] | str:
    """``(namespace, rig_id, leaf)`` of a rig key of the contract, else why not: a message
    starting with ``bad-key:`` (not a rig key) or ``bad-rig-id:`` (the layout, but an id
    outside the contract's). ``ns`` None takes a rig key under any namespace (the topics of a
    recording), the last ``rig`` chunk being the one of the layout."""
    if ns is not None:
        prefix = f"{ns}/rig/"
        if not key.startswith(prefix):
            return f"bad-key: not under {prefix}"
        parts = key[len(prefix):].split("/")
        namespace = ns
    else:
        chunks = key.split("/")
        if len(chunks) < 3 or chunks[-3] != "rig":
            return "bad-key: not <ns>/rig/<id>/<leaf>"
        namespace, parts = "/".join(chunks[:-3]), chunks[-2:]
    if len(parts) != 2 or parts[1] not in LEAVES:
        return f"bad-key: expected <ns>/rig/<id>/{'|'.join(LEAVES)}"
    if not valid_rig_id(parts[0]):
        return f"bad-rig-id: {parts[0][:80]!r} is not 1-64 chars of [A-Za-z0-9_-]"
    return namespace, parts[0], parts[1]


def split_rig_key(key: str, ns: str | None = DEFAULT_NAMESPACE) -> tuple[str, str] | str:
    """``(rig_id, leaf)`` of a rig key under ``ns`` (None: any), else why not
    (:func:`rig_key_parts`)."""
    parts = rig_key_parts(key, ns)
    return parts if isinstance(parts, str) else parts[1:]


def parse_rig_key(key: str, ns: str | None = DEFAULT_NAMESPACE) -> tuple[str, str] | None:
    """``(rig_id, leaf)`` of a rig key under ``ns`` (None: any), else None."""
    parts = rig_key_parts(key, ns)
    return None if isinstance(parts, str) else parts[1:]
