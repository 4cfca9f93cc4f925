"""``hydromon audit FILE``: what the simulation gets wrong in measured data (cause, extended model, gain)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from hydromon.cli.rigconfig import add_config_argument, config_from_args, has_recorded_config

NAME = "audit"
HELP = "audit a recording (.csv t,ug,x1,x3,x4,x5 SI, or .mcap): which named model extension explains it"
# compiled numerical kernels (a cold cache compiles them first: hydromon.cli.main), in these
# source directories only: numba caches them under each one's name
KERNELS = ("monitor", "monitor/audit", "plant_sim")
EXAMPLES = (
    'hydromon audit db.csv --report audit-report',
    'hydromon audit tour.mcap --json   # every rig of a recording',
)


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="CSV with header t,ug,x1,x3,x4,x5 (SI) or an MCAP recording")
    parser.add_argument("--rig", metavar="ID", help="MCAP: audit only this rig (default: every rig of the recording, "
                        "one row each; --report DIR then writes DIR/<rig>/)")
    add_config_argument(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout (for a recording of "
                        "several rigs, one per rig id)")
    parser.add_argument("--report", metavar="DIR", help="write audit.md and PNG plots into DIR")
    parser.add_argument("--train-fraction", type=float, default=0.7,
                        help="leading fraction of the record used for fitting (0.2-0.9; default 0.7)")


def read_csv(stream, name: str = "<csv>") -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], samples (N, 5))`` from a CSV path or text stream with header t,ug,x1,x3,x4,x5:
    ``hydromon.store.csvfile.read_csv``, whose errors name the file and line."""
    from hydromon.store.csvfile import read_csv as read_rows

    data = read_rows(stream, name)
    return data[:, 0], data[:, 1:]


def _stretch(rec, csv: bool) -> dict | None:
    """The audit fits and re-simulates one stretch of evenly spaced samples: across a gap (whole
    missing sample periods, a seq jump, an invalid sample skipped) it takes the longest stretch
    without one, as ``evaluate --refine`` does, and says which. None when there is no gap."""
    if not rec.restarts:
        return None
    lo, hi = rec.longest_stretch()
    where = (lambda i: f"line {i + 2}") if csv else (lambda i: f"sample {i}")
    return {"first": lo, "last": hi - 1, "t_start": float(rec.t[lo]), "t_end": float(rec.t[hi - 1]),
            "samples": hi - lo, "of": len(rec.samples), "gaps": len(rec.restarts), "missing": rec.missing,
            "rejected": rec.rejected, "where": f"{where(lo)} to {where(hi - 1)}"}


def load(path: str, rig: str | None = None, config=None):
    """``(config, samples)`` from a CSV or MCAP file, read and validated as ``hydromon evaluate``
    reads it (``hydromon.store.recording.load_recording``: the sample rate is the rig config's, an
    MCAP goes by seq, its duplicate messages are dropped and only the samples after its last
    config change are taken); a ValueError (FileNotFoundError) names the file and what is wrong
    with it. Returns ``(config, samples, stretch)``: across gaps, the samples of the longest
    stretch without one, which ``stretch`` describes (None: no gap, every sample)."""
    from hydromon.store.recording import load_recording
    from monitor.audit.residuals import MIN_SAMPLES

    p = Path(path)
    name = str(p)
    if not p.exists():
        raise FileNotFoundError(f"{name}: no such file")
    if p.is_dir():
        raise ValueError(f"{name}: is a directory; give a .csv or .mcap file")
    if not p.is_file():  # a device or a pipe: /dev/zero would be read until memory runs out
        raise ValueError(f"{name}: is not a regular file (a device or a pipe); give a .csv or .mcap file")
    rec = load_recording(p, rig=rig, config=config)
    csv = p.suffix.lower() == ".csv"
    stretch = _stretch(rec, csv)
    samples = rec.samples
    if stretch is not None and stretch["samples"] < MIN_SAMPLES:
        first = rec.restarts[0]
        at = f"line {first + 2}" if csv else f"rig {rec.rig!r} sample {first}"
        skipped = f"; {rec.rejected} invalid sample(s) skipped" if rec.rejected else ""
        raise ValueError(f"{name} {at}: t = {float(rec.t[first])!r} s follows a gap ({stretch['gaps']} gap(s), "
                         f"{rec.missing} sample(s) missing{skipped}); the longest stretch without one, "
                         f"{stretch['where']}, has {stretch['samples']} samples and the audit needs {MIN_SAMPLES}")
    if stretch is not None:
        samples = rec.samples[stretch["first"]:stretch["last"] + 1]
        skipped = f", {rec.rejected} invalid sample(s) skipped" if rec.rejected else ""
        print(f"hydromon audit: {name}: {stretch['gaps']} gap(s) ({rec.missing} sample(s) missing{skipped}): "
              f"auditing the longest stretch without one, {stretch['where']} (t = {stretch['t_start']:g} to "
              f"{stretch['t_end']:g} s, {stretch['samples']} of {stretch['of']} samples)", file=sys.stderr)
    if len(samples) < 2:
        raise ValueError(f"{name}: {len(samples)} sample(s) in one stretch; the audit needs more")
    if config is None and csv:  # once the file is read: an error stays one line
        print(f"hydromon audit: {name}: the paper's rig constants (a CSV carries none; give yours with --config FILE)",
              file=sys.stderr)
    elif config is None and not has_recorded_config(p, rec.rig):
        print(f"hydromon audit: no rig config for {rec.rig!r} in the recording; using the paper's", file=sys.stderr)
    if rec.config_changes:
        print(f"hydromon audit: {name}: the rig's config changed {rec.config_changes} time(s): auditing the "
              f"{len(rec.samples)} samples after the last change with its constants ({rec.skipped} before it "
              "skipped), as hydromon evaluate does", file=sys.stderr)
    return rec.config, samples, stretch


