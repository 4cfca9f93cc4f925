"""``hydromon sim``: the simulator node (simulated rigs -> bus), or a run into a CSV/MCAP file."""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from contextlib import ExitStack
from pathlib import Path

from hydromon.cli.busopts import add_bus_arguments, session_from_args
from hydromon.cli.stop import stop_on_signals

NAME = "sim"
HELP = "simulate rigs and publish their samples on the bus (or write a run to --to-csv/--to-mcap)"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon sim --noise realistic --mode client --connect tcp/127.0.0.1:7447',
    'hydromon sim --to-csv db.csv --duration 30 --rig table4-g2 --noise realistic --effect valve_dead_band=5um',
)


def add_arguments(parser) -> None:
    from hydromon.store.quantities import EFFECTS, unit_table

    g = parser.add_argument_group("rigs (default: the paper's five Table 4 rigs table4-g1..g5)")
    g.add_argument("--fleet", metavar="FILE", help="fleet file (.toml or .json) listing the rigs")
    g.add_argument("--rigs", type=int, metavar="N",
                   help="N rigs rig-0000.. with severities spread evenly over [0, 1] (random with --seed)")
    g.add_argument("--severity", type=float, metavar="S",
                   help="degradation in [0, 1] of every rig (alone: one rig)")
    g.add_argument("--profile", metavar="SPEC", help="command profile, e.g. paper-var, paper-id, "
                   "steps:low=1.5,high=2.5, file:path=u.csv (default paper-var)")
    g.add_argument("--noise", metavar="MODEL", help="none | realistic | stress | pct:F (default none)")
    g.add_argument("--effect", action="append", default=None, metavar="NAME=MAG",
                   help="effect on every rig, a magnitude with its unit (a bare number is SI), e.g. "
                   "valve_dead_band=2.5um (repeatable; names, SI unit and sensible range: "
                   + "; ".join(f"{n} [{u}] {r}" for n, u, r, _ in unit_table(EFFECTS)) + ")")
    g.add_argument("--sensor-delay-loop", action="store_true", default=None,
                   help="the sensor delay acts inside the control loop too")
    g.add_argument("--seed", type=int, default=None, help="base seed of noise (and random severities)")
    g.add_argument("--controller", metavar="SPEC", default=None,
                   help="every rig's position loop: p (the rig constants' proportional loop, default) or "
                   "pi:ki=K_I,kff=K_FF (a digital PI loop with feed-forward, K_I [1/s], K_FF [s])")
    g.add_argument("--publish-u", action=argparse.BooleanOptionalAction, default=None,
                   help="publish each rig's valve drive u [V] in its samples (default: when its loop is not p)")
    r = parser.add_argument_group("run")
    r.add_argument("--rate", type=float, default=1.0,
                   help="speed relative to real time, 0 = as fast as possible (default 1)")
    r.add_argument("--duration", type=float, default=None, metavar="S",
                   help="rig time to simulate [s] (default: until Ctrl-C; required with --to-*)")
    r.add_argument("--block", type=int, default=None, metavar="K",
                   help="samples per rig per step, >= 1 (default 10)")
    r.add_argument("--frame", type=int, default=None, metavar="N",
                   help="publish frames of N consecutive samples per rig on <namespace>/rig/<id>/frame, one "
                   "message every N samples (1..1000; 10 at 100 Hz is one per 100 ms), instead of one message "
                   "per sample; each rig's frames end at its own phase, so a fleet's frames come spread over "
                   "the N samples; --to-mcap writes frames too (all rigs' on the same samples)")
    r.add_argument("--to-csv", metavar="FILE", help="write the run as CSV t,ug,x1,x3,x4,x5 (SI), no bus: one rig "
                   "into FILE; a fleet of several (without --rig) one file per rig, FILE-<rig>.csv, or DIR/<rig>.csv "
                   "when FILE is a directory (each written to a temporary file beside it, renamed into place when "
                   "complete)")
    r.add_argument("--to-mcap", metavar="FILE", help="write the fleet's run as an MCAP recording, no bus "
                   "(likewise written whole or not at all)")
    r.add_argument("--rig", metavar="ID", help="with --to-csv/--to-mcap: write only this rig of the fleet")
    add_bus_arguments(parser)


