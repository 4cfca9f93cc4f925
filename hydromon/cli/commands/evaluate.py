"""``hydromon evaluate FILE``: grade one recording (.csv t,ug,x1,x3,x4,x5 in SI, or .mcap)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from hydromon.cli.memory import LIVE_MEMORY_S, MEMORY_HELP, add_memory_argument, check_memory, options_from_args
from hydromon.cli.ranges import add_ranges_argument, ranges_from_args
from hydromon.cli.rigconfig import (
    add_config_argument, config_from_args, constants_line, has_recorded_config,
)

NAME = "evaluate"
HELP = "grade a recording (.mcap: every rig in it; or .csv with columns t,ug,x1,x3,x4,x5 in SI units)"
DESCRIPTION = (f"{HELP}. Prints each rig's grade, its confidence, its status and why in words (the parameters "
               "that carry the grade and how far they moved); a recording of several rigs as a table, the rigs "
               "that need attention first. The confidence is the chance the grade is right given the estimates' "
               "uncertainty, times the share of graded parameters that could be placed in a band: 0.60 is 3 of 5 "
               "placed (a rig that barely moves has no identifiable friction or damping). Exit status 0 when every "
               "rig is graded with status ok; 1 when one is not graded or not to be trusted (bad-input, "
               "uncalibrated: graded on ranges not made for its constants, converging: the record is too short)")
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon evaluate tour.mcap   # every rig, worst first',
    'hydromon evaluate tour.mcap --rig table4-g3 --plots plots/',
    'hydromon evaluate g3.csv --config rig.json --json',
)


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="recording: .csv (t,ug,x1,x3,x4,x5, SI) or .mcap")
    parser.add_argument("--json", action="store_true",
                        help='print {"grade","level","confidence","status","params","std_errors","why",...} on '
                             'stdout; for a recording of several rigs, one such document per rig id')
    parser.add_argument("--rig", metavar="ID", help="grade only this rig of a multi-rig MCAP recording (default: "
                        "every rig, in a table)")
    add_config_argument(parser)
    add_ranges_argument(parser)
    add_memory_argument(parser, f"{MEMORY_HELP} (default: none, the whole record; --memory {LIVE_MEMORY_S:g} "
                                "grades as a default live monitor would)")
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
    from hydromon.cli.exits import exit_status
    from hydromon.report.evaluate import render, render_many, to_json
    from hydromon.store.recording import recording_rigs

    if args.plots:  # before the evaluation (minutes with --refine): not a refusal after it
        from hydromon.cli.checks import writable_dir

        writable_dir("--plots", args.plots)
    ranges = ranges_from_args(args)
    check_memory(args)
    config = config_from_args(args)
    rigs = recording_rigs(args.file, args.rig)
    if len(rigs) == 1:  # a CSV, a one-rig recording or --rig: the rig in full
        result = _evaluate(args, rigs[0], ranges, config)
        if args.json:  # the evaluation first: a plotting error must not lose it
            print(json.dumps(to_json(result)), flush=True)
        else:
            render(result)
        _plots(args, result, args.plots)
        return exit_status([result.status])
    print(f"hydromon evaluate: {args.file}: {len(rigs)} rigs ({', '.join(rigs)}); each graded on its own "
          f"(--rig ID for one in full)", file=sys.stderr)
    results, errors = {}, {}
    for rig in rigs:
        try:
            results[rig] = _evaluate(args, rig, ranges, config, quiet=True)
        except ValueError as exc:  # one rig's record cannot be graded: the others still are
            errors[rig] = str(exc)
    if args.json:
        doc = {rig: to_json(ev) for rig, ev in results.items()}
        doc.update({rig: {"error": msg} for rig, msg in errors.items()})
        print(json.dumps(dict(sorted(doc.items()))), flush=True)
    else:
        render_many(results, errors, args.file)
    for rig, ev in results.items():
        _plots(args, ev, None if args.plots is None else str(Path(args.plots) / rig))
    return exit_status([ev.status for ev in results.values()] + ["error"] * len(errors))


def _evaluate(args, rig, ranges, config, quiet: bool = False):
    """One rig of ``args.file`` evaluated (its stderr header unless ``quiet``)."""
    from hydromon.engine.evaluate import evaluate
    from hydromon.store.recording import load_recording

    rec = load_recording(args.file, rig=rig, config=config)
    suffix = Path(args.file).suffix.lower()
    if not quiet:
        skipped = f" ({rec.skipped} before its last config change skipped)" if rec.skipped else ""
        recorded = config is not None or suffix != ".mcap" or has_recorded_config(args.file, rec.rig)
        print(f"hydromon evaluate: {rec.source}: rig {rec.rig}, {len(rec.samples)} samples{skipped}; "
              f"{constants_line(rec.config, config is not None, suffix, recorded)}", file=sys.stderr)
    if args.refine:
        print(f"hydromon evaluate: {rec.rig}: refining over {len(rec.samples) / rec.config.sample_rate:g} s of data "
              f"(about {0.1 * len(rec.samples) / rec.config.sample_rate:.0f} s)", file=sys.stderr)
    return evaluate(rec, ranges=ranges, options=options_from_args(args, rec.config.sample_rate), refined=args.refine)


def _plots(args, result, directory) -> None:
    if directory:
        from hydromon.report.evaluate_plots import plot_evaluation

        for path in plot_evaluation(result, directory).files:
            print(f"hydromon evaluate: wrote {path}", file=sys.stderr)
