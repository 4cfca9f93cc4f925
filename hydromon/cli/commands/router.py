"""``hydromon router``: a zenoh router in this process, for nodes started in client mode."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.stop import stop_on_signals

NAME = "router"
HELP = "run a zenoh router (other nodes --connect to it) until Ctrl-C/SIGTERM or --duration"
EXAMPLES = (
    'hydromon router --listen tcp/0.0.0.0:7447',
)


def add_arguments(parser) -> None:
    from hydromon.bus.session import DEFAULT_ROUTER_ENDPOINT

    parser.add_argument("--listen", action="append", default=None, metavar="ENDPOINT",
                        help=f"endpoint to listen on (repeatable; default {DEFAULT_ROUTER_ENDPOINT})")
    parser.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                        help="another router to connect to (repeatable)")
    parser.add_argument("--multicast", action="store_true", help="enable multicast scouting (off by default)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    parser.add_argument("--zenoh-config", metavar="FILE", default=None,
                        help="zenoh's own JSON5 configuration file (TLS, access control...); its mode is "
                             "always router; --listen/--connect/--multicast, where given, override what it sets, "
                             f"and without --listen or a listen in the file it listens on {DEFAULT_ROUTER_ENDPOINT}")


def router_config(listen, connect=(), multicast: bool = False, config_file=None):
    """``(config, listen endpoints)`` of the router: the file's (if any) with the given options
    on top; listening on :data:`~hydromon.bus.session.DEFAULT_ROUTER_ENDPOINT` when neither the
    options nor the file say where."""
    from hydromon.bus.session import DEFAULT_ROUTER_ENDPOINT, config_endpoints, make_config

    conf = make_config("router", connect, listen or (), multicast, config_file)
    if not listen and not config_endpoints(conf, "listen", "router"):
        conf = make_config("router", connect, [DEFAULT_ROUTER_ENDPOINT], multicast, config_file)
    return conf, config_endpoints(conf, "listen", "router")


def run_router(listen, connect=(), multicast: bool = False, duration: float | None = None,
               stop_event: threading.Event | None = None, on_ready=None, config_file=None) -> None:
    """Run a router until ``stop_event`` is set or ``duration`` [s] has passed."""
    from hydromon.bus.session import open_session
    from hydromon.cli.busopts import NodeSession

    if duration is not None and not duration > 0:
        raise ValueError(f"--duration {duration!r} must be > 0 s")
    stop = stop_event or threading.Event()
    conf, _ = router_config(listen, connect, multicast, config_file)
    with NodeSession(open_session(config=conf, config_file=config_file), "router", []) as session:
        if on_ready is not None:
            on_ready(session)
        stop.wait(duration)


def run(args) -> int:
    _, listen = router_config(args.listen, args.connect, args.multicast, args.zenoh_config)
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        run_router(args.listen, args.connect, args.multicast, args.duration, stop,
                   on_ready=lambda s: print(f"hydromon router: {s.zid()} listening on {', '.join(listen)}",
                                            file=sys.stderr, flush=True), config_file=args.zenoh_config)
    finally:
        restore_signals()
    print("hydromon router: stopped", file=sys.stderr)
    return 0
