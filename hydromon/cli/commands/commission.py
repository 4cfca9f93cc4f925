"""``hydromon commission RECORDING --out RANGES.json``: a rig's own health ranges from a record of
it in good condition."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from hydromon.cli.rigconfig import add_config_argument, config_from_args, constants_line, has_recorded_config

NAME = "commission"
HELP = "make a rig's own health ranges from a recording of it in good condition (its baseline, ranges and noise)"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
PROGRESS_AFTER_S = 3.0  # the twin's progress goes to stderr once a run takes longer than this [s]
EXAMPLES = (
    'hydromon commission good-day.mcap --rig press-1 --out press-1.ranges.json',
)


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="RECORDING",
                        help="the rig in good condition, 30 s or more of its usual motion: .mcap, or .csv "
                             "(t,ug,x1,x3,x4,x5[,u], SI)")
    parser.add_argument("--out", required=True, metavar="RANGES.json",
                        help="the ranges file to write (give it to evaluate/replay --ranges, or put it into "
                             "the monitor's --ranges-dir as <rig-id>.json)")
    parser.add_argument("--rig", metavar="ID", help="which rig of a multi-rig MCAP recording")
    add_config_argument(parser)
    parser.add_argument("--runs", type=int, default=60, metavar="N",
                        help="runs of the rig's digital twin to calibrate the ranges on (default 60; 0: the bands "
                             "relative to the baseline as they are)")
    parser.add_argument("--seed", type=int, default=0, help="base seed of the twin's noise (default 0)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")
    parser.add_argument("--json", action="store_true", help="print the baseline, ranges and warnings as JSON")


class _Progress:
    """The twin's progress on stderr, once the run has taken PROGRESS_AFTER_S."""

    def __init__(self, clock=time.monotonic):
        self.clock, self.start, self.last = clock, clock(), None

    def __call__(self, done: int, total: int) -> None:
        now = self.clock()
        if now - self.start < PROGRESS_AFTER_S or (self.last is not None and now - self.last < 2.0 and done < total):
            return
        self.last = now
        print(f"hydromon commission: digital twin {done}/{total} runs", file=sys.stderr, flush=True)


def run(args) -> int:
    from hydromon.cli.checks import at_least, not_an_input, replace_on_success, writable_file
    from hydromon.report.commission import render, to_json
    from hydromon.store.recording import load_recording
    from monitor.commission import commission

    writable_file("--out", args.out)
    not_an_input("--out", args.out, [args.file, getattr(args, "config", None)])
    if Path(args.out).exists() and not args.force:
        raise ValueError(f"--out {args.out!r} exists: it may hold a rig's baseline; give --force to replace it")
    at_least("--runs", args.runs, 0)
    config = config_from_args(args)
    rec = load_recording(args.file, rig=args.rig, config=config)
    suffix = Path(args.file).suffix.lower()
    recorded = config is not None or suffix != ".mcap" or has_recorded_config(args.file, rec.rig)
    seconds = len(rec.samples) / rec.config.sample_rate
    drive = f"; valve drive u in {rec.drive_samples} samples" if rec.drive_samples else ""
    if rec.restarts:  # the seconds are of samples: say what the record's span also holds
        drive += f"; {len(rec.restarts)} gap(s), {rec.missing} sample(s) missing"
    print(f"hydromon commission: {rec.source}: rig {rec.rig}, {seconds:.1f} s{drive}; "
          f"{constants_line(rec.config, config is not None, suffix, recorded)}", file=sys.stderr, flush=True)
    made_on = f"{rec.source} rig {rec.rig}: {seconds:.1f} s, {len(rec.samples)} samples" + drive
    created = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    result = commission(rec.samples, rec.config, restarts=rec.restarts, runs=args.runs, seed=args.seed,
                        made_on=made_on, created=created, progress=_Progress())
    with replace_on_success(args.out) as f:
        f.write(json.dumps(result.ranges.model_dump(mode="json", exclude_none=True), indent=2) + "\n")
    for w in result.warnings:
        print(f"hydromon commission: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(to_json(result, args.out)))
    else:
        render(result)
    print(f"hydromon commission: wrote {args.out}", file=sys.stderr)
    return 0
