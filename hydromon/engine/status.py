"""The status a health verdict carries, in order of precedence (``contract.STATUSES``).

``bad-input``: a message of the rig was rejected since its previous verdict, its estimates are
physically impossible (``monitor.plausibility``), its x1 went beyond a chamber's end, or its
readings keep breaking its config's bounds (``hydromon.engine.units_watch``);
``stale``: the verdict follows a gap by fewer samples than the filters need, or the rig went
silent; ``commissioning``: the monitor is commissioning the rig from its first samples (its
grade is unknown until it has ranges); ``uncalibrated``: no health ranges were made for the
rig's constants, so it is not graded (its parameters are still reported); ``converging``: the
estimator has not converged or cannot place the grade (level -1); ``ok`` otherwise. The live
monitor and ``evaluate`` both say it with :func:`health_status`.
"""

from __future__ import annotations

__all__ = ["health_status"]


def health_status(bad_input: bool, stale: bool, converged: bool, level: int, calibrated: bool = True,
                  commissioning: bool = False) -> str:
    """The status of a verdict: see the module docstring; ``level`` -1 is an unplaced grade."""
    if bad_input:
        return "bad-input"
    if stale:
        return "stale"
    if commissioning:
        return "commissioning"
    if not calibrated:
        return "uncalibrated"
    return "ok" if converged and level >= 0 else "converging"
