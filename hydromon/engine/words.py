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

__all__ = ["parameter_words", "why_words", "confidence_words", "se_text", "known_ranges", "placed", "SE_UNKNOWN",
           "CONFIDENCE_HELP"]


def parameter_words(name: str, value: float, baseline: float | None = None, threshold: float | None = None,
                    units: bool = False) -> str:
    """One parameter in words: against its fault ``threshold`` when it has one (a leakage), else
    its change from ``baseline`` [same unit], else its value and unit. With ``units``, the size
    in the parameter's unit follows: "valve gain -44 % of its baseline (-0.00011 m/V)",
    "internal leakage 3.2x the fault threshold (3.2e-10 m^3/(s Pa))"."""
    what = PARAM_WORDS.get(name, name)
    unit = PARAM_UNITS.get(name, "")
    if not math.isfinite(value):
        return f"{what}: not identified"
    if threshold is not None and threshold > 0:
        ratio = value / threshold
        size = f" ({_size(value)} {unit})" if units else ""
        if ratio >= 1:
            return f"{what} {ratio:.1f}x the fault threshold{size}"
        return f"{what} below the fault threshold ({100 * ratio:.0f} % of it){size}"
    if baseline is not None and baseline != 0 and math.isfinite(baseline):
        pct = 100.0 * (value / baseline - 1.0)
        if not units:
            return f"{what} {pct:+.0f} % of its baseline"
        change = f"{value / baseline:.1f}x its baseline" if value / baseline >= 2 else f"{pct:+.0f} % of its baseline"
        return f"{what} {change} ({_size(value - baseline, '+')} {unit})"
    return f"{what} {value:.4g} {unit}".rstrip()


def _size(x: float, sign: str = "") -> str:
    """A size for a person: whole numbers from 100 to 1e6, else two significant digits."""
    return f"{x:{sign}.0f}" if 100 <= abs(x) < 1e6 else f"{x:{sign}.2g}"


def known_ranges(health: Mapping):
    """The ranges a health payload was graded on, when a reader can know them without asking the
    monitor: its ``ranges`` tag ``default`` (or none: a monitor that does not tag them grades on
    the default ranges unless told otherwise) or ``paper``; None for a rig's own ranges."""
    from monitor.ranges import Ranges

    tag = health.get("ranges")
    if tag in (None, "default"):
        return Ranges.default()
    if tag == "paper":
        return Ranges.paper()
    return None


def placed(param_grades: Mapping) -> tuple[int, int]:
    """``(placed, graded)``: the graded parameters whose grade could be placed, of all graded."""
    return sum(1 for g in param_grades.values() if g != UNKNOWN), len(param_grades)


SE_UNKNOWN = ("std error -: not identifiable from this record (its equation had too few informative rows, "
              "e.g. a piston that barely moves); such a parameter is left out of the grade")
"""Why a table shows ``-`` for a standard error (:func:`se_text`)."""


def why_words(health: Mapping, ranges=None, units: bool = False) -> list[str]:
    """The parameters that carry a health payload's grade (``contract.Health`` as a dict), in
    words; ``ranges`` (``monitor.ranges.Ranges``, optional) gives each one's baseline and fault
    threshold; ``units``: each with its size in its unit (:func:`parameter_words`). Empty for a
    healthy or unknown grade."""
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
        out.append(parameter_words(name, params[name], baseline, threshold, units))
    return out


def confidence_words(confidence: float, placed: int, graded: int) -> str:
    """What a confidence means: the probability that the grade is right given the estimates'
    standard errors, discounted by the share of graded parameters that could be placed."""
    return (f"confidence {confidence:.2f}: the chance the grade is right given the estimates' uncertainty, "
            f"{placed} of {graded} graded parameters placed")


CONFIDENCE_HELP = ("conf is the chance the grade is right given the estimates' uncertainty, times the share of "
                   "graded parameters that could be placed in a band: 0.60 is 3 of 5 placed")
"""One line under a table with a ``conf`` column."""


def se_text(se: float | None) -> str:
    """A standard error for a table: ``-`` when unknown (the equation has too few rows)."""
    return "-" if se is None or not math.isfinite(se) else f"{se:.3g}"