def build_fleet(args):
    """The FleetSpec the flags describe."""
    from hydromon.store.fleetfile import FleetSpec, default_fleet, load_fleet, parse_effect, spread_fleet

    if args.fleet and args.rigs is not None:
        raise ValueError("give --fleet or --rigs, not both")
    if args.fleet:
        spec = load_fleet(args.fleet)
        if args.seed is not None:
            spec = FleetSpec(config=spec.config, seed=args.seed, rigs=spec.rigs)
    elif args.rigs is not None or args.severity is not None:
        n = 1 if args.rigs is None else args.rigs
        spec = spread_fleet(n, seed=None if args.severity is not None else args.seed)
        if args.seed is not None:
            spec = FleetSpec(config=spec.config, seed=args.seed, rigs=spec.rigs)
    else:
        spec = default_fleet(seed=args.seed or 0)
    effects = None
    if args.effect is not None:
        effects = dict(parse_effect(e) for e in args.effect)
    return spec.with_overrides(severity=args.severity, profile=args.profile, noise=args.noise,
                               effects=effects, sensor_delay_loop=args.sensor_delay_loop,
                               controller=args.controller, publish_u=args.publish_u)


class Progress:
    """``on_block(done, total)`` for the file writers: a line on stderr every ``every`` [s] of
    wall time once a run takes that long (a short run prints nothing)."""

    def __init__(self, what: str, every: float = 5.0, clock=time.monotonic, stream=None):
        self.what, self.every, self.clock = what, every, clock
        self.stream = stream
        self.start = clock()
        self.next = self.start + every

    def __call__(self, done: int, total: int) -> None:
        now = self.clock()
        if now < self.next or done >= total:
            return
        self.next = now + self.every
        eta = (now - self.start) * (total - done) / max(done, 1)
        print(f"hydromon sim: {self.what}: {100 * done / total:.0f} % ({done} of {total} samples), "
              f"about {eta:.0f} s to go", file=self.stream or sys.stderr, flush=True)


def check_args(args, spec) -> None:
    """Every option's check, before a file or the bus is touched (ValueError names the option)."""
    from hydromon.cli import checks
    from hydromon.contract import FRAME_MAX, check_namespace
    from hydromon.store import simfiles

    checks.non_negative("--rate", args.rate)
    checks.positive("--duration", args.duration)
    checks.at_least("--block", args.block, 1)
    checks.at_least("--frame", args.frame, 1)
    if args.frame is not None and args.frame > FRAME_MAX:
        raise ValueError(f"--frame {args.frame}: at most {FRAME_MAX} samples a frame")
    if args.frame is not None and args.to_csv:
        raise ValueError("--frame goes with the bus or --to-mcap; a CSV has one sample a line")
    check_namespace(args.namespace)
    if not (args.to_csv or args.to_mcap):
        if args.rig:
            raise ValueError("--rig selects the rig of --to-csv/--to-mcap")
        return
    if args.duration is None:
        raise ValueError("--to-csv/--to-mcap need --duration S")
    h = spec.config.h
    if round(args.duration / h) < 1:
        raise ValueError(f"--duration {args.duration!r} s is shorter than one sample ({h:g} s)")
    # a name that says the other format: evaluate and replay would then refuse what was written
    for opt, path, other, ext in (("--to-csv", args.to_csv, "--to-mcap", ".mcap"),
                                  ("--to-mcap", args.to_mcap, "--to-csv", ".csv")):
        if path and str(path).lower().endswith(ext):
            raise ValueError(f"{opt} {path!r}: the name says {ext[1:].upper()}; use {other} for that, or another name")
    if args.to_csv and args.to_mcap and os.path.realpath(args.to_csv) == os.path.realpath(args.to_mcap):
        raise ValueError(f"--to-csv and --to-mcap name the same file {args.to_csv!r}")
    if args.to_csv:
        targets = csv_targets(args.to_csv, spec, args.rig)
        if len(targets) > 1 and Path(args.to_csv).is_dir():
            checks.writable_dir("--to-csv", args.to_csv)
        for _, path in targets:
            checks.writable_file("--to-csv", path)
        checks.fits_on_disk("--to-csv", targets[0][1], len(targets) * simfiles.file_bytes("csv", args.duration, h),
                             f"{args.duration:g} s of {len(targets)} rig(s)")
    if args.to_mcap:
        n_rigs = len(simfiles.select_rig(spec, args.rig).rigs) if args.rig else len(spec.rigs)
        checks.writable_file("--to-mcap", args.to_mcap)
        checks.fits_on_disk("--to-mcap", args.to_mcap, simfiles.file_bytes("mcap", args.duration, h, n_rigs),
                             f"{args.duration:g} s of {n_rigs} rig(s)")


