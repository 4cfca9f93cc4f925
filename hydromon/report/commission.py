"""A commissioning as a table for a person and as the ``commission --json`` document."""

from __future__ import annotations

import math

from hydromon.contract import PARAM_UNITS
from monitor.commission import Commissioning

__all__ = ["to_json", "render"]

SENSOR_UNITS = {"x1": "m", "x3": "Pa", "x4": "Pa", "x5": "m"}


def _num(x):
    return float(x) if x is not None and math.isfinite(x) else None


def to_json(c: Commissioning, out: str | None = None) -> dict:
    """``{"ranges_file", "baseline": {name: {"value", "std_error"}}, "noise", "ranges": {name: {...}},
    "ungraded": {name: why}, "warnings": [...]}`` (SI)."""
    return {
        "ranges_file": out,
        "baseline": {k: {"value": _num(v.value), "std_error": _num(v.std_error)} for k, v in c.ranges.baseline.items()},
        "noise": c.noise,
        "ranges": {k: v.model_dump(exclude_none=True) for k, v in c.ranges.params.items()},
        "ungraded": dict(c.ungraded),
        "warnings": list(c.warnings),
        "twin_runs": None if c.twin is None else {"runs": int(len(c.twin.severity)),
                                                   "converged": int(c.twin.converged.sum())},
    }


def _edges(pr, baseline: float) -> str:
    vals = pr.edges if pr.edges is not None else (pr.fault_threshold,)
    cells = ", ".join(f"{v:.4g}" for v in vals)
    if pr.edges is not None and baseline > 0:
        cells += "  (" + ", ".join(f"{100 * (v / baseline - 1):+.1f} %" for v in vals) + ")"
    return cells


def render(c: Commissioning, console=None) -> None:
    """The baseline and the ranges as a rich table on ``console`` (default stdout)."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    base = c.ranges.baseline
    t = Table(title="commissioned: the rig's baseline and its health ranges", title_justify="left")
    for col, just in (("parameter", "left"), ("baseline", "right"), ("+- SE", "right"), ("unit", "left"),
                      ("band edges health|sub|avg|det|fault (from the baseline)", "left")):
        t.add_column(col, justify=just)
    for name, unit in PARAM_UNITS.items():
        est = base.get(name)
        if est is None:
            continue
        se = "-" if est.std_error is None else f"{est.std_error:.2g}"
        if name in c.ranges.params:
            bands = _edges(c.ranges.params[name], est.value)
        elif name in c.ungraded:
            bands = f"[yellow]ungraded: {c.ungraded[name]}[/]"
        else:
            bands = "[dim]reported, not graded[/]"
        t.add_row(name, f"{est.value:.5g}", se, unit, bands)
    console.print(t)
    noise = ", ".join(f"{k} {v:.3g} {SENSOR_UNITS[k]}" for k, v in c.noise.items())
    console.print(f"sensor noise (rms): {noise}")
    if c.twin is not None:
        console.print(f"digital twin: {len(c.twin.severity)} runs degraded along the relative bands, "
                      f"{int(c.twin.converged.sum())} converged; each edge moved by the identification's median "
                      "bias near it")

