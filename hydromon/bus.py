"""Zenoh plumbing shared by every node: sessions from flags, JSON payloads, test endpoints.

Nodes take an open ``zenoh.Session`` (STYLE.md 8); this module is how the CLI makes one.
Multicast scouting is off unless asked for, so a node only talks to the endpoints it is
given (``--connect``/``--listen``) and tests on loopback never meet strangers.
"""

from __future__ import annotations

import argparse
import json
import sys
import socket
from collections.abc import Iterable

import orjson
import zenoh

from hydromon.contract import DEFAULT_NAMESPACE, _check_ns

__all__ = [
    "MODES", "JSON", "open_session", "make_config", "free_tcp_endpoint", "add_bus_arguments",
    "session_from_args", "dumps", "loads", "DEFAULT_ROUTER_ENDPOINT",
]

MODES = ("peer", "client", "router")
DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
JSON = zenoh.Encoding.APPLICATION_JSON
"""Encoding of every contract payload (DESIGN.md section 3)."""


def _endpoints(name: str, values: Iterable[str] | str | None) -> list[str]:
    if values is None:
        return []
    if isinstance(values, str):
        values = [values]
    out = []
    for v in values:
        if not isinstance(v, str) or "/" not in v or not v.split("/", 1)[1]:
            raise ValueError(f"{name} endpoint {v!r}: expected PROTO/ADDRESS, e.g. tcp/127.0.0.1:7447")
        out.append(v)
    return out


def make_config(mode: str = "peer", connect: Iterable[str] = (), listen: Iterable[str] = (),
                multicast: bool = False) -> zenoh.Config:
    """A ``zenoh.Config`` for ``mode`` (peer|client|router) with the given endpoints.

    Parameters
    ----------
    connect, listen : iterable of str
        Zenoh endpoints such as ``tcp/127.0.0.1:7447``.
    multicast : bool
        Enable multicast scouting (off by default: nodes meet only through the explicit
        endpoints; a peer given no ``listen`` still listens on a random port of every
        interface, zenoh's default, which no other node can know).
    """
    if mode not in MODES:
        raise ValueError(f"zenoh mode {mode!r}: choose one of {', '.join(MODES)}")
    connect, listen = _endpoints("connect", connect), _endpoints("listen", listen)
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(multicast)))
    return conf


def open_session(mode: str = "peer", connect: Iterable[str] = (), listen: Iterable[str] = (),
                 multicast: bool = False) -> zenoh.Session:
    """Open a zenoh session (see :func:`make_config`); close it with ``with`` or ``.close()``.

    ConnectionError (one line: the mode, the endpoints and zenoh's reason) if zenoh cannot open
    it: a client whose router is not up (zenoh does not wait for it), a port already in use.
    """
    connect, listen = _endpoints("connect", connect), _endpoints("listen", listen)
    conf = make_config(mode, connect, listen, multicast)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        where = "".join(f", {name} {', '.join(eps)}" for name, eps in (("connect", connect), ("listen", listen)) if eps)
        reason = str(exc).split("  at ")[0].strip()  # without the Rust source location
        raise ConnectionError(f"cannot open the zenoh session ({mode}{where}): {reason}") from None


def free_tcp_endpoint(host: str = "127.0.0.1") -> str:
    """``tcp/HOST:PORT`` for a port that was free a moment ago (for tests on loopback)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port = s.getsockname()[1]
    return f"tcp/{host}:{port}"


def add_bus_arguments(parser: argparse.ArgumentParser, default_mode: str = "peer") -> None:
    """Add ``--mode``, ``--connect``, ``--listen``, ``--namespace`` and ``--multicast``."""
    g = parser.add_argument_group("bus (zenoh)")
    g.add_argument("--mode", choices=MODES, default=default_mode, help=f"zenoh mode (default {default_mode})")
    g.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    g.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    g.add_argument("--namespace", default=DEFAULT_NAMESPACE,
                   help=f"key expression prefix (default {DEFAULT_NAMESPACE!r})")
    g.add_argument("--multicast", action="store_true", help="enable multicast scouting (off by default)")


def isolation_hint(mode: str, connect, listen, multicast: bool) -> str | None:
    """Why a node with these flags will meet no other node, or None. A peer or client with no
    endpoint and no multicast scouting is alone: two nodes started with default flags each wait
    for the other, and nothing says so."""
    if mode == "router" or connect or listen or multicast:
        return None
    return ("no --connect, --listen or --multicast: this node will meet no other node (e.g. --listen "
            "tcp/127.0.0.1:7447 on one node and --connect tcp/127.0.0.1:7447 on the others, "
            "or --multicast on all)")


def session_from_args(args: argparse.Namespace) -> zenoh.Session:
    """Open the session described by the flags of :func:`add_bus_arguments` (a node that will
    meet nobody says so on stderr: :func:`isolation_hint`)."""
    _check_ns(args.namespace)
    hint = isolation_hint(args.mode, args.connect, args.listen, args.multicast)
    if hint is not None:
        print(f"hydromon {getattr(args, 'command', None) or 'node'}: warning: {hint}", file=sys.stderr, flush=True)
    return open_session(args.mode, args.connect, args.listen, args.multicast)


def dumps(obj) -> bytes:
    """JSON bytes of a payload (a dict of plain numbers/strings, or a pydantic model)."""
    if hasattr(obj, "model_dump"):
        obj = obj.model_dump(mode="json")
    return orjson.dumps(obj)


def loads(data) -> object:
    """Parse JSON from bytes, str or a ``zenoh.ZBytes``; raise ValueError on bad JSON."""
    if isinstance(data, zenoh.ZBytes):
        data = data.to_bytes()
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError as exc:
        raise ValueError(f"payload is not JSON: {exc}") from None