def csv_targets(to_csv: str, spec, rig: str | None) -> list[tuple[str | None, Path]]:
    """``(rig id, path)`` of each CSV ``--to-csv`` writes: one rig (``--rig``, or a fleet of one)
    into the file itself; every rig of a larger fleet into ``FILE-<rig>.csv``, or ``DIR/<rig>.csv``
    when the name is a directory (or ends with a slash)."""
    from hydromon.store import simfiles

    if rig is not None or len(spec.rigs) == 1:
        simfiles.select_rig(spec, rig)  # the rig must be in the fleet
        return [(rig, Path(to_csv))]
    if Path(to_csv).is_dir() or to_csv.endswith(("/", os.sep)):
        return [(r, Path(to_csv) / f"{r}.csv") for r in spec.ids]
    p = Path(to_csv)
    stem = p.with_suffix("") if p.suffix.lower() == ".csv" else p
    return [(r, stem.parent / f"{stem.name}-{r}.csv") for r in spec.ids]


def run(args) -> int:
    from pydantic import ValidationError

    from hydromon.bus import sim as simnode
    from hydromon.cli.checks import replace_on_success
    from hydromon.store import simfiles
    from hydromon.store.fleetfile import brief_error

    try:
        spec = build_fleet(args)
    except ValidationError as exc:
        raise ValueError(brief_error(exc)) from None
    check_args(args, spec)
    if args.to_csv or args.to_mcap:
        # each file is written beside its place and renamed into it once complete: an error
        # (or Ctrl-C) leaves the old file, if any, as it was
        with ExitStack() as files:
            if args.to_csv:
                targets = csv_targets(args.to_csv, spec, args.rig)
                for rig, path in targets:
                    f = files.enter_context(replace_on_success(path, "w", newline=""))
                    rows = simfiles.write_csv(spec, args.duration, f, rig=rig, on_block=Progress(f"--to-csv {path}"))
            if args.to_mcap:
                one = simfiles.select_rig(spec, args.rig) if args.rig else spec
                f = files.enter_context(replace_on_success(args.to_mcap, "wb"))
                n = simfiles.write_mcap(one, args.duration, f, namespace=args.namespace,
                                       on_block=Progress(f"--to-mcap {args.to_mcap}"), frame=args.frame)
        if args.to_csv:
            print(f"hydromon sim: {rows} samples of {len(targets)} rig(s) -> {', '.join(str(p) for _, p in targets)}",
                  file=sys.stderr)
        if args.to_mcap:
            print(f"hydromon sim: {n} messages of {len(one.rigs)} rig(s) -> {args.to_mcap}", file=sys.stderr)
        return 0
    stop = threading.Event()
    restore_signals = stop_on_signals(stop)  # not stop.set() in the handler: hydromon.cli.stop
    try:
        with session_from_args(args) as session:
            sent = "sample" if args.frame is None else f"frame (frames of {args.frame} samples)"
            print(f"hydromon sim: {len(spec.rigs)} rig(s) on {args.namespace}/rig/*/{sent} at "
                  f"{'max speed' if args.rate == 0 else f'{args.rate:g}x real time'}", file=sys.stderr, flush=True)
            stats = simnode.run_sim(session, spec, namespace=args.namespace, rate=args.rate,
                                    duration=args.duration, stop_event=stop,
                                    block=simnode.DEFAULT_BLOCK if args.block is None else args.block,
                                    frame=args.frame)
    finally:
        restore_signals()
    print(f"hydromon sim: {stats.samples} samples x {len(spec.rigs)} rig(s), {stats.published} messages in "
          f"{stats.wall:.2f} s; max lateness {stats.max_late * 1e3:.1f} ms", file=sys.stderr)
    return 0
