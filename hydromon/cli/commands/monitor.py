"""``hydromon monitor``: the monitor node (rig samples -> health verdicts on the bus)."""

from __future__ import annotations

import sys
import threading
import time

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.memory import LIVE_MEMORY_S, MEMORY_HELP, add_memory_argument, options_from_args
from hydromon.cli.ranges import add_ranges_argument, ranges_from_args
from hydromon.cli.stop import stop_on_signals

NAME = "monitor"
HELP = "grade every rig on <namespace>/rig/*/sample (and .../frame) and publish <namespace>/rig/<id>/health"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon monitor --mode client --connect tcp/127.0.0.1:7447',
    "hydromon monitor --rigs 'line1-*' --memory 10min",
)


def add_arguments(parser) -> None:
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop after this many seconds (default: until Ctrl-C / SIGTERM)")
    parser.add_argument("--node", default="monitor", metavar="NAME",
                        help="node name of the liveliness token <namespace>/monitor/NAME (default monitor)")
    parser.add_argument("--rigs", default="*", metavar="PATTERN",
                        help="grade only rigs whose id matches this key-expression chunk, e.g. 'line1-*' "
                             "(shard a plant over several monitors; default all)")
    parser.add_argument("--eval-every", type=int, default=10, metavar="N",
                        help="a health message every N samples of a rig (default 10)")
    parser.add_argument("--max-rigs", type=int, default=10000, metavar="N",
                        help="most rigs this monitor holds (about 5 kB each); samples and configs of further "
                             "rig ids are rejected as too-many-rigs (default 10000)")
    parser.add_argument("--stale-after", type=float, default=2.0, metavar="S",
                        help="a rig that sends no sample for S seconds has its latest health re-sent with "
                             "status stale (default 2)")
    parser.add_argument("--forget-after", type=float, default=None, metavar="S",
                        help="a rig that sends no sample for S seconds is forgotten: its estimates and latest "
                             "health are dropped and its place goes to new rigs, so rig ids that come and go "
                             "never fill --max-rigs; if it comes back it starts afresh (default: never)")
    add_ranges_argument(parser)
    parser.add_argument("--ranges-dir", default=None, metavar="DIR",
                        help="a directory of per-rig ranges files <rig-id>.json (hydromon commission writes them): "
                             "each grades its rig, reloaded when it changes (logged); a bad file is refused and "
                             "the rig keeps the ranges it had; rigs without a file take --ranges if made for them")
    parser.add_argument("--commission-new-rigs", type=float, default=None, metavar="S",
                        help="commission a rig that has no ranges from its first S seconds (10 or more) and write "
                             "its ranges into --ranges-dir; its health says commissioning meanwhile. It takes the "
                             "rig as new: a rig already worn would be graded relative to its worn state "
                             "(default: off)")
    parser.add_argument("--state-dir", default=None, metavar="DIR",
                        help="keep a checkpoint of every rig's state in DIR (written every --checkpoint-every "
                             "seconds and at stop, atomically) and resume from it at start: a restarted monitor "
                             "grades on at once, with what it had learnt; a primary and its standbys share DIR")
    parser.add_argument("--checkpoint-every", type=float, default=2.0, metavar="S",
                        help="seconds between checkpoints with --state-dir (default 2)")
    parser.add_argument("--standby", action="store_true",
                        help="start as a standby: take every sample, publish nothing while another monitor of "
                             "the group publishes, take over within a poll of its death (default: publish "
                             "unless another monitor of the group already does)")
    parser.add_argument("--group", default=None, metavar="NAME",
                        help="failover group: of the monitors of one group only the one that claimed first "
                             "publishes (default: one group per --rigs pattern)")
    add_memory_argument(parser, f"{MEMORY_HELP} (default {LIVE_MEMORY_S:g}: a monitor runs for weeks and must "
                                "follow a rig that degrades while it watches)", default=LIVE_MEMORY_S)
    parser.add_argument("--threads", type=int, default=1, metavar="N",
                        help="threads for the estimators when many samples arrive at once (rigs split "
                             "between them; same numbers for any N; default 1)")
    add_bus_arguments(parser)


