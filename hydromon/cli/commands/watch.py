"""``hydromon watch``: the latest health of every rig on the bus, worst first (``hydromon.engine.board``)."""

from __future__ import annotations

import sys
import threading
import time

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.stop import stop_on_signals
from hydromon.engine.words import CONFIDENCE_HELP

NAME = "watch"
HELP = ("show the latest health of every rig on the bus, the rigs that need attention first and the "
        "parameters that set their grade (asks the running monitors, then follows <namespace>/rig/*/health), "
        "and the latest grade and status changes (<namespace>/rig/*/event)")
DESCRIPTION = (f"{HELP}. Columns: {CONFIDENCE_HELP}. "
               "Age: seconds since the verdict was published (- when only the monitor's answer was seen, of "
               "unknown age).")
EXAMPLES = (
    'hydromon watch --once --mode client --connect tcp/127.0.0.1:7447',
    "hydromon watch --rigs 'line1-*' --top 20",
)

DEFAULT_TOP = 40
PLAIN_EVERY_S = 5.0


def add_arguments(parser) -> None:
    parser.add_argument("--rigs", default="*", metavar="PATTERN",
                        help="only rigs whose id matches this key-expression chunk, e.g. 'line1-*' (default all)")
    parser.add_argument("--once", action="store_true",
                        help="ask the monitors for their latest health, listen up to --wait seconds for the verdicts "
                             "they publish (which give each its age), print and exit; exit status 0 when every rig "
                             "is graded with status ok, 1 when one is not (bad-input, uncalibrated, stale, "
                             "converging) or no monitor answered")
    parser.add_argument("--json", action="store_true",
                        help="with --once: print {\"rigs\": {id: health}, \"counts\": {grade: n}} on stdout")
    parser.add_argument("--wait", type=float, default=2.0, metavar="S",
                        help="how long the monitors have to answer the query for their latest health (default 2)")
    parser.add_argument("--top", type=int, default=DEFAULT_TOP, metavar="N",
                        help=f"rows shown, the rigs that need attention first (default {DEFAULT_TOP}; 0 = all)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    parser.add_argument("--plain", action="store_true",
                        help=f"print a plain table every {PLAIN_EVERY_S:g} s even on a terminal")
    add_bus_arguments(parser)


def run(args) -> int:
    import orjson
    import zenoh

    from hydromon.cli import checks
    from hydromon.contract import check_namespace, monitor_of_token
    from hydromon.engine.board import Board
    from hydromon.report.board import render_board_plain, render_board_rich

    checks.positive("--wait", args.wait)
    checks.positive("--duration", args.duration)
    checks.at_least("--top", args.top, 0)
    if args.json and not args.once:
        raise ValueError("--json needs --once (the live board is for people; --once --json for scripts)")
    if args.once and args.duration is not None:
        raise ValueError("--duration has no effect with --once (which waits --wait seconds for answers)")
    check_namespace(args.namespace)
    chunk = checks.rigs_pattern("--rigs", args.rigs)
    key = f"{args.namespace}/rig/{chunk}/health"
    top = args.top or None
    board = Board(ns=args.namespace)
    ages = Ages(board)
    clock = time.monotonic
    start = clock()
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        with session_from_args(args) as session:
            # the monitors alive now, and (following) their tokens coming and going: a verdict is
            # shown only from a live monitor, and a rig whose monitor is gone says so
            monitors = f"{args.namespace}/monitor/*"
            for reply in session.liveliness().get(monitors, timeout=min(args.wait, 2.0)):
                if reply.ok is not None and (node := monitor_of_token(str(reply.ok.key_expr))) is not None:
                    board.monitor(node, True)
            live = None if args.once else session.liveliness().declare_subscriber(
                monitors, zenoh.handlers.FifoChannel(10_000), history=True)
            # subscribe first: a verdict published while the query runs is not missed
            sub = session.declare_subscriber(key, zenoh.handlers.FifoChannel(100_000))
            events = None if args.once else session.declare_subscriber(
                f"{args.namespace}/rig/{chunk}/event", zenoh.handlers.FifoChannel(10_000))
            # every monitor answers for the rigs it holds (sharded monitors each for theirs)
            for reply in session.get(key, timeout=args.wait):
                if reply.ok is not None and reply.ok.key_expr is not None:
                    ages.update(str(reply.ok.key_expr), reply.ok.payload.to_bytes(), clock(), published=False)
                if stop.is_set():
                    break
            if args.once:
                _listen(sub, ages, stop, clock, start + args.wait)
                return _print_once(board, ages, args, orjson, render_board_plain, clock(), top)
            if not board.latest:
                print(f"hydromon watch: no monitor answered in {args.wait:g} s; following {key} for the next "
                      "verdicts (is a monitor running on this namespace, and reachable?)", file=sys.stderr, flush=True)
            _follow((sub, events), live, ages, args, stop, clock, top, render_board_plain, render_board_rich, key)
            for decl in (sub, events, live):
                decl.undeclare()
    finally:
        restore_signals()
    print(render_board_plain(board, clock(), top, ages.since))
    return 0