class Progress:
    """``progress(done, total, name)`` for :func:`monitor.audit.audit`: once the audit has taken
    ``every`` [s] of wall time, a line on stderr per stage at most every ``every`` [s] (a short
    audit prints nothing; a long record takes minutes)."""

    def __init__(self, every: float = 5.0, clock=time.monotonic, stream=None):
        self.every, self.clock, self.stream = every, clock, stream
        self.start = clock()
        self.next = self.start + every

    def __call__(self, done: int, total: int, name: str) -> None:
        now = self.clock()
        if now < self.next or done >= total:
            return
        self.next = now + self.every
        what = "nominal model fitted" if done == 0 else f"{done} of {total} candidate extensions tried (last {name})"
        print(f"hydromon audit: {what}, {now - self.start:.0f} s so far", file=self.stream or sys.stderr, flush=True)


def run(args) -> int:
    from hydromon.cli.checks import writable_dir
    from hydromon.store.recording import recording_rigs
    from monitor.audit import AuditOptions

    try:  # the options first, then the file
        options = AuditOptions(train_fraction=args.train_fraction)
    except ValueError as exc:
        raise ValueError(f"--train-fraction {args.train_fraction!r}: {exc}") from None
    if args.report is not None and not args.report.strip():
        raise ValueError("--report '': give the directory to write the report into")
    if args.report:
        writable_dir("--report", args.report)
    config = config_from_args(args)
    rigs = recording_rigs(args.file, args.rig)
    if len(rigs) == 1:
        return _one(args, rigs[0], config, options)
    print(f"hydromon audit: {args.file}: {len(rigs)} rigs ({', '.join(rigs)}), each audited on its own (--rig ID "
          "for one)", file=sys.stderr)
    return _many(args, rigs, config, options)


def _audit(args, rig, config, options):
    from monitor.audit import audit

    config, samples, stretch = load(args.file, rig, config)
    what = args.file + (f" rig {rig!r}" if rig else "")
    try:
        return audit(samples, config, options, progress=Progress()), stretch
    except np.linalg.LinAlgError as exc:  # a ValueError too, but numpy's own words say nothing of the record
        raise ValueError(f"{what}: the audit's equations cannot be solved on this record ({exc}): two channels "
                         "that move as one (x3 = x4?), or values written with too few decimals") from None
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None


def _one(args, rig, config, options) -> int:
    from hydromon.report.audit import summary, to_json

    result, stretch = _audit(args, rig, config, options)
    # the result first: a report that cannot be written (disk full) must not take it along
    if args.json:
        print(json.dumps({**to_json(result), "stretch": stretch}), flush=True)
    else:
        print(summary(result), flush=True)
    _report(args, result, args.report, rig)
    return _exit(result)


def _many(args, rigs, config, options) -> int:
    from hydromon.report.audit import cause_row, to_json

    results, errors = {}, {}
    for rig in rigs:
        try:
            results[rig] = _audit(args, rig, config, options)
        except ValueError as exc:  # one rig's record cannot be audited: the others still are
            errors[rig] = str(exc)
    if args.json:
        doc = {rig: {**to_json(r), "stretch": st} for rig, (r, st) in results.items()}
        doc.update({rig: {"error": msg} for rig, msg in errors.items()})
        print(json.dumps(dict(sorted(doc.items()))), flush=True)
    else:
        rows = [["rig", "cause", "free-run gain", "note"]]
        rows += [[rig, *cause_row(r)] for rig, (r, _) in sorted(results.items())]
        rows += [[rig, "not audited", "-", msg] for rig, msg in sorted(errors.items())]
        widths = [max(len(r[i]) for r in rows) for i in range(3)]
        print("\n".join("  ".join([*(c.ljust(w) for c, w in zip(r[:3], widths)), r[3]]).rstrip() for r in rows))
        print(f"one rig in full: hydromon audit {args.file} --rig ID", flush=True)
    for rig, (r, _) in results.items():
        _report(args, r, None if args.report is None else str(Path(args.report) / rig), rig)
    return max([_exit(r) for r, _ in results.values()] + [1] * len(errors))


def _report(args, result, directory, rig=None) -> None:
    from hydromon.report.audit import write_report

    if directory:
        try:
            what = Path(args.file).name + (f", rig {rig}" if rig else "")
            path = write_report(result, directory, what)
        except OSError as exc:
            raise ValueError(f"--report {directory!r}: {exc.strerror or exc} (the result above is complete)") from None
        print(f"hydromon audit: report -> {path}", file=sys.stderr)


def _exit(result) -> int:
    """1 for a record that does not obey the model (wrong units, signs, zeros or rig constants:
    the nominal fit is impossible and no candidate restores it): it is audited and reported,
    but its cause "unexplained" must not be read as a pass by a script (hydromon.cli.exits)."""
    return 0 if result.obeys else 1
