"""The audit's options and its result: what ``monitor.audit.audit`` takes and returns."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["AuditOptions", "CandidateResult", "AuditResult"]


@dataclass(frozen=True)
class AuditOptions:
    """Hyperparameters of the audit.

    Attributes
    ----------
    train_fraction : float
        Leading fraction of the record used for fitting (the rest is held out) [-].
    threshold : float
        Score (summed held-out log variance ratio) a candidate must exceed to be named [-].
    penalty : float
        Score charged per parameter an extension adds [-].
    margin : float
        Runner-up score, as a fraction of the winner's, above which the audit says it cannot
        tell them apart [-].
    free_run : bool
        Re-simulate every model (the gain); off for a quick ranking, which re-simulates only the
        nominal model and the candidates scoring above ``threshold`` (whose free run must not
        diverge to be named).
    """

    train_fraction: float = 0.7
    threshold: float = 0.15
    penalty: float = 0.01
    margin: float = 0.6
    free_run: bool = True

    def __post_init__(self):
        if not (0.2 <= self.train_fraction <= 0.9):
            raise ValueError(f"train_fraction must lie in [0.2, 0.9], got {self.train_fraction!r}")
        if not math.isfinite(self.threshold):
            raise ValueError(f"threshold must be finite, got {self.threshold!r}")


@dataclass(frozen=True)
class CandidateResult:
    """One candidate, fitted and scored.

    Attributes
    ----------
    name, equation : str
    value : object
        The searched parameter's best value (SI; sensor delay: (samples, in_loop)).
    score : float
        Held-out information-criterion score (higher = better; > threshold earns its place), less
        ``twin``.
    twin : float
        What the same extension at the same value scores on the nominal model's twin (the
        nominal free run with the record's noise level: no effect by construction), at least 0
        [-]; computed only for a candidate that scores above the threshold.
    residual_ratio : dict
        Held-out residual variance extended / nominal, per block.
    train_ratio : dict
        The same on the training part.
    gain : float
        Free-run held-out error reduction, 1 - mean NRMSE extended / mean NRMSE nominal (nan
        without free run, -inf when the extended model's free run diverged).
    freerun : dict
        Held-out per-channel {"nrmse", "fit"} of the extended model's free run.
    params : dict
        The identified parameters of the extended model (bus names, SI).
    effect : dict
        The fitted extension as ``plant_sim.params.Effects`` fields.
    plausible : bool
        Whether the simulated extension is one the candidate stands for (``Candidate.plausible``).
    """

    name: str
    equation: str
    value: object
    score: float
    residual_ratio: dict
    train_ratio: dict
    gain: float
    freerun: dict
    params: dict
    effect: dict
    caveat: str = ""
    plausible: bool = True
    twin: float = 0.0
    simulated: np.ndarray | None = field(default=None, repr=False, compare=False)
    residuals: dict = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class AuditResult:
    """What the audit found (compute, then present: see ``hydromon.report.audit``).

    Attributes
    ----------
    cause : str
        The effect name (the stronger one when two are named), "none", or "unexplained" (the
        residual keeps structure no candidate explains, or the nominal fit is impossible and no
        extension restores it).
    causes : tuple of str
        Every effect named (one or two; empty for "none" and "unexplained").
    words : str
        The verdict for a person: the cause in words and units, what it did to the nominal
        parameters, the gain, the confidence; or which equation fails and how.
    structure : dict
        Block -> {"share": held-out residual variance beyond noise / variance of the block's
        left side [-], "like": the signal the residual is most correlated with, "r": that
        correlation [-]} of the final model.
    confident : bool
        False when the best candidates cannot be told apart (see ``note``).
    note : str
    candidates : list of CandidateResult
        Best score first.
    params_nominal : dict
        Nominal identification on the training part (bus names, SI).
    freerun_nominal : dict
        Held-out per-channel {"nrmse", "fit"} of the nominal free run.
    residual_var_nominal : dict
        Held-out equation-error variance per block of the nominal model [N^2, (m^3/s)^2, m^2].
    split : int
        First held-out sample index.
    t : array
        Sample times [s].
    measured : array (N, 4)
        x1, x3, x4, x5 as recorded.
    simulated_nominal : array (N, 4) or None
    residuals_nominal : dict
        Block -> (sample index, residual) of the nominal model.
    """

    cause: str
    confident: bool
    note: str
    candidates: list
    params_nominal: dict
    freerun_nominal: dict
    residual_var_nominal: dict
    split: int
    t: np.ndarray = field(repr=False)
    measured: np.ndarray = field(repr=False)
    simulated_nominal: np.ndarray | None = field(default=None, repr=False)
    residuals_nominal: dict = field(default_factory=dict, repr=False)
    causes: tuple = ()
    words: str = ""
    structure: dict = field(default_factory=dict)
    obeys: bool = True
    """False when the nominal fit is impossible and no candidate restores it."""
    effect: dict = field(default_factory=dict)
    """Every named cause's fitted extension, fitted together when two are named (``Effects`` fields, SI)."""
    stribeck_reach: float | None = None
    """When nothing is named and Stribeck friction cannot be excluded: the smallest hump [N above
    Coulomb, v_s = 10 mm/s] this record would have named (``monitor.audit.reach``), ``inf`` when
    none up to 2560 N would; None when not asked."""
    unfitted: dict = field(default_factory=dict)
    """Candidates of the library that no searched value could be fitted for on this record, by
    name: why (they are not in ``candidates``, so not ranked)."""
    glitches: dict = field(default_factory=dict)
    """Sensor glitches replaced by their neighbours before the audit (``monitor.outlier_gate``,
    as the live monitor replaces them), per sensor x1, x3, x4, x5."""

    @property
    def best(self) -> CandidateResult | None:
        """The named cause's candidate (None when the cause is "none")."""
        for c in self.candidates:
            if c.name == self.cause:
                return c
        return None

    @property
    def gain(self) -> dict:
        """Before/after on held-out data for the named cause (or nominal twice when none)."""
        best = self.best
        after = best.freerun if best else self.freerun_nominal
        out = {ch: {"nrmse_nominal": self.freerun_nominal[ch]["nrmse"], "nrmse_extended": after[ch]["nrmse"],
                    "fit_nominal": self.freerun_nominal[ch]["fit"], "fit_extended": after[ch]["fit"]}
               for ch in self.freerun_nominal}
        out["free_run_error_reduction"] = best.gain if best else 0.0
        out["residual_variance"] = {
            g: {"nominal": self.residual_var_nominal[g],
                "extended": self.residual_var_nominal[g] * (best.residual_ratio[g] if best else 1.0)}
            for g in self.residual_var_nominal}
        return out