def run(args) -> int:
    from hydromon.cli import checks
    from hydromon.contract import liveliness_key
    from hydromon.engine.core import MonitorCore
    from hydromon.engine.watches import RateLimitedLog, RigWarningLog
    from hydromon.bus.monitor import run_monitor
    from hydromon.bus.failover import group_name
    from hydromon.contract import valid_rig_id
    from hydromon.store.ranges_dir import RangesDir
    from hydromon.store.state_dir import StateDir

    # every option is checked here, before the bus opens and the banner is printed
    checks.positive("--duration", args.duration)
    checks.at_least("--eval-every", args.eval_every, 1)
    checks.at_least("--threads", args.threads, 1)
    checks.at_least("--max-rigs", args.max_rigs, 1)
    checks.positive("--stale-after", args.stale_after)
    if args.forget_after is not None:
        checks.positive("--forget-after", args.forget_after)
        if args.forget_after <= args.stale_after:
            raise ValueError(f"--forget-after {args.forget_after:g} s must be longer than --stale-after "
                             f"{args.stale_after:g} s (a rig is stale before it is forgotten)")
    liveliness_key(args.node, args.namespace)  # the node name and the namespace
    checks.rigs_pattern("--rigs", args.rigs)
    ranges = ranges_from_args(args)  # a bad file fails here, before the bus
    ranges_dir = RangesDir(args.ranges_dir) if args.ranges_dir is not None else None
    checks.positive("--checkpoint-every", args.checkpoint_every)
    if args.commission_new_rigs is not None:
        from monitor.commission import MIN_SECONDS

        if ranges_dir is None:
            raise ValueError("--commission-new-rigs writes each rig's ranges into --ranges-dir: give one")
        checks.at_least("--commission-new-rigs", args.commission_new_rigs, MIN_SECONDS)
    state_dir = StateDir(args.state_dir) if args.state_dir is not None else None
    group = args.group if args.group is not None else group_name(args.rigs)
    if not valid_rig_id(group):
        raise ValueError(f"--group {group!r}: 1-64 chars of [A-Za-z0-9_-]")
    options = options_from_args(args, MonitorCore.SAMPLE_RATE)
    # the epoch: this start of the node, later than any earlier start of it (ms of the wall clock)
    core = MonitorCore(args.namespace, eval_every=args.eval_every, on_reject=RateLimitedLog(),
                       on_warning=RigWarningLog(), threads=args.threads, ranges=ranges, max_rigs=args.max_rigs,
                       options=options, node=args.node, epoch=time.time_ns() // 1_000_000)
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        with session_from_args(args) as session:
            print(f"hydromon monitor: node {args.node!r} on {args.namespace}/rig/{args.rigs}/sample",
                  file=sys.stderr, flush=True)
            run_monitor(session, namespace=args.namespace, node_name=args.node, stop_event=stop,
                        duration=args.duration, core=core, rigs=args.rigs, stale_after_s=args.stale_after,
                        forget_after_s=args.forget_after, ranges_dir=ranges_dir, state_dir=state_dir,
                        checkpoint_s=args.checkpoint_every, group=group, standby=args.standby,
                        commission_new_s=args.commission_new_rigs)
    finally:
        restore_signals()
    c = core.counters
    rejected = ", ".join(f"{k} {v}" for k, v in c.rejected.items() if v) or "none"
    print(f"hydromon monitor: {len(core.rigs)} rig(s), {c.accepted} samples, {c.health} health messages; "
          f"rejected: {rejected}; dropped seq {c.dropped_seq}, gaps {c.gaps} ({c.missing} samples missing), "
          f"restarts {c.restarts}" + (f"; silent rigs' health re-sent stale {c.stale_resent} time(s)"
                                      if c.stale_resent else "")
          + (f"; {c.forgotten} silent rig(s) forgotten" if c.forgotten else ""), file=sys.stderr)
    for line in (x1_clamped_line(core), units_line(core)):
        if line:
            print(f"hydromon monitor: {line}", file=sys.stderr)
    return 0


def units_line(core) -> str | None:
    """The rigs whose readings broke their config's bounds, for the exit summary (None if none)."""
    flagged = core.units_flagged()
    if not flagged:
        return None
    return ("readings beyond the rig config's bounds (a channel in other units than SI, or a sensor span the "
            "config does not give; their health said bad-input): "
            + ", ".join(f"{rig} in {n} evaluation(s)" for rig, n in flagged.items()))


def x1_clamped_line(core) -> str | None:
    """The rigs whose x1 would have emptied a chamber, for the exit summary (None if none)."""
    clamped = {rig: core.fleet.x1_clamped(r.row) for rig, r in core.rigs.items()}
    clamped = {rig: n for rig, n in sorted(clamped.items()) if n}
    if not clamped:
        return None
    return ("x1 beyond a chamber's end (rig constants A1, A2, V10, V20 or x1's zero, sign or unit wrong; "
            "their chamber parameters are not to be trusted): "
            + ", ".join(f"{rig} {n} sample(s)" for rig, n in clamped.items()))
