"""``hydromon audit FILE``: what the simulation gets wrong in measured data (cause, extended model, gain)."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

NAME = "audit"
HELP = "audit a recording (.csv t,ug,x1,x3,x4,x5 SI, or .mcap): which named model extension explains it"

COLUMNS = ("t", "ug", "x1", "x3", "x4", "x5")


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="CSV with header t,ug,x1,x3,x4,x5 (SI) or an MCAP recording")
    parser.add_argument("--rig", metavar="ID", help="MCAP: which rig (needed if it holds several)")
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    parser.add_argument("--report", metavar="DIR", help="write audit.md and PNG plots into DIR")
    parser.add_argument("--train-fraction", type=float, default=0.7,
                        help="leading fraction of the record used for fitting (default 0.7)")


def read_csv(stream) -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], samples (N, 5))`` from a CSV stream with header t,ug,x1,x3,x4,x5."""
    reader = csv.DictReader(stream)
    if reader.fieldnames is None or not set(COLUMNS) <= set(reader.fieldnames):
        raise ValueError(f"CSV needs a header with columns {','.join(COLUMNS)}; got {reader.fieldnames}")
    rows = []
    for i, r in enumerate(reader):
        try:
            rows.append([float(r[c]) for c in COLUMNS])
        except (TypeError, ValueError):
            raise ValueError(f"CSV row {i + 2}: not a number in {[r.get(c) for c in COLUMNS]}") from None
    data = np.array(rows, dtype=float).reshape(len(rows), len(COLUMNS))
    return data[:, 0], data[:, 1:]


def _config_for(t: np.ndarray, config=None):
    from plant_sim.params import RigConfig

    if len(t) < 2:
        raise ValueError(f"record has {len(t)} samples; too few")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise ValueError("t must increase strictly")
    h = float(np.median(dt))
    if np.max(np.abs(dt - h)) > 0.01 * h:
        raise ValueError(f"samples must be evenly spaced (median period {h:g} s, max deviation "
                         f"{float(np.max(np.abs(dt - h))):g} s)")
    base = config or RigConfig()
    return base.model_copy(update={"sample_rate": 1.0 / h})


def load(path: str, rig: str | None = None):
    """``(config, samples)`` from a CSV or MCAP file."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(path)
    if p.suffix.lower() == ".mcap":
        from hydromon import mcap_io

        with open(p, "rb") as f:
            rig_id, data, _ = mcap_io.read_samples(f, rig)
        config = None
        try:
            with open(p, "rb") as f:
                config = mcap_io.read_rig_config(f, rig_id)
        except ValueError:
            print(f"hydromon audit: no rig config for {rig_id!r} in the recording; using the paper's",
                  file=sys.stderr)
        return _config_for(data[:, 0], config), data[:, 1:]
    with open(p, newline="") as f:
        t, samples = read_csv(f)
    return _config_for(t), samples


def run(args) -> int:
    from hydromon.audit_report import summary, to_json, write_report
    from monitor.audit import AuditOptions, audit

    config, samples = load(args.file, args.rig)
    result = audit(samples, config, AuditOptions(train_fraction=args.train_fraction))
    if args.report:
        path = write_report(result, args.report)
        print(f"hydromon audit: report -> {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(to_json(result)))
    else:
        print(summary(result))
    return 0
