"""``hydromon foxglove``: the bus served to the Foxglove app (``hydromon.dashboard.foxglove_bridge``)."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.ranges import add_ranges_argument
from hydromon.cli.stop import stop_on_signals

NAME = "foxglove"
HELP = ("serve the bus to the Foxglove app (Foxglove WebSocket protocol): every rig's health (with its health "
        "bands), events and config as JSON-Schema channels, samples of the rigs a client subscribes to, and "
        "<namespace>/fleet; open it with the layout the package ships (docs/dashboard.md); read-only")
EXAMPLES = (
    'hydromon foxglove --mode client --connect tcp/127.0.0.1:7447',
)
DEFAULT_PORT = 8765


def add_arguments(parser) -> None:
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to serve on (default 127.0.0.1: this machine only)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"TCP port to serve on (default {DEFAULT_PORT}, Foxglove's; 0 = a free one)")
    parser.add_argument("--rigs", default="*", metavar="PATTERN",
                        help="only rigs whose id matches this key-expression chunk, e.g. 'line1-*' (default all)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    add_ranges_argument(parser, help="health ranges of the bands of a rig whose monitor does not answer the "
                                     "ranges query: paper, default or a JSON file (default: none)")
    add_bus_arguments(parser)


def run(args) -> int:
    from hydromon.cli import checks
    from hydromon.cli.ranges import ranges_from_args
    from hydromon.contract import check_namespace
    from hydromon.dashboard.service import open_live

    checks.positive("--duration", args.duration)
    checks.port("--port", args.port)
    check_namespace(args.namespace)
    chunk = checks.rigs_pattern("--rigs", args.rigs)
    fallback = ranges_from_args(args)
    node = session_from_args(args)  # closed with its connectivity log
    session = node.session
    try:
        dash = open_live(session, namespace=args.namespace, rigs=chunk, host=args.host, port=None,
                         fallback_ranges=fallback, foxglove_port=args.port)
    except BaseException:
        node.close()
        raise
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        print(f"hydromon foxglove: {dash.foxglove.address} ({args.namespace}/rig/{chunk}/*; open it in Foxglove: "
              "Open connection, Foxglove WebSocket; Ctrl-C to stop)", file=sys.stderr, flush=True)
        stop.wait(args.duration)
    finally:
        restore_signals()
        dash.close()
        node.close()
    print("hydromon foxglove: stopped", file=sys.stderr)
    return 0