class Ages:
    """The board, and when each rig's current verdict was published by the clock of this watch
    (``since``; None: unknown). A monitor's answer to the query is its last verdict, of unknown
    age; a verdict published while watch listens is as old as its arrival, and a re-send of the
    same verdict (a silent rig's, marked stale) keeps the age it had."""

    def __init__(self, board):
        self.board = board
        self.since: dict[str, float | None] = {}
        self._verdict: dict[str, tuple] = {}

    def update(self, key: str, payload: bytes, now: float, published: bool = True) -> None:
        from hydromon.contract import split_rig_key

        if not self.board.update(key, payload, now):
            return
        rig = split_rig_key(key, self.board.ns)[0]
        h = self.board.latest[rig]
        verdict = (h.get("seq"), h.get("t"), h.get("node"), h.get("epoch"))
        if verdict == self._verdict.get(rig) and self.since.get(rig) is not None:
            return  # the same verdict again: its age goes on
        self._verdict[rig] = verdict
        self.since[rig] = now if published else None


def _listen(sub, ages, stop, clock, until) -> None:
    """Take the verdicts published until every rig that is not silent (stale, or its monitor
    gone) has published one, or ``until``: their ages."""
    from hydromon.engine.board import NO_MONITOR

    while not stop.is_set():
        while (m := sub.try_recv()) is not None:
            ages.update(str(m.key_expr), m.payload.to_bytes(), clock())
        board = ages.board
        silent = ("stale", NO_MONITOR)
        waiting = [r for r in board.latest if board.status(r) not in silent and ages.since.get(r) is None]
        if not waiting or clock() >= until:
            return
        stop.wait(0.05)


def _print_once(board, ages, args, orjson, render_plain, now, top) -> int:
    from hydromon.cli.exits import exit_status
    from hydromon.engine.board import NO_MONITOR

    if args.json:
        counts = board.grade_counts()
        print(orjson.dumps({"rigs": dict(sorted(board.latest.items())), "counts": dict(sorted(counts.items())),
                            "invalid": board.invalid, "not_shown": board.not_shown,
                            "no_monitor": sorted(r for r in board.latest if board.status(r) == NO_MONITOR)}).decode())
    elif board.latest:  # an empty table says nothing the error below does not
        print(render_plain(board, now, top, ages.since))
    if not board.latest:
        print(f"hydromon watch: no monitor answered with a rig's health in {args.wait:g} s (is one running on "
              f"namespace {args.namespace!r}, and reachable? --connect ENDPOINT)", file=sys.stderr)
        return 1
    return exit_status(board.status(r) for r in board.latest)


def _follow(subs, live, ages, args, stop, clock, top, render_plain, render_rich, key) -> None:
    """Take every verdict, event and monitor's coming and going as they come (``subs``: the health
    and event subscribers); redraw the board until Ctrl-C or --duration."""
    import zenoh

    from hydromon.contract import monitor_of_token

    board = ages.board
    deadline = None if args.duration is None else clock() + args.duration

    def drain():
        while (m := live.try_recv()) is not None:
            if (node := monitor_of_token(str(m.key_expr))) is not None:
                board.monitor(node, m.kind == zenoh.SampleKind.PUT)
        while (m := subs[0].try_recv()) is not None:
            ages.update(str(m.key_expr), m.payload.to_bytes(), clock())
        while (m := subs[1].try_recv()) is not None:
            board.event(str(m.key_expr), m.payload.to_bytes(), clock())

    def done():
        return stop.is_set() or (deadline is not None and clock() >= deadline)

    title = f"hydromon watch - {key} (Ctrl-C to stop)"
    if not args.plain and sys.stdout.isatty():
        from rich.console import Console
        from rich.live import Live

        console = Console()
        with Live(render_rich(board, clock(), top, title, console.width, ages.since), console=console,
                  refresh_per_second=2, transient=True) as screen:  # not "live": drain() reads that one
            while not done():
                stop.wait(0.5)
                drain()
                screen.update(render_rich(board, clock(), top, title, console.width, ages.since))
        drain()
        return
    next_print = clock()
    while not done():
        drain()
        if clock() >= next_print:
            next_print += PLAIN_EVERY_S
            print(render_plain(board, clock(), top, ages.since) + "\n", flush=True)
        stop.wait(0.2)
    drain()
