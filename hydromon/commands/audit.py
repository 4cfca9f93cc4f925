"""``hydromon audit FILE``: what the simulation gets wrong in measured data (cause, extended model, gain)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from hydromon.commands._rigconfig import add_config_argument, config_from_args

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


def _config_for(t: np.ndarray, config=None, name: str = "<record>", where=lambda i: f"sample {i}"):
    """The rig constants with the record's sample rate (its median period); ``where(i)``
    names sample i in an error (e.g. its CSV line)."""
    from hydromon.recording import check_increasing
    from plant_sim.params import RigConfig

    if len(t) < 2:
        raise ValueError(f"{name}: {len(t)} sample(s); the audit needs more")
    dt = check_increasing(t, where)
    h = float(np.median(dt))
    dev = np.abs(dt - h)
    if np.max(dev) > 0.01 * h:
        i = int(np.argmax(dev)) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous "
                         f"sample; the audit needs evenly spaced samples (median period {h:g} s, 1 % "
                         "tolerance; no gaps)")
    base = config or RigConfig()
    return base.model_copy(update={"sample_rate": 1.0 / h})


def load(path: str, rig: str | None = None, config=None):
    """``(config, samples)`` from a CSV or MCAP file; a ValueError (FileNotFoundError) names
    the file and what is wrong with it."""
    p = Path(path)
    name = str(p)
    if not p.exists():
        raise FileNotFoundError(f"{name}: no such file")
    if p.is_dir():
        raise ValueError(f"{name}: is a directory; give a .csv or .mcap file")
    if p.suffix.lower() == ".mcap":
        from hydromon import mcap_io

        try:
            rig_id, data, _ = mcap_io.read_samples(str(p), rig)
        except ValueError as exc:
            msg = str(exc).replace("; choose one", "; choose one with --rig ID")
            raise ValueError(msg if msg.startswith(name) else f"{name}: {msg}") from None
        if config is None:
            try:
                config = mcap_io.read_rig_config(str(p), rig_id)
            except ValueError:
                print(f"hydromon audit: no rig config for {rig_id!r} in the recording; using the paper's",
                      file=sys.stderr)
        return _config_for(data[:, 0], config, f"{name} rig {rig_id!r}",
                           lambda i: f"{name} rig {rig_id!r} sample {i}"), data[:, 1:]
    if rig is not None:
        raise ValueError("--rig selects a rig of an MCAP recording; a CSV holds one rig")
    t, samples = read_csv(p)
    found = _config_for(t, config, name, lambda i: f"{name} line {i + 2}")
    if config is None:  # once the file is read: an error stays one line
        print(f"hydromon audit: {name}: the paper's rig constants (a CSV carries none; give yours with --config FILE)",
              file=sys.stderr)
    return found, samples


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
