"""``hydromon replay FILE``: a recording back onto the bus, or straight into the monitor."""

from __future__ import annotations

import sys
import threading

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.memory import LIVE_MEMORY_S, MEMORY_HELP, add_memory_argument, check_memory, options_from_args
from hydromon.cli.ranges import RANGES_HELP, add_ranges_argument, ranges_from_args
from hydromon.cli.stop import stop_on_signals

NAME = "replay"
HELP = "publish an MCAP recording on the bus (paced), or grade it in-process with --direct"
EXAMPLES = (
    'hydromon replay tour.mcap --rate 10',
    'hydromon replay recordings/table4-realistic.mcap --direct --out replayed.jsonl',
)


def KERNELS(args) -> bool:  # noqa: N802 (read by hydromon.cli.main like the other commands' flag)
    """--direct grades in-process with the compiled kernels; publishing needs none."""
    return bool(args.direct)


# the bus replay's defaults; the options stay None when not given, so --direct can refuse them
DEFAULT_RATE = 1.0
DEFAULT_WAIT_S = 3.0


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="an MCAP recording")
    parser.add_argument("--rate", type=float, default=None,
                        help=f"speed relative to the recording, 0 = as fast as possible (default {DEFAULT_RATE:g})")
    parser.add_argument("--keys", action="append", default=None, metavar="KEYEXPR",
                        help="replay only topics matching this zenoh key expression, e.g. 'hydro/rig/*/sample' "
                        "('*' one chunk, '**' any chunks; repeatable; default: everything, recorded verdicts "
                        "included: to re-grade with a live monitor give --keys 'hydro/rig/*/sample' "
                        "--keys 'hydro/rig/*/frame' --keys 'hydro/rig/*/config')")
    parser.add_argument("--start", type=float, default=None, metavar="S",
                        help="start this many seconds after the recording's first message")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="replay this many seconds of the recording")
    parser.add_argument("--loop", action="store_true", help="play the window again and again until Ctrl-C")
    parser.add_argument("--wait", type=float, default=None, metavar="S",
                        help=f"wait up to S seconds for a subscriber before sending (default {DEFAULT_WAIT_S:g})")
    parser.add_argument("--quiet", action="store_true", help="no progress bar (with --direct too)")
    parser.add_argument("--direct", action="store_true",
                        help="no bus: run the monitor in-process over the recording as fast as possible and "
                        "print the health sequence as JSON lines (or write it to --out)")
    parser.add_argument("--out", metavar="FILE", help="with --direct: write the health JSON lines here")
    parser.add_argument("--jobs", type=int, default=None, metavar="N",
                        help="with --direct: grade in N processes, the rigs split between them; the same "
                        "health, in the same order (default 1)")
    add_ranges_argument(parser, f"with --direct: {RANGES_HELP}; give the live monitor's to get its health "
                                "byte for byte")
    add_memory_argument(parser, f"with --direct: {MEMORY_HELP} (default: none, a growing window, with which the "
                                "golden recordings were graded live; give the live monitor's, --memory "
                                f"{LIVE_MEMORY_S:g} by default, to get its health byte for byte)")
    add_bus_arguments(parser)


def check_args(args) -> None:
    """Every option's check, before the recording is read, the bus opened or a bar shown."""
    from hydromon.cli import checks
    from hydromon.contract import check_namespace
    from hydromon.store.replay import KeyFilter

    checks.non_negative("--start", args.start, unit="s")
    checks.non_negative("--duration", args.duration, unit="s")
    check_namespace(args.namespace)
    KeyFilter(args.keys)  # a bad --keys expression
    if args.direct:
        # it grades as fast as it can, with no bus: pacing and waiting for subscribers do not apply
        for opt, given in (("--loop", args.loop), ("--rate", args.rate is not None), ("--wait", args.wait is not None)):
            if given:
                raise ValueError(f"{opt} has no meaning with --direct")
        if args.out:
            checks.writable_file("--out", args.out)
        checks.at_least("--jobs", args.jobs, 1)
    else:
        checks.non_negative("--rate", args.rate)
        checks.non_negative("--wait", args.wait, unit="s")
        if args.out:
            raise ValueError("--out goes with --direct (a bus replay publishes; record it with hydromon record)")
        for opt, value in (("--ranges", args.ranges), ("--memory", args.memory), ("--jobs", args.jobs)):
            if value is not None:
                raise ValueError(f"{opt} goes with --direct (a bus replay publishes samples; the monitor grades them)")
    check_memory(args)


