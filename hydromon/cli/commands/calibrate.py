"""``hydromon calibrate``: health ranges from labelled runs (the method's section 4.1): simulated
runs of the reference rig labelled by the method's x1 thresholds, or your own labelled records
(``--labelled LIST``)."""

from __future__ import annotations

import sys

NAME = "calibrate"
HELP = ("health ranges from labelled runs: your own labelled recordings (--labelled LIST), or simulated runs of the "
        "reference rig labelled by the method's x1 thresholds")
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon calibrate --out ranges.json --runs 200 --noise realistic',
)


def add_arguments(parser) -> None:
    parser.add_argument("--labelled", metavar="LIST",
                        help="a CSV (recording,grade[,rig]) or TOML ([[records]]) list of your own recordings of one rig "
                             "with the grade each had (e.g. from maintenance records); grades without records take "
                             "their edges from --baseline")
    parser.add_argument("--baseline", metavar="RANGES.json",
                        help="with --labelled: the rig's commissioned ranges (hydromon commission), for the edges "
                             "the records cannot place")
    parser.add_argument("--config", metavar="FILE",
                        help="with --labelled: the rig's constants as JSON, for CSV records (which carry none)")
    parser.add_argument("--runs", type=int, default=200, metavar="N",
                        help="runs, severities spread evenly over [0, 1] (default 200)")
    parser.add_argument("--out", default="ranges.json", metavar="FILE",
                        help="ranges JSON to write (default ranges.json; '-' = do not write)")
    parser.add_argument("--noise", default="none", metavar="MODEL",
                        help="none | realistic | stress | pct:F (default none)")
    parser.add_argument("--seed", type=int, default=0, help="base noise seed: run i uses seed + i (default 0)")
    parser.add_argument("--drop-unseparable", action="store_true",
                        help="simulated runs: leave out a parameter whose labels overlap too much for monotone "
                             "edges (default: error), e.g. B_fv under realistic noise; --labelled always leaves "
                             "such a parameter out and says so")


def comparison_table(ranges, dropped, reference, reference_title: str = "paper (Table 3)"):
    """A rich Table of calibrated edges (``ranges``; ``dropped``: name -> why left out) beside
    the ``reference`` ones."""
    from rich.table import Table

    t = Table(title="health ranges: edges health|sub-health|average|deterioration|fault", header_style="bold")
    t.add_column("parameter")
    t.add_column("direction")
    t.add_column(reference_title, justify="right")
    t.add_column("ours", justify="right")

    def fmt(r):
        if r is None:
            return "-"
        if r.fault_threshold is not None:
            return f"fault past {r.fault_threshold:.3g}"
        return "  ".join(f"{e:.4g}" for e in r.edges)

    names = list(reference.params) + [k for k in ranges.params if k not in reference.params]
    for name in names:
        ours = ranges.params.get(name)
        ref = ours or reference.params[name]
        t.add_row(name, ref.direction, fmt(reference.params.get(name)),
                  fmt(ours) if ours else "left out (below)" if name in dropped else "not graded")
    return t


def run_labelled(args) -> int:
    import numpy as np

    from hydromon.cli.checks import not_an_input, writable_file
    from hydromon.cli.rigconfig import config_from_args
    from hydromon.contract import GRADES, PARAM_NAMES
    from hydromon.engine.evaluate import evaluate
    from hydromon.store.labelled import load_labelled
    from hydromon.store.recording import load_recording
    from monitor.calibrate import calibrate_labelled
    from monitor.ranges import Ranges

    if args.out == "-":
        raise ValueError("--labelled writes its ranges: give --out FILE")
    writable_file("--out", args.out)
    entries = load_labelled(args.labelled)
    not_an_input("--out", args.out, [args.labelled, args.baseline, args.config, *(e.path for e in entries)])
    config = config_from_args(args)
    baseline = Ranges.load(args.baseline) if args.baseline else None
    rows, labels, rig = [], [], None
    for i, e in enumerate(entries, 1):
        try:
            rec = load_recording(e.path, rig=e.rig, config=config)
        except ValueError as exc:  # refused by the reader (a dead drive, a broken file): one record, not the list
            print(f"hydromon calibrate: {i}/{len(entries)} {e.path} ({GRADES[e.grade]}): left out: {exc}",
                  file=sys.stderr)
            continue
        if rig is None:
            rig = rec.config
        elif rec.config != rig:
            raise ValueError(f"{e.path}: its rig constants differ from the first record's: one list, one rig")
        ev = evaluate(rec, ranges=baseline)
        a = ev.assessment
        # a record whose input is bad would put its wrong estimates into the edges of every grade
        bad = ev.bad_input_words
        state = (f"left out: its input is bad ({bad})" if bad else
                 "converged" if a.converged else "not converged: left out")
        print(f"hydromon calibrate: {i}/{len(entries)} {e.path} ({GRADES[e.grade]}): {state}", file=sys.stderr)
        if a.converged and not bad:
            rows.append([a.params[k] for k in PARAM_NAMES])
            labels.append(e.grade)
    if not rows:
        raise ValueError("no record converged: nothing to calibrate from")
    ranges = calibrate_labelled(np.array(rows), np.array(labels), rig, commissioned=baseline,
                                what=f"listed in {args.labelled}")
    ranges.save(args.out)
    from rich.console import Console

    Console().print(comparison_table(ranges, ranges.ungraded, baseline or Ranges.default(),
                                     "commissioned" if baseline else "reference rig"))
    for why in ranges.ungraded.values():
        print(f"hydromon calibrate: left out {why}", file=sys.stderr)
    print(f"hydromon calibrate: ranges -> {args.out}", file=sys.stderr)
    return 0


def run(args) -> int:
    if args.labelled:
        return run_labelled(args)
    if args.baseline or args.config:
        raise ValueError("--baseline and --config go with --labelled")
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
    out.print(comparison_table(cal.ranges, cal.dropped, Ranges.paper()))
    for msg in cal.dropped.values():
        out.print(f"left out: {msg}")
    if cal.overlaps:
        out.print("labels overlapping (edge from medians): "
                  + "; ".join(f"{k} at {v}" for k, v in cal.overlaps.items()))
    if args.out != "-":
        cal.ranges.save(args.out)
        print(f"hydromon calibrate: ranges -> {args.out}", file=sys.stderr)
    return 0
