"""``hydromon evaluate FILE``: grade one recording (.csv t,ug,x1,x3,x4,x5 in SI, or .mcap)."""

from __future__ import annotations

import json
import sys

from hydromon.cli.memory import add_memory_argument, check_memory, options_from_args
from hydromon.cli.ranges import add_ranges_argument, ranges_from_args
from hydromon.cli.rigconfig import (
    add_config_argument, config_from_args, constants_line, has_recorded_config,
)

NAME = "evaluate"
HELP = "grade one recording (.mcap, or .csv with columns t,ug,x1,x3,x4,x5 in SI units)"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="recording: .csv (t,ug,x1,x3,x4,x5, SI) or .mcap")
    parser.add_argument("--json", action="store_true",
                        help='print {"grade","level","confidence","status","params","std_errors"} on stdout')
    parser.add_argument("--rig", metavar="ID", help="which rig of a multi-rig MCAP recording")
    add_config_argument(parser)
    add_ranges_argument(parser)
    add_memory_argument(parser)
    parser.add_argument("--refine", action="store_true",
                        help="also fit the force and chamber parameters to the whole record by prediction error "
                             "(monitor/refine.py: B + f_v at realistic sensor noise ~0.8 %% instead of ~4 %%; "
                             "about 0.1 s of CPU per second of data)")
    parser.add_argument("--plots", metavar="DIR",
                        help="also write PNGs into DIR: the grade over time with each graded parameter's "
                             "grade, the graded parameters' estimates with +-3 standard errors against their health "
                             "bands (coloured zones), the other parameters' estimates, the signals with the "
                             "replaced glitches and the gaps")


def run(args) -> int:
    from hydromon.report.evaluate import render, to_json
    from hydromon.engine.evaluate import evaluate
    from hydromon.store.recording import load_recording

    from pathlib import Path

    if args.plots:  # before the evaluation (minutes with --refine): not a refusal after it
        from hydromon.cli.checks import writable_dir

        writable_dir("--plots", args.plots)
    ranges = ranges_from_args(args)
    check_memory(args)
    config = config_from_args(args)
    rec = load_recording(args.file, rig=args.rig, config=config)
    skipped = f" ({rec.skipped} before its last config change skipped)" if rec.skipped else ""
    suffix = Path(args.file).suffix.lower()
    recorded = config is not None or suffix != ".mcap" or has_recorded_config(args.file, rec.rig)
    print(f"hydromon evaluate: {rec.source}: rig {rec.rig}, {len(rec.samples)} samples{skipped}; "
          f"{constants_line(rec.config, config is not None, suffix, recorded)}", file=sys.stderr)
    if args.refine:
        print(f"hydromon evaluate: refining over {len(rec.samples) / rec.config.sample_rate:g} s of data "
              f"(about {0.1 * len(rec.samples) / rec.config.sample_rate:.0f} s)", file=sys.stderr)
    result = evaluate(rec, ranges=ranges, options=options_from_args(args, rec.config.sample_rate),
                      refined=args.refine)
    if args.json:  # the evaluation first: a plotting error must not lose it
        print(json.dumps(to_json(result)), flush=True)
    else:
        render(result)
    if args.plots:
        from hydromon.report.evaluate_plots import plot_evaluation

        for path in plot_evaluation(result, args.plots).files:
            print(f"hydromon evaluate: wrote {path}", file=sys.stderr)
    return 0