def _direct(args) -> int:
    from hydromon.cli.checks import replace_on_success
    from hydromon.engine.watches import RateLimitedLog
    from hydromon.engine.core import MonitorCore
    from hydromon.store.replay import NothingToReplay, check_window, health_jsonl, nothing_graded
    from hydromon.store.replay_jobs import replay_direct_jobs

    check_window(args.file, keys=args.keys, start=args.start, namespace=args.namespace)
    ranges, options = ranges_from_args(args), options_from_args(args, MonitorCore.SAMPLE_RATE)

    def make_core():
        return MonitorCore(args.namespace, on_reject=RateLimitedLog(), ranges=ranges, options=options)

    def grade(progress=None):
        return replay_direct_jobs(args.file, jobs=args.jobs or 1, keys=args.keys, start=args.start,
                                  duration=args.duration, namespace=args.namespace, make_core=make_core,
                                  progress=progress)

    if args.quiet:
        health, core = grade()
    else:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        # no refresh thread: --jobs forks workers, best from a process with one thread
        with Progress(TextColumn("grading"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total:.0f} s"),
                      TimeElapsedColumn(), console=Console(stderr=True), transient=True, auto_refresh=False) as bar:
            task = bar.add_task("grading", total=0)

            def show(done, total):
                bar.update(task, completed=done, total=total)
                bar.refresh()

            health, core = grade(show)
    why = nothing_graded(args.file, health, core.counters)
    if why:
        raise NothingToReplay(why)  # before --out: no empty health file
    if args.out:
        with replace_on_success(args.out, "wb") as f:
            f.writelines(health_jsonl(health))
    else:
        out = sys.stdout.buffer
        out.writelines(health_jsonl(health))
        out.flush()
    import orjson

    c = core.counters
    print(f"hydromon replay: {c.accepted} samples of {len(core.rigs)} rig(s), {len(health)} health messages"
          + (f" -> {args.out}" if args.out else ""), file=sys.stderr)
    for rig in sorted(core.latest):
        h = orjson.loads(core.latest[rig])
        print(f"  {rig}: {h['grade']} (confidence {h['confidence']:.2f}, {h['status']}, seq {h['seq']})",
              file=sys.stderr)
    rejected = {k: v for k, v in c.rejected.items() if v}
    if rejected or c.dropped_seq or c.gaps:
        print(f"  rejected {rejected or 'none'}; dropped seq {c.dropped_seq}; gaps {c.gaps} "
              f"({c.missing} samples missing); restarts {c.restarts}", file=sys.stderr)
    return 0


def run(args) -> int:
    check_args(args)
    if args.direct:
        return _direct(args)
    from hydromon.bus.replay import replay_bus
    from hydromon.store.replay import (
        NothingToReplay, check_window, recording_span, recording_topics, sample_namespaces,
    )

    check_window(args.file, keys=args.keys, start=args.start)  # a bad file fails here, before the session opens
    recorded = sample_namespaces(recording_topics(args.file))
    if recorded and args.namespace not in recorded:  # the keys go out as recorded: say where
        print(f"hydromon replay: note: {args.file} was recorded under namespace {', '.join(recorded)}, and its "
              f"messages go out under it, not {args.namespace}: a monitor must run with --namespace "
              f"{recorded[0]} to grade them", file=sys.stderr)
    first, last, _ = recording_span(args.file)
    total = max(0.0, (last - first) / 1e9 - (args.start or 0.0))
    if args.duration is not None:
        total = min(total, args.duration)
    rate = DEFAULT_RATE if args.rate is None else args.rate
    wait_s = DEFAULT_WAIT_S if args.wait is None else args.wait
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        with session_from_args(args) as session:
            if args.quiet:
                stats = replay_bus(session, args.file, rate=rate, keys=args.keys, start=args.start,
                                   duration=args.duration, loop=args.loop, stop_event=stop, wait_s=wait_s)
            else:
                from rich.console import Console
                from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

                with Progress(TextColumn("replay"), BarColumn(), TextColumn("{task.completed:.1f}/{task.total:.1f} s"),
                              TimeElapsedColumn(), console=Console(stderr=True)) as bar:
                    task = bar.add_task("replay", total=total)
                    stats = replay_bus(session, args.file, rate=rate, keys=args.keys, start=args.start,
                                       duration=args.duration, loop=args.loop, stop_event=stop, wait_s=wait_s,
                                       progress=lambda done, total: bar.update(task, completed=done, total=total))
    finally:
        restore_signals()
    stopped = "" if stats.stopped_at is None else \
        f", stopped (Ctrl-C/SIGTERM) {stats.stopped_at:.1f} s into a pass of {total:.1f} s"
    print(f"hydromon replay: {stats.published} messages on {len(stats.keys)} key(s), {stats.passes} pass(es)"
          f"{stopped} in {stats.wall:.2f} s; max lateness {stats.max_late * 1e3:.1f} ms", file=sys.stderr)
    if stats.not_keys:
        topics = sorted(stats.not_keys)
        print(f"hydromon replay: skipped {sum(stats.not_keys.values())} message(s) on {len(topics)} topic(s) that "
              f"are not zenoh keys and cannot be published: {', '.join(repr(t) for t in topics[:5])}"
              + (", ..." if len(topics) > 5 else ""), file=sys.stderr)
    if stats.published == 0 and not stop.is_set():
        raise NothingToReplay(f"{args.file}: no message in the window (--start, --duration, --keys): nothing sent")
    code = exit_code(stats, args.loop)
    if code:
        print(f"hydromon replay: incomplete: the window was not sent to its end (exit {code})", file=sys.stderr)
    return code


def exit_code(stats, loop: bool) -> int:
    """0 when the window went out whole; 1 when a stop (Ctrl-C/SIGTERM) cut a single pass short,
    so that ``hydromon replay F && next-step`` does not go on as if the record had been sent.
    With ``--loop`` a stop is the only way to end, so it is the normal end (0)."""
    return 1 if stats.stopped_at is not None and not loop else 0
