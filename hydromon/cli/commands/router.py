"""``hydromon router``: a zenoh router in this process, for nodes started in client mode."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.stop import stop_on_signals

NAME = "router"
HELP = "run a zenoh router (other nodes --connect to it) until Ctrl-C/SIGTERM or --duration"


def add_arguments(parser) -> None:
    from hydromon.bus.session import DEFAULT_ROUTER_ENDPOINT

    parser.add_argument("--listen", action="append", default=None, metavar="ENDPOINT",
                        help=f"endpoint to listen on (repeatable; default {DEFAULT_ROUTER_ENDPOINT})")
    parser.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                        help="another router to connect to (repeatable)")
    parser.add_argument("--multicast", action="store_true", help="enable multicast scouting (off by default)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")


def run_router(listen, connect=(), multicast: bool = False, duration: float | None = None,
               stop_event: threading.Event | None = None, on_ready=None) -> None:
    """Run a router until ``stop_event`` is set or ``duration`` [s] has passed."""
    from hydromon.bus.session import open_session

    if duration is not None and not duration > 0:
        raise ValueError(f"--duration {duration!r} must be > 0 s")
    stop = stop_event or threading.Event()
    with open_session("router", connect=connect, listen=listen, multicast=multicast) as session:
        if on_ready is not None:
            on_ready(session)
        stop.wait(duration)


def run(args) -> int:
    from hydromon.bus.session import DEFAULT_ROUTER_ENDPOINT

    listen = args.listen or [DEFAULT_ROUTER_ENDPOINT]
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        run_router(listen, args.connect, args.multicast, args.duration, stop,
                   on_ready=lambda s: print(f"hydromon router: {s.zid()} listening on {', '.join(listen)}",
                                            file=sys.stderr, flush=True))
    finally:
        restore_signals()
    print("hydromon router: stopped", file=sys.stderr)
    return 0
