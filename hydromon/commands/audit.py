"""``hydromon audit FILE``: what the simulation gets wrong in measured data (cause, extended model, gain)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from hydromon.commands._rigconfig import add_config_argument, config_from_args, has_recorded_config

NAME = "audit"
HELP = "audit a recording (.csv t,ug,x1,x3,x4,x5 SI, or .mcap): which named model extension explains it"


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="CSV with header t,ug,x1,x3,x4,x5 (SI) or an MCAP recording")
    parser.add_argument("--rig", metavar="ID", help="MCAP: which rig (needed if it holds several)")
    add_config_argument(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    parser.add_argument("--report", metavar="DIR", help="write audit.md and PNG plots into DIR")
    parser.add_argument("--train-fraction", type=float, default=0.7,
                        help="leading fraction of the record used for fitting (default 0.7)")


def read_csv(stream, name: str = "<csv>") -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], samples (N, 5))`` from a CSV path or text stream with header t,ug,x1,x3,x4,x5:
    ``hydromon.recording.read_csv``, whose errors name the file and line."""
    from hydromon.recording import read_csv as read_rows

    data = read_rows(stream, name)
    return data[:, 0], data[:, 1:]


def _no_gaps(rec, csv: bool) -> None:
    """The audit fits and re-simulates one stretch: a gap (whole missing sample periods, a seq
    jump, an invalid sample skipped) is an error naming where it is."""
    if not rec.restarts:
        return
    i = rec.restarts[0]
    where = f"{rec.source} line {i + 2}" if csv else f"{rec.source} rig {rec.rig!r} sample {i}"
    skipped = f"; {rec.rejected} invalid sample(s) skipped" if rec.rejected else ""
    raise ValueError(f"{where}: t = {float(rec.t[i])!r} s follows a gap ({len(rec.restarts)} gap(s), {rec.missing} "
                     f"sample(s) missing{skipped}): the audit needs one stretch of evenly spaced samples without "
                     "gaps (hydromon evaluate grades across them)")


def load(path: str, rig: str | None = None, config=None):
    """``(config, samples)`` from a CSV or MCAP file, read and validated as ``hydromon evaluate``
    reads it (``hydromon.recording.load_recording``: the sample rate is the rig config's, an
    MCAP goes by seq, its duplicate messages are dropped and only the samples after its last
    config change are taken); a ValueError (FileNotFoundError) names the file and what is wrong
    with it. A gap is an error: the audit needs one stretch."""
    from hydromon.recording import load_recording

    p = Path(path)
    name = str(p)
    if not p.exists():
        raise FileNotFoundError(f"{name}: no such file")
    if p.is_dir():
        raise ValueError(f"{name}: is a directory; give a .csv or .mcap file")
    rec = load_recording(p, rig=rig, config=config)
    csv = p.suffix.lower() == ".csv"
    _no_gaps(rec, csv)
    if len(rec.samples) < 2:
        raise ValueError(f"{name}: {len(rec.samples)} sample(s); the audit needs more")
    if config is None and csv:  # once the file is read: an error stays one line
        print(f"hydromon audit: {name}: the paper's rig constants (a CSV carries none; give yours with --config FILE)",
              file=sys.stderr)
    elif config is None and not has_recorded_config(p, rec.rig):
        print(f"hydromon audit: no rig config for {rec.rig!r} in the recording; using the paper's", file=sys.stderr)
    if rec.config_changes:
        print(f"hydromon audit: {name}: the rig's config changed {rec.config_changes} time(s): auditing the "
              f"{len(rec.samples)} samples after the last change with its constants ({rec.skipped} before it "
              "skipped), as hydromon evaluate does", file=sys.stderr)
    return rec.config, rec.samples


def run(args) -> int:
    from hydromon.audit_report import summary, to_json, write_report
    from hydromon.commands._checks import writable_dir
    from monitor.audit import AuditOptions, audit

    try:  # the options first, then the file
        options = AuditOptions(train_fraction=args.train_fraction)
    except ValueError as exc:
        raise ValueError(f"--train-fraction {args.train_fraction!r}: {exc}") from None
    if args.report:
        writable_dir("--report", args.report)
    config, samples = load(args.file, args.rig, config_from_args(args))
    result = audit(samples, config, options)
    if args.report:
        path = write_report(result, args.report)
        print(f"hydromon audit: report -> {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(to_json(result)))
    else:
        print(summary(result))
    return 0
