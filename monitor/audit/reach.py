"""How large a Stribeck hump a record could have shown: its own detection limit.

A breakaway hump is told from Coulomb plus viscous friction only by rows that slide through its
Stribeck velocity; how many a record has, and how noisy its net force is, depends on the input
and on the rig's health. ``stribeck_reach`` adds a hump F_s sign(v) exp(-(v/v_s)^2) [N] to the
record's measured net force on the force equation's rows (through the equations' filter) and
audits the result for Stribeck friction exactly as ``monitor.audit.audit`` does (the nominal fit,
its floors, the search over v_s, the held-out score against twice the threshold), for F_s on a
doubling grid; the smallest F_s named is the record's reach.

The injected force leaves the motion as it was: a real hump would also slow the piston where
it acts, so the reach is what the record's motion and noise resolve, not a promise about a
record with the hump in it.
"""

from __future__ import annotations

from dataclasses import replace

from .candidates import StribeckFriction
from .residuals import build_blocks, fit_blocks, improves_training

__all__ = ["REACH_GRID", "REACH_V_S", "stribeck_reach"]

REACH_GRID = tuple(10.0 * 2.0 ** k for k in range(9))
"""Hump heights tried, smallest first [N above Coulomb]: 10 to 2560 N."""

REACH_V_S = 0.01
"""Stribeck velocity of the injected hump [m/s]."""


def stribeck_reach(sig, cfg, split: int, h: float, base: dict, theta0: float, threshold: float, penalty: float,
                   score_of, cache: dict | None = None) -> float | None:
    """The smallest hump of ``REACH_GRID`` [N] (Stribeck velocity ``REACH_V_S``) that this
    record's force equation would name, or None when none up to 2560 N would be.

    Parameters
    ----------
    sig : Signals
        The record's filtered signals (``monitor.audit.signals``).
    cfg : RigConfig
    split : int
        First held-out sample.
    h : float
        Sample period [s].
    base : dict
        The nominal model's equation blocks (``build_blocks`` under ``Spec()``), as the audit built them.
    theta0 : float
        The nominal C_d W/sqrt(rho) the audit's candidates were built with.
    threshold, penalty : float
        The audit's threshold (Stribeck friction needs twice it) and per-parameter penalty [-].
    score_of : callable
        ``score_of(nominal_fit, extended_fit) -> (train log ratio, held-out log ratio)``, the
        audit's own scoring (its floors taken from ``nominal_fit``).
    cache : dict or None
        The audit's valve-fit memo (the valve block does not change here).
    """
    cand = StribeckFriction()
    ext = {v: build_blocks(sig, cfg, cand.spec(v), theta0) for v in cand.grid(sig)}
    # the injected hump is the candidate's own force column at REACH_V_S (one of its searched v_s)
    force = ext[REACH_V_S]["force"]
    hump = force.X[:, force.columns.index("F_s")]
    for f_s in REACH_GRID:
        def add(blocks):
            return {**blocks, "force": replace(blocks["force"], y=blocks["force"].y + f_s * hump)}
        nominal = fit_blocks(add(base), split, h, cache)
        best = None
        for blocks in ext.values():
            fit = fit_blocks(add(blocks), split, h, cache)
            train, held = score_of(nominal, fit)
            key = (cand.admissible(fit.theta), train)
            if best is None or key > best[0]:
                best = (key, held)
        (physical, train), held = best
        if physical and improves_training(train, threshold) and held - penalty * cand.n_extra > 2.0 * threshold:
            return f_s
    return None
