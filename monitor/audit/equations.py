"""A record's equations, and its nominal model's twin: what ``monitor.audit.audit`` fits and scores.

``_Equations`` holds a record's filtered signals, the nominal model's fit and its resolution
floors, and fits any candidate at one value of its searched parameter and scores it on the
held-out part (``monitor.audit.audit``, step 2). ``_twin`` builds the nominal model's twin of a
record: the same command, the nominal model's free run as the measurements and the record's own
noise level; it holds no effect by construction, so what a candidate (or a probe family) scores
on it is what the equations make of this rig's motion at this sample rate, and the audit takes
that off its score.
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import RigConfig

from .residuals import BLOCKS, Fit, Spec, build_blocks, fit_blocks, improves_training, nominal_params, signals
from .result import AuditOptions

__all__ = ["THETA_TOL", "TWIN_SEED", "TWIN_FIT", "_Equations", "_twin", "_floors", "_mse_split", "_log_ratio"]

THETA_TOL = 0.05
"""Log mismatch [-] between the orifice coefficient a flow law not linear in theta (the supply
sag) is built with and the one its fit returns, above which the value is refused: on a 1.6e10
Pa/(m^3/s) sag at realistic noise (tuning sag ladder, record 127) the secant steps converged to
0.001 at the true value and stalled at 0.29-1.3 from 2.1e10 up, where the fits' free runs erred
up to 13 times as much as the nominal model's."""


def _floors(fit: Fit, split: int) -> tuple[dict, dict]:
    """The nominal fit's resolution per block on the training and the held-out part: every
    model is compared above it (a model whose regressor noise differs must not win by that)."""
    tr, te = {}, {}
    for g in BLOCKS:
        rows = fit.blocks[g].rows
        tr[g], te[g] = fit.floor(g, rows < split), fit.floor(g, rows >= split)
    return tr, te


def _mse_split(fit: Fit, split: int, floors: tuple[dict, dict] | None = None) -> tuple[dict, dict]:
    """Residual variance per block on the training and the held-out part (above ``floors``)."""
    tr, te = {}, {}
    for g in BLOCKS:
        rows = fit.blocks[g].rows
        f_tr, f_te = (floors[0][g], floors[1][g]) if floors else (0.0, 0.0)
        tr[g], te[g] = fit.mse(g, rows < split, f_tr), fit.mse(g, rows >= split, f_te)
    return tr, te


def _log_ratio(nom: dict, ext: dict) -> float:
    return sum(math.log(nom[g] / ext[g]) for g in BLOCKS if nom[g] > 0 and ext[g] > 0)


TWIN_SEED = 0
"""Seed of the noise added to the nominal model's twin (``_twin``): the audit stays a pure function."""

TWIN_FIT = 0.1
"""Held-out mean NRMSE [-] of the nominal free run above which it has no twin: a free run that
strays that far from the record does not move as the rig did. A 4000 N load offset on a
noise-free multisine record at fault-grade health left the nominal free run at 2.6 times x1's
spread, and its twin scored the offset at 11.6; the clean records of the tuning rigs whose
equations the twin explained were followed to 0.002-0.04."""


class _Equations:
    """A record's equations: its filtered signals, the nominal fit and its floors, and any
    candidate's fit and held-out score at one value of its searched parameter.

    Parameters
    ----------
    s : array (N, 5)
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m].
    cfg : RigConfig
    train_fraction : float
        Leading share of the record the fits see [-].
    """

    def __init__(self, s: np.ndarray, cfg: RigConfig, train_fraction: float):
        self.cfg = cfg
        self.sig = signals(s, cfg.h)
        self.split = int(train_fraction * self.sig.n)
        self.cache: dict = {}  # valve fits by what they depend on
        self.nominal = fit_blocks(build_blocks(self.sig, cfg, Spec()), self.split, cfg.h, self.cache)
        self.p_nom = nominal_params(self.nominal)
        self.theta0 = max(self.p_nom["CdW_sqrt_rho"], 1e-6)
        self.floors = _floors(self.nominal, self.split)
        self.nom_tr, self.nom_te = _mse_split(self.nominal, self.split, self.floors)

    def fit(self, spec, theta0: float) -> Fit:
        """The equations fitted under ``spec`` with the flow laws built at ``theta0``."""
        return fit_blocks(build_blocks(self.sig, self.cfg, spec, theta0), self.split, self.cfg.h, self.cache)

    def fit_at(self, cand, value):
        """``((admissible, training log ratio), value, fit)`` of ``cand`` at ``value``; a
        ValueError when the record's rows cannot fit it."""
        spec = cand.spec(value)
        fit = self.fit(spec, self.theta0)
        if cand.refits:
            # a flow law not linear in theta: solve theta_fit(theta0) = theta0 by secant steps on
            # h(u) = ln theta_fit(e^u) - u (plain iteration converges slowly when the sag dominates)
            def h(u):
                f = self.fit(spec, math.exp(u))
                return math.log(max(f.theta["chamber"]["CdW_sqrt_rho"], 1e-6)) - u, f
            u0 = math.log(self.theta0)
            h0 = math.log(max(fit.theta["chamber"]["CdW_sqrt_rho"], 1e-6)) - u0
            u1 = u0 + h0
            for _ in range(cand.refits):
                h1, fit = h(u1)
                if abs(h1) < 1e-3 or h1 == h0:
                    break
                u0, u1, h0 = u1, u1 - h1 * (u1 - u0) / (h1 - h0), h1
                u1 = min(max(u1, u0 - 1.0), u0 + 1.0)
            if abs(h1) > THETA_TOL:
                # no orifice coefficient reproduces itself: the law cannot pass the record's flows
                # (a supply line this resistive chokes them), so this value explains nothing
                raise ValueError(f"no orifice coefficient is consistent with {cand.name} = {value:.3g}: "
                                 "the flow law cannot pass the record's flows")
        tr, _ = _mse_split(fit, self.split, self.floors)
        # an unphysical fit (a friction dip, not a hump) ranks below every physical one
        return (cand.admissible(fit.theta), _log_ratio(self.nom_tr, tr)), value, fit

    def score(self, cand, physical: bool, fit: Fit, opt: AuditOptions) -> tuple[float, dict, dict]:
        """The held-out score [-] of ``cand``'s ``fit`` (module docstring, step 2) and its
        residual variances per block on the training and the held-out part."""
        tr, te = _mse_split(fit, self.split, self.floors)
        score = _log_ratio(self.nom_te, te) - opt.penalty * cand.n_extra
        if not improves_training(_log_ratio(self.nom_tr, tr), opt.threshold) or not physical:
            score = min(score, 0.0)  # hardly better on the data it was fitted to (noise), or unphysical
        return score, tr, te


def _twin(s: np.ndarray, simulated: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The nominal model's twin of a record: its command ug, the nominal model's free run as the
    measured channels, and white noise of the record's own noise level per channel
    (``Signals.sigma``, seeded by ``TWIN_SEED``). It holds no effect by construction, so what a
    candidate scores on it is what the equations make of this rig's motion at this sample rate."""
    twin = np.array(s, dtype=float)
    noise = np.random.default_rng(TWIN_SEED).standard_normal(simulated.shape)
    twin[:, 1:] = simulated + noise * np.asarray(sigma, dtype=float)[None, :]
    return twin
