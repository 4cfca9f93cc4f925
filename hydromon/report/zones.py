"""Health bands drawn as coloured zones (matplotlib): each grade's band of a parameter filled in
the grade's colour and labelled with its name, so a plot says at a glance which band an estimate
is in, not only where an edge lies."""

from __future__ import annotations

import math

from hydromon.contract import GRADES

__all__ = ["GRADE_COLOURS", "zones", "draw_zones"]

GRADE_COLOURS = {"health": "#2e7d32", "sub-health": "#9ccc65", "average": "#fdd835", "deterioration": "#fb8c00",
                 "fault": "#c62828", "unknown": "#bdbdbd"}
"""The colour of each grade in every plot (and of the dashboard's zones)."""


def zones(pr) -> list[tuple[float, float, str]]:
    """``(low, high, grade)`` of each band of a ``monitor.ranges.ParamRange`` [its unit]: five
    from the four edges in grade order, or health and fault on either side of a fault threshold."""
    rising = pr.direction == "rising"
    inf = math.inf
    if pr.edges is None:
        t = pr.fault_threshold
        return [(-inf, t, "health"), (t, inf, "fault")] if rising else [(t, inf, "health"), (-inf, t, "fault")]
    bounds = [-inf, *pr.edges, inf] if rising else [inf, *pr.edges, -inf]
    return [(min(a, b), max(a, b), g) for a, b, g in zip(bounds, bounds[1:], GRADES)]


def draw_zones(ax, pr, alpha: float = 0.18, min_label: float = 0.09) -> None:
    """Fill ``ax`` (its y limits already set) with the bands of ``pr``; a band taller than
    ``min_label`` of the axis gets its grade's name at the right."""
    lo, hi = ax.get_ylim()
    for a, b, g in zones(pr):
        a, b = max(a, lo), min(b, hi)
        if b <= a:
            continue
        ax.axhspan(a, b, color=GRADE_COLOURS[g], alpha=alpha, lw=0, zorder=0)
        if (b - a) / (hi - lo) >= min_label:
            ax.text(0.995, (a + b) / 2, g, transform=ax.get_yaxis_transform(), ha="right", va="center",
                    fontsize=7, color=GRADE_COLOURS[g] if g not in ("average", "sub-health") else "#5d4037",
                    zorder=1)
    ax.set_ylim(lo, hi)
