"""``hydromon demo``: simulated rigs, monitor and recorder in one process; live grades."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.stop import stop_on_signals
from hydromon.engine.words import CONFIDENCE_HELP

NAME = "demo"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
HELP = ("everything in one process on an embedded zenoh session: simulated rigs, monitor, recorder and the "
        "web dashboard; shows the live grades and the dashboard's URL, and writes an MCAP recording")
DESCRIPTION = f"{HELP}. Columns: {CONFIDENCE_HELP}."
EXAMPLES = (
    'hydromon demo --duration 10',
    'hydromon demo --fleet plant.toml --out recordings/',
)


def add_arguments(parser) -> None:
    parser.add_argument("--duration", type=float, default=30.0, metavar="S",
                        help="wall time to run [s] (default 30; 0 = until Ctrl-C)")
    parser.add_argument("--out", default=".", metavar="DIR",
                        help="directory of the recording demo-<UTC time>.mcap (default .)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="simulation speed relative to real time, 0 = as fast as possible (default 1)")
    parser.add_argument("--fleet", metavar="FILE",
                        help="fleet file (.toml or .json) of the rigs (default: the paper's Table 4 rigs)")
    parser.add_argument("--namespace", default="hydro", help="key expression prefix (default 'hydro')")
    parser.add_argument("--plain", action="store_true",
                        help="print a plain table every few seconds even on a terminal")
    parser.add_argument("--zenoh-config", metavar="FILE", default=None,
                        help="zenoh's own JSON5 configuration file for the embedded session (TLS, access "
                             "control...); where it names no listen or connect endpoint the session listens on "
                             "a free loopback port")
    parser.add_argument("--dashboard-port", type=int, default=0, metavar="PORT",
                        help="port of the web dashboard on 127.0.0.1 (default 0: a free one; its URL is printed)")
    parser.add_argument("--no-dashboard", action="store_true", help="run without the web dashboard")
    parser.add_argument("--foxglove-port", type=int, default=None, metavar="PORT",
                        help="also serve the bus to Foxglove on this port of 127.0.0.1 (0 = a free one; default: not)")


def _dashboard(args):
    """``attach`` of :func:`hydromon.bus.demo.run_demo`: the dashboard (and Foxglove bridge) on the
    demo's session, graded on the ranges the demo's monitor uses."""
    def attach(session, namespace):
        from hydromon.dashboard.service import open_live
        from monitor.ranges import Ranges

        dash = open_live(session, namespace=namespace, port=args.dashboard_port, fallback_ranges=Ranges.default(),
                         wait_s=0.5, foxglove_port=args.foxglove_port)
        lines = [f"dashboard: {dash.url}"]
        if dash.foxglove is not None:
            lines.append(f"Foxglove: {dash.foxglove.address} (layout: docs/dashboard.md)")
        return dash.close, lines
    return attach


def run(args) -> int:
    from hydromon.cli import checks
    from hydromon.contract import check_namespace
    from hydromon.report.demo import summary
    from hydromon.bus.demo import run_demo
    from hydromon.store.fleetfile import default_fleet, load_fleet

    checks.non_negative("--duration", args.duration, unit="s")
    checks.non_negative("--rate", args.rate)
    check_namespace(args.namespace)
    checks.writable_dir("--out", args.out)
    if args.zenoh_config is not None:
        from hydromon.bus.session import load_config_file

        load_config_file(args.zenoh_config)  # a bad file: one line, before the kernels load
    checks.port("--dashboard-port", args.dashboard_port)
    checks.port("--foxglove-port", args.foxglove_port)
    if args.no_dashboard and args.foxglove_port is not None:
        raise ValueError("--foxglove-port is served beside the dashboard; drop --no-dashboard")
    spec = load_fleet(args.fleet) if args.fleet else default_fleet()
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        result = run_demo(duration=args.duration or None, out_dir=args.out, rate=args.rate,
                          namespace=args.namespace, fleet=spec, stop_event=stop,
                          live=False if args.plain else None, zenoh_config=args.zenoh_config,
                          attach=None if args.no_dashboard else _dashboard(args))
    finally:
        restore_signals()
    print(summary(result, spec.ids))
    c = result.counters
    rejected = sum(c["rejected"].values())
    print(f"hydromon demo: monitor took {c['accepted']} samples, {c['health']} verdicts; rejected {rejected}, "
          f"gaps {c['gaps']}, dropped seq {c['duplicate'] + c['out_of_order']}", file=sys.stderr)
    return 0
