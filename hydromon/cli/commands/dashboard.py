"""``hydromon dashboard``: the fleet in a web browser (``hydromon.dashboard``)."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.ranges import add_ranges_argument
from hydromon.cli.stop import stop_on_signals

NAME = "dashboard"
HELP = ("a web page of every rig, worst first, why and since when; each rig's parameters over time "
        "against its health bands; the grade and status changes, to acknowledge (asks the running "
        "monitors, then follows <namespace>/rig/*/health and /event; read-only; or --recording FILE)")
EXAMPLES = (
    'hydromon dashboard --mode client --connect tcp/127.0.0.1:7447',
    'hydromon dashboard --recording tour.mcap --port 8051',
)
DEFAULT_PORT = 8050


def add_arguments(parser) -> None:
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to serve on (default 127.0.0.1: this machine only; the pages are read-only "
                             "and unauthenticated, so serve another address only on a trusted network)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"TCP port to serve on (default {DEFAULT_PORT}; 0 = a free one)")
    parser.add_argument("--foxglove-port", type=int, default=None, metavar="PORT",
                        help="also serve the Foxglove WebSocket protocol on this port of --host (0 = a free one; "
                             "default: not served; `hydromon foxglove` serves it alone)")
    parser.add_argument("--rigs", default="*", metavar="PATTERN",
                        help="only rigs whose id matches this key-expression chunk, e.g. 'line1-*' (default all)")
    parser.add_argument("--recording", metavar="FILE",
                        help="show an MCAP recording (its health and events) instead of the bus")
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--state-dir", metavar="DIR",
                   help="directory of the dashboard's event log dashboard-events-<namespace>.jsonl (default "
                        "$XDG_STATE_HOME/hydromon, else ~/.local/state/hydromon)")
    g.add_argument("--events-file", metavar="FILE",
                   help="the dashboard's event log (JSON lines: the events heard and their acknowledgements)")
    parser.add_argument("--wait", type=float, default=2.0, metavar="S",
                        help="how long the monitors have to answer the query for their latest health (default 2)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    add_ranges_argument(parser, help="health ranges drawn and put in words for a rig whose monitor does not answer "
                                     "the ranges query: paper, default or a JSON file (default: none)")
    add_bus_arguments(parser)


def run(args) -> int:
    from hydromon.cli import checks
    from hydromon.cli.ranges import ranges_from_args
    from hydromon.contract import check_namespace
    from hydromon.dashboard.service import default_events_path, open_live, open_recording

    checks.positive("--wait", args.wait)
    checks.positive("--duration", args.duration)
    checks.port("--port", args.port)
    checks.port("--foxglove-port", args.foxglove_port)
    check_namespace(args.namespace)
    chunk = checks.rigs_pattern("--rigs", args.rigs)
    fallback = ranges_from_args(args)
    if args.recording:
        if args.events_file or args.state_dir:
            raise ValueError("--recording shows the recording's events; --events-file/--state-dir are for the bus")
        if args.foxglove_port is not None:
            raise ValueError("--foxglove-port serves the bus; open a recording in Foxglove itself "
                             "(docs/dashboard.md)")
        dash = open_recording(args.recording, host=args.host, port=args.port, fallback_ranges=fallback)
        node = None
    else:
        events = args.events_file or default_events_path(args.state_dir, args.namespace)
        if args.events_file:
            checks.writable_file("--events-file", args.events_file)
        node = session_from_args(args)  # closed with its connectivity log
        try:
            dash = open_live(node.session, namespace=args.namespace, rigs=chunk, host=args.host, port=args.port,
                             events_path=events, fallback_ranges=fallback, wait_s=args.wait,
                             foxglove_port=args.foxglove_port)
        except BaseException:
            node.close()
            raise
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        what = f"recording {args.recording}" if args.recording else f"{args.namespace}/rig/{chunk}/health"
        print(f"hydromon dashboard: {dash.url} ({what}; Ctrl-C to stop)", file=sys.stderr, flush=True)
        if args.recording and dash.web.info.get("verdicts") == 0:
            print(f"hydromon dashboard: {args.recording} holds no health verdicts (recorded without a monitor on "
                  f"the bus): grade it with hydromon evaluate {args.recording}", file=sys.stderr, flush=True)
        if dash.foxglove is not None:
            print(f"hydromon dashboard: Foxglove: {dash.foxglove.address}", file=sys.stderr, flush=True)
        stop.wait(args.duration)
    finally:
        restore_signals()
        dash.close()
        if node is not None:
            node.close()
    print("hydromon dashboard: stopped", file=sys.stderr)
    return 0
