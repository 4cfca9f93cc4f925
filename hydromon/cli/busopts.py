"""The bus options every node command shares, and the session they describe."""

from __future__ import annotations

import argparse
import sys

import zenoh

from hydromon.bus.session import MODES, endpoints, open_session, warn_if_not_connected
from hydromon.contract import DEFAULT_NAMESPACE, check_namespace

__all__ = ["add_bus_arguments", "session_from_args", "isolation_hint"]


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
    meet nobody says so on stderr: :func:`isolation_hint`, and :func:`warn_if_not_connected`
    when its ``--connect`` endpoints reach no node)."""
    check_namespace(args.namespace)
    name = getattr(args, "command", None) or "node"
    hint = isolation_hint(args.mode, args.connect, args.listen, args.multicast)
    if hint is not None:
        print(f"hydromon {name}: warning: {hint}", file=sys.stderr, flush=True)
    session = open_session(args.mode, args.connect, args.listen, args.multicast)
    warn_if_not_connected(session, name, endpoints("connect", args.connect))
    return session
