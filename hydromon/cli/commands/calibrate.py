"""``hydromon calibrate``: health ranges from labelled simulated runs (paper section 4.1)."""

from __future__ import annotations

import sys

NAME = "calibrate"
HELP = "build health ranges from labelled runs (paper section 4.1) into a ranges file"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)


def add_arguments(parser) -> None:
    parser.add_argument("--runs", type=int, default=200, metavar="N",
                        help="runs, severities spread evenly over [0, 1] (default 200)")
    parser.add_argument("--out", default="ranges.json", metavar="FILE",
                        help="ranges JSON to write (default ranges.json; '-' = do not write)")
    parser.add_argument("--noise", default="none", metavar="MODEL",
                        help="none | realistic | stress | pct:F (default none)")
    parser.add_argument("--seed", type=int, default=0, help="base noise seed: run i uses seed + i (default 0)")
    parser.add_argument("--drop-unseparable", action="store_true",
                        help="leave out a parameter whose labels overlap too much for monotone edges "
                             "(default: error), e.g. B_fv under realistic noise")


def comparison_table(cal, paper):
    """A rich Table of our calibrated edges beside the paper's (Table 3) ones."""
    from rich.table import Table

    t = Table(title="health ranges: edges health|sub-health|average|deterioration|fault", header_style="bold")
    t.add_column("parameter")
    t.add_column("direction")
    t.add_column("paper (Table 3)", justify="right")
    t.add_column("ours", justify="right")

    def fmt(r):
        if r is None:
            return "-"
        if r.fault_threshold is not None:
            return f"fault past {r.fault_threshold:.3g}"
        return "  ".join(f"{e:.4g}" for e in r.edges)

    names = list(paper.params) + [k for k in cal.ranges.params if k not in paper.params]
    for name in names:
        ours = cal.ranges.params.get(name)
        ref = ours or paper.params[name]
        t.add_row(name, ref.direction, fmt(paper.params.get(name)),
                  fmt(ours) if ours else "left out (labels overlap)" if name in cal.dropped else "not graded")
    return t


def run(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from hydromon.cli.checks import writable_file
    from monitor.calibrate import calibrate, simulate_runs
    from monitor.grading import Ranges
    from plant_sim.noise import noise_model
    from hydromon.contract import RigConfig

    if args.runs < 10:
        raise ValueError(f"--runs {args.runs}: need at least 10 runs (two per label)")
    noise_model(args.noise, RigConfig())  # a bad model fails here, not after the bar appears
    if args.out != "-":
        writable_file("--out", args.out)  # here, not after minutes of runs
    err = Console(stderr=True)
    with Progress(TextColumn("simulate + identify"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=err) as prog:
        task = prog.add_task("runs", total=args.runs)
        results = simulate_runs(args.runs, noise=args.noise, seed=args.seed,
                                progress=lambda k: prog.advance(task, k))
    cal = calibrate(results, strict=not args.drop_unseparable)
    out = Console()
    if not out.is_terminal:
        out = Console(width=120)  # a pipe or file: room for the table
    out.print(f"{cal.n_used} of {args.runs} runs converged; x1-mean thresholds (mm): "
              + ", ".join(f"{1e3 * x:.2f}" for x in cal.thresholds)
              + f"; runs per label: {[int((cal.labels == j).sum()) for j in range(5)]}")
    out.print(comparison_table(cal, Ranges.paper()))
    for msg in cal.dropped.values():
        out.print(f"left out: {msg}")
    if cal.overlaps:
        out.print("labels overlapping (edge from medians): "
                  + "; ".join(f"{k} at {v}" for k, v in cal.overlaps.items()))
    if args.out != "-":
        cal.ranges.save(args.out)
        print(f"hydromon calibrate: ranges -> {args.out}", file=sys.stderr)
    return 0
