"""Errors-in-variables least squares: the bias-compensated solve of the audit's equation blocks.

A column formed from filtered sensor signals (a pressure rate, an acceleration) carries noise,
which biases plain least squares toward zero. Each row's noise loading L (rows, columns, noise
sources) is known from the sensor noise through the filter, so the normal matrix's noise part
S = sum over rows of L L^T is removed: theta = (X'X - S)^-1 X'y. Where the noise rivals the
data in some direction of the columns the removal is capped (``COMPENSATION_MAX``).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

__all__ = ["compensated_lstsq", "noise_share", "COMPENSATION_MAX"]

COMPENSATION_MAX = 0.9
"""Largest share of the data's energy in any direction of the regressors that the noise
compensation removes [-]. Where the noise holds more, X'X - S is nearly singular or indefinite
and the compensated solution is noise: the chamber equation with entrained air at fault-grade
health and realistic noise (the air column and the 1/beta_e column carry the same pressure-rate
noise) reached 1.0-1.07 on tuning records, and its air fit then made the chamber residual 1.2
to 50000 times the nominal one. The force equation's fits on the tuning records looked at
reached 0.67-0.75 at realistic noise in the fault band (untouched) and 0.9-2.6 at stress noise."""


def noise_share(G: np.ndarray, S: np.ndarray) -> float:
    """The largest share of the data's energy that noise holds in any direction of the
    regressors [-]: max over u of u'Su / u'Gu (G = X'X, S the noise's part of it), the largest
    generalized eigenvalue; ``nan`` when G is singular."""
    try:
        return float(scipy.linalg.eigh(S, G, eigvals_only=True)[-1])
    except (np.linalg.LinAlgError, ValueError):
        return math.nan


def compensated_lstsq(X: np.ndarray, y: np.ndarray, noise_load: np.ndarray | None = None) -> np.ndarray:
    """Least squares, bias-compensated when the regressors' noise is known:
    theta = (X'X - c S)^-1 X'y with S = sum over rows of L L^T (errors in variables) and c = 1,
    or less where the noise holds more than ``COMPENSATION_MAX`` of the data in some direction
    (c = COMPENSATION_MAX / ``noise_share``). X is (rows, columns) and y (rows) in the
    equation's units; noise_load (rows, columns, noise sources) is each row's noise in each
    column per unit noise source, in the columns' units. Columns are scaled to unit rms first,
    so the result does not depend on their units."""
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale == 0] = 1.0
    Xs = X / scale
    if noise_load is None:
        th, *_ = np.linalg.lstsq(Xs, y, rcond=None)
        return th / scale
    L = noise_load / scale[None, :, None]
    G, S = Xs.T @ Xs, np.einsum("rik,rjk->ij", L, L)
    share = noise_share(G, S)
    if share > COMPENSATION_MAX:
        S = S * (COMPENSATION_MAX / share)
    th = np.linalg.solve(G - S, Xs.T @ y)
    return th / scale
