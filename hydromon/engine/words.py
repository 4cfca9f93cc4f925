"""Why a rig has its grade, in words a shift engineer can act on.

One function for every place that shows a verdict (``watch``, ``evaluate``, the demo, the
dashboard, the events' reasons): each graded parameter that carries the rig's grade, by what it
is and how far it has moved from the rig's own healthy value (the baseline of its ranges), e.g.
"valve gain -44 % of its baseline" or "internal leakage 3.2x the fault threshold".
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from hydromon.contract import PARAM_UNITS, PARAM_WORDS, UNKNOWN

__all__ = ["parameter_words", "why_words", "confidence_words", "se_text"]


def parameter_words(name: str, value: float, baseline: float | None = None, threshold: float | None = None) -> str:
    """One parameter in words: against its fault ``threshold`` when it has one (a leakage), else
    its change from ``baseline`` [same unit], else its value and unit."""
    what = PARAM_WORDS.get(name, name)
    if not math.isfinite(value):
        return f"{what}: not identified"
    if threshold is not None and threshold > 0:
        ratio = value / threshold
        if ratio >= 1:
            return f"{what} {ratio:.1f}x the fault threshold"
        return f"{what} below the fault threshold ({100 * ratio:.0f} % of it)"
    if baseline is not None and baseline != 0 and math.isfinite(baseline):
        pct = 100.0 * (value / baseline - 1.0)
        return f"{what} {pct:+.0f} % of its baseline"
    return f"{what} {value:.4g} {PARAM_UNITS.get(name, '')}".rstrip()


def why_words(health: Mapping, ranges=None) -> list[str]:
    """The parameters that carry a health payload's grade (``contract.Health`` as a dict), in
    words; ``ranges`` (``monitor.ranges.Ranges``, optional) gives each one's baseline and fault
    threshold. Empty for a healthy or unknown grade."""
    grade = health.get("grade", UNKNOWN)
    if grade in (UNKNOWN, "health"):
        return []
    params = health.get("params", {})
    out = []
    for name, g in health.get("param_grades", {}).items():
        if g != grade or name not in params:
            continue
        baseline = threshold = None
        if ranges is not None:
            est = ranges.baseline.get(name)
            baseline = est.value if est is not None else None
            pr = ranges.params.get(name)
            threshold = pr.fault_threshold if pr is not None else None
        out.append(parameter_words(name, params[name], baseline, threshold))
    return out


def confidence_words(confidence: float, placed: int, graded: int) -> str:
    """What a confidence means: the probability that the grade is right given the estimates'
    standard errors, discounted by the share of graded parameters that could be placed."""
    return (f"confidence {confidence:.2f}: the chance the grade is right given the estimates' uncertainty, "
            f"{placed} of {graded} graded parameters placed")


def se_text(se: float | None) -> str:
    """A standard error for a table: ``-`` when unknown (the equation has too few rows)."""
    return "-" if se is None or not math.isfinite(se) else f"{se:.3g}"
