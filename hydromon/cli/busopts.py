"""The bus options every node command shares, and the session they describe.

Precedence of a node's zenoh settings, highest first: the options given on the command line
(``--mode``, ``--connect``, ``--listen``, ``--multicast``), then the ``--zenoh-config`` file,
then hydromon's defaults (mode ``peer``, multicast scouting off), then zenoh's own. An option
not given never overrides the file: a file's ``mode``, ``connect`` or ``listen`` stays as
written unless the option is given.
"""

from __future__ import annotations

import argparse
import sys

import zenoh

from hydromon.bus.connectivity import ConnectivityLog
from hydromon.bus.session import MODES, make_config, open_session, summarize_config, warn_if_not_connected
from hydromon.contract import DEFAULT_NAMESPACE, check_namespace

__all__ = ["add_bus_arguments", "add_zenoh_config_argument", "session_from_args", "isolation_hint", "NodeSession",
           "ZENOH_CONFIG_HELP"]

ZENOH_CONFIG_HELP = ("zenoh's own JSON5 configuration file (TLS, access control, timeouts...); "
                     "--mode/--connect/--listen/--multicast, where given, override what it sets")


def add_zenoh_config_argument(parser) -> None:
    parser.add_argument("--zenoh-config", metavar="FILE", default=None, help=ZENOH_CONFIG_HELP)


def add_bus_arguments(parser: argparse.ArgumentParser, default_mode: str = "peer") -> None:
    """Add ``--mode``, ``--connect``, ``--listen``, ``--namespace``, ``--multicast`` and ``--zenoh-config``."""
    g = parser.add_argument_group("bus (zenoh)")
    g.add_argument("--mode", choices=MODES, default=None,
                   help=f"zenoh mode (default: the --zenoh-config file's, else {default_mode})")
    g.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable; replaces the "
                        "--zenoh-config file's)")
    g.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable; replaces the "
                        "--zenoh-config file's)")
    g.add_argument("--namespace", default=DEFAULT_NAMESPACE,
                   help=f"key expression prefix (default {DEFAULT_NAMESPACE!r})")
    g.add_argument("--multicast", action="store_true",
                   help="enable multicast scouting (off by default, unless the --zenoh-config file turns it on)")
    add_zenoh_config_argument(g)
    parser.set_defaults(_default_mode=default_mode)


def isolation_hint(mode: str, connect, listen, multicast: bool) -> str | None:
    """Why a node with these flags will meet no other node, or None. A peer or client with no
    endpoint and no multicast scouting is alone: two nodes started with default flags each wait
    for the other, and nothing says so."""
    if mode == "router" or connect or listen or multicast:
        return None
    return ("no --connect, --listen or --multicast: this node will meet no other node (e.g. --listen "
            "tcp/127.0.0.1:7447 on one node and --connect tcp/127.0.0.1:7447 on the others, "
            "or --multicast on all)")


class NodeSession:
    """A node's open session (``with NodeSession(...) as session``) and what watches it: the
    warning when ``--connect`` reaches nobody, and the log of being cut off and reconnected
    (:class:`~hydromon.bus.connectivity.ConnectivityLog`), stopped before the session closes."""

    def __init__(self, session: zenoh.Session, name: str, connect: list[str]):
        self.session = session
        self.connectivity = ConnectivityLog(session, name)
        self._timer = warn_if_not_connected(session, name, connect, reached=lambda: self.connectivity.reached)

    def __enter__(self) -> zenoh.Session:
        return self.session

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self.connectivity.close()
        self.session.close()


def node_config(args, mode: str | None = None) -> zenoh.Config:
    """The zenoh configuration the options describe (``mode`` forces one, as the router does);
    ValueError on a bad ``--zenoh-config`` file, before anything starts."""
    return make_config(mode or args.mode, args.connect, args.listen, args.multicast,
                       getattr(args, "zenoh_config", None))


def session_from_args(args: argparse.Namespace) -> NodeSession:
    """Open the session described by the flags of :func:`add_bus_arguments` (a node that will
    meet nobody says so on stderr: :func:`isolation_hint`, and :func:`warn_if_not_connected`
    when its ``--connect`` endpoints reach no node); use it as ``with session_from_args(args)
    as session``."""
    check_namespace(args.namespace)
    name = getattr(args, "command", None) or "node"
    if args.mode is None and getattr(args, "zenoh_config", None) is None:
        args.mode = getattr(args, "_default_mode", "peer")
    conf = node_config(args)
    summary = summarize_config(conf)
    hint = isolation_hint(summary.mode, summary.connect, summary.listen, summary.multicast)
    if hint is not None:
        print(f"hydromon {name}: warning: {hint}", file=sys.stderr, flush=True)
    session = open_session(config=conf, config_file=getattr(args, "zenoh_config", None))
    return NodeSession(session, name, summary.connect)
