"""Recursive least squares and recursive instrumental variables, as pure kernels.

Paper eqs (46)-(54) with a forgetting factor lam:

    K = P phi / (lam + phi' P phi)
    theta <- theta + K (y - phi' theta)
    P <- (P - K phi' P) / lam

Guards: P is re-symmetrised after every update; forgetting is skipped while
trace(P) exceeds ``p_max`` (so P stays bounded with no excitation: no windup); a
non-finite row is refused, leaving the state untouched. The IV form replaces P phi by
P z with an instrument z uncorrelated with the noise in phi (Young's recursive IV):

    K = P z / (lam + phi' P z);  theta <- theta + K e;  P <- (P - K phi' P) / lam

Kernels update ``theta`` and ``P`` in place and return the a-priori residual.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _finite_row(phi: np.ndarray, y: float) -> bool:
    if not math.isfinite(y):
        return False
    for v in phi:
        if not math.isfinite(v):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _forget(P: np.ndarray, n: int, lam: float, p_max: float) -> None:
    tr = 0.0
    for i in range(n):
        tr += P[i * n + i]
    if lam < 1.0 and tr * (1.0 / lam) <= p_max:
        inv = 1.0 / lam
        for i in range(n * n):
            P[i] *= inv


# P is passed flat, P[i * n + j] (a slice of a rig's state row as it lies): reshaping the slice
# to (n, n) on every row would call numba's reshape helper, ~100 instructions a call, 5-6 calls
# a sample on the hot path.
@njit(cache=True, error_model="numpy")
def rls_update(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, lam: float, p_max: float,
               w: np.ndarray) -> float:
    """One RLS update (in place). Returns the a-priori residual y - phi' theta (NaN if refused).

    Parameters
    ----------
    theta : array (n,)
    P : array (n * n,)
        Covariance, flat by rows (scaled by the noise variance it is the parameter covariance).
    phi : array (n,)
        Regressor row.
    y : float
        Target.
    lam : float
        Forgetting factor in (0, 1].
    p_max : float
        Trace bound beyond which forgetting pauses.
    w : array (>= n,)
        Scratch space (the hot path allocates nothing).
    """
    if not _finite_row(phi, y):
        return np.nan
    n = theta.shape[0]
    denom = lam
    e = y
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[i * n + j] * phi[j]
        w[i] = acc
        denom += phi[i] * acc
        e -= phi[i] * theta[i]
    for i in range(n):
        k = w[i] / denom
        theta[i] += k * e
        for j in range(n):
            P[i * n + j] -= k * w[j]
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (P[i * n + j] + P[j * n + i])
            P[i * n + j] = s
            P[j * n + i] = s
    _forget(P, n, lam, p_max)
    return e


@njit(cache=True, error_model="numpy")
def rls_step(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, lam: float, p_max: float) -> float:
    """``rls_update`` with P as an (n, n) matrix and its own scratch space (callers off the hot path)."""
    return rls_update(theta, P.reshape(P.size), phi, y, lam, p_max, np.empty(theta.shape[0]))


@njit(cache=True, error_model="numpy")
def riv_update(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, z: np.ndarray, y: float, lam: float,
               p_max: float, w: np.ndarray) -> float:
    """One recursive-IV update with instrument z (in place), P flat (n * n,) by rows; scratch w
    (>= 2 n). Returns the residual."""
    if not (_finite_row(phi, y) and _finite_row(z, 0.0)):
        return np.nan
    n = theta.shape[0]
    denom = lam
    e = y
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(n):
            a += P[i * n + j] * z[j]
            b += phi[j] * P[j * n + i]
        w[i] = a  # P z
        w[n + i] = b  # phi' P
        e -= phi[i] * theta[i]
    for i in range(n):
        denom += phi[i] * w[i]
    if not (abs(denom) > 1e-300):
        return np.nan
    for i in range(n):
        k = w[i] / denom
        theta[i] += k * e
        for j in range(n):
            P[i * n + j] -= k * w[n + j]
    _forget(P, n, lam, p_max)
    return e


class RLS:
    """Streaming RLS for one linear model y = phi' theta (a thin holder around ``rls_step``).

    Parameters
    ----------
    n : int
        Number of parameters.
    lam : float
        Forgetting factor in (0, 1].
    p0 : float
        Initial covariance P0 = p0 I (large: a weak prior, not a ridge).
    p_max : float
        Trace bound of P (anti-windup).
    """

    def __init__(self, n: int, lam: float = 1.0, p0: float = 1e8, p_max: float = 1e12):
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        if not (0 < lam <= 1):
            raise ValueError(f"lam must lie in (0, 1], got {lam}")
        if not (p0 > 0 and p_max >= p0 * n):
            raise ValueError(f"need p0 > 0 and p_max >= n p0, got p0={p0}, p_max={p_max}")
        self.n, self.lam, self.p0, self.p_max = n, lam, p0, p_max
        self.theta = np.zeros(n)
        self.P = np.eye(n) * p0

    def update(self, phi, y) -> np.ndarray:
        phi = np.asarray(phi, dtype=float)
        if phi.shape != (self.n,):
            raise ValueError(f"phi must have shape ({self.n},), got {phi.shape}")
        if not (np.all(np.isfinite(phi)) and math.isfinite(y)):
            raise ValueError("non-finite regressor or target")
        rls_step(self.theta, self.P, phi.copy(), float(y), self.lam, self.p_max)
        return self.theta.copy()
