"""``hydromon evaluate FILE``: grade one recording (.csv t,ug,x1,x3,x4,x5 in SI, or .mcap)."""

from __future__ import annotations

import json
import sys

NAME = "evaluate"
HELP = "grade one recording (.mcap, or .csv with columns t,ug,x1,x3,x4,x5 in SI units)"


RANGES_HELP = ('health ranges: "default" (the default: Table 3 with the valve on its static gain K_sv), '
               '"paper" (Table 3 as printed: grades K_sv omega^2) or a JSON file (./paper for a file of that name)')

def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="recording: .csv (t,ug,x1,x3,x4,x5, SI) or .mcap")
    parser.add_argument("--json", action="store_true",
                        help='print {"grade","level","confidence","status","params","std_errors"} on stdout')
    parser.add_argument("--rig", metavar="ID", help="which rig of a multi-rig MCAP recording")
    parser.add_argument("--ranges", metavar="paper|default|FILE", help=RANGES_HELP)
    parser.add_argument("--refine", action="store_true",
                        help="also fit the force and chamber parameters to the whole record by prediction error "
                             "(monitor/refine.py: B + f_v at realistic sensor noise ~0.8 %% instead of ~4 %%; "
                             "about 0.1 s of CPU per second of data)")
    parser.add_argument("--plots", metavar="DIR",
                        help="also write PNGs into DIR: the grade over time with each graded parameter's "
                             "grade, the estimates with +-3 standard errors and the health-band edges, the "
                             "signals with the replaced glitches and the gaps")


def run(args) -> int:
    from hydromon.evaluate import evaluate, load_recording, render, to_json
    from monitor.grading import Ranges

    ranges = Ranges.resolve(args.ranges) if args.ranges is not None else None
    rec = load_recording(args.file, rig=args.rig)
    print(f"hydromon evaluate: {rec.source}: rig {rec.rig}, {len(rec.samples)} samples", file=sys.stderr)
    if args.refine:
        print(f"hydromon evaluate: refining over {len(rec.samples) / rec.config.sample_rate:g} s of data "
              f"(about {0.1 * len(rec.samples) / rec.config.sample_rate:.0f} s)", file=sys.stderr)
    result = evaluate(rec, ranges=ranges, refined=args.refine)
    if args.json:  # the evaluation first: a plotting error must not lose it
        print(json.dumps(to_json(result)), flush=True)
    else:
        render(result)
    if args.plots:
        from hydromon.evaluate_plots import plot_evaluation

        for path in plot_evaluation(result, args.plots).files:
            print(f"hydromon evaluate: wrote {path}", file=sys.stderr)
    return 0
