"""``hydromon reproduce``: the paper's Tables 2, 3 and 4, ours beside the paper's."""

from __future__ import annotations

import json
import sys

NAME = "reproduce"
HELP = "the paper's Tables 2, 3 and 4, ours side by side with the paper's"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon reproduce',
    'hydromon reproduce --noise realistic --seeds 5',
)


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    parser.add_argument("--noise", default="none", metavar="MODEL",
                        help="none | realistic | stress | pct:F (default none)")
    parser.add_argument("--seeds", type=int, default=1, metavar="N",
                        help="Table 2 over N noise seeds: mean |relative error| per parameter, both recipes (default 1)")
    parser.add_argument("--calibration-runs", type=int, default=40, metavar="N",
                        help="runs of the Table 3 calibration (0 = compare with our default ranges; default 40)")
    parser.add_argument("--plots", metavar="DIR", help="write PNGs of the estimates over time (Figs 10-12)")
    parser.add_argument("--refine", action="store_true",
                        help="add the whole-record prediction-error fit (evaluate --refine) to Table 2, "
                             "about 1 s per seed")


def run(args) -> int:
    from hydromon.cli.checks import writable_dir
    from hydromon.report.reproduce import plot, render, reproduce, to_json

    if args.plots:
        writable_dir("--plots", args.plots)  # before the tables are computed
    rep = reproduce(noise=args.noise, seeds=args.seeds, calibration_runs=args.calibration_runs,
                    refined=args.refine)
    if args.plots:
        files = plot(rep, args.plots)
        print(f"hydromon reproduce: plots -> {', '.join(map(str, files))}", file=sys.stderr)
    if args.json:
        print(json.dumps(to_json(rep)))
    else:
        render(rep)
    return 0
