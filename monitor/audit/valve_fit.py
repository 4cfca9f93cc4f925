"""The valve equation of the audit, fitted by output error on raw samples.

The valve is the 2nd-order lag x5 = K_sv omega^2 / (s^2 + 2 zeta omega s + omega^2) du,
discretised with a first-order hold; its simulated response to the measured du is compared
with the measured spool position (no derivative of noisy samples is taken).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.optimize import minimize

__all__ = ["valve_response", "fit_valve", "VALVE_OMEGA", "VALVE_ZETA"]

VALVE_OMEGA = np.geomspace(20.0, 600.0, 18)  # [rad/s] valve natural frequencies searched
VALVE_ZETA = np.array([0.15, 0.3, 0.5, 0.7, 1.0, 1.5])  # [-] damping ratios searched


def _expm(x: np.ndarray) -> np.ndarray:
    """exp(x) of a small square matrix by scaling and squaring with a degree-16 Taylor series
    (after scaling, ||x|| <= 1/2: truncation error below 1e-19 relative). scipy's expm costs
    ~1 ms per 4x4 call in its setup, and the valve fit's Nelder-Mead polish calls it ~50 times
    per fit: most of an audit's time."""
    norm = float(np.max(np.sum(np.abs(x), axis=1)))
    k = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    y = x / (2.0 ** k)
    term = np.eye(len(x))
    out = term.copy()
    for i in range(1, 17):
        term = term @ y / i
        out += term
    for _ in range(k):
        out = out @ out
    return out


@lru_cache(maxsize=4096)
def _valve_filter(omega: float, zeta: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    # pure function of its arguments; memoised because the grid points recur in every fit.
    # First-order hold as scipy.signal.cont2discrete(..., method="foh"), on the balanced
    # realisation A = [[0, w], [-w, -2 zeta w]], B = [0, w]', C = [1, 0] of w^2/(s^2 + 2 zeta w s + w^2)
    # (entries ~w, not w^2: a small norm for the scaling and squaring)
    em = np.zeros((4, 4))
    em[0, 1], em[1, 0], em[1, 1], em[1, 2] = omega * h, -omega * h, -2.0 * zeta * omega * h, omega * h
    em[2, 3] = 1.0
    ms = _expm(em)
    ad, ms12, ms13 = ms[:2, :2], ms[:2, 2], ms[:2, 3]
    bd = ms12 - ms13 + ad @ ms13
    dd = ms13[0]
    den = np.array([1.0, -np.trace(ad), np.linalg.det(ad)])
    m = ad.copy()
    m[:, 0] -= bd  # A_d - B_d C_d with C_d = [1, 0]
    num = np.array([1.0, -np.trace(m), np.linalg.det(m)]) + (dd - 1.0) * den
    return num, den


@njit(cache=True)
def _filter2(b, a, x):  # pragma: no cover (compiled)
    # scipy.signal.lfilter(b, a, x) for a second-order filter with a[0] = 1 (transposed direct
    # form II, zero initial state); importing scipy.signal costs about a second
    y = np.empty_like(x)
    z1 = 0.0
    z2 = 0.0
    for k in range(x.shape[0]):
        xk = x[k]
        yk = b[0] * xk + z1
        z1 = b[1] * xk - a[1] * yk + z2
        z2 = b[2] * xk - a[2] * yk
        y[k] = yk
    return y


def valve_response(omega: float, zeta: float, h: float, du: np.ndarray) -> np.ndarray:
    """Unit-gain valve response [m/V * V] to du sampled with period h, first-order hold."""
    b, a = _valve_filter(float(omega), float(zeta), float(h))
    return _filter2(b, a, np.ascontiguousarray(du, dtype=float))


def fit_valve(b, h: float, train: np.ndarray) -> tuple[dict, np.ndarray]:
    """Output-error fit of the valve block ``b`` (``monitor.audit.residuals.Block``: du in X,
    spool position in y, an optional clip): grid over omega and zeta, Nelder-Mead polish, the
    gain by least squares at each point. Returns the parameters and the residuals on all rows."""
    du = b.X[:, 0]
    use = train & b.fit_mask
    y = b.y

    def cost(omega, zeta):
        omega = min(max(omega, 0.5 * VALVE_OMEGA[0]), 2.0 * VALVE_OMEGA[-1])
        zeta = min(max(zeta, 0.5 * VALVE_ZETA[0]), 2.0 * VALVE_ZETA[-1])
        g = valve_response(omega, zeta, h, du)[b.rows]
        gg = float(np.dot(g[use], g[use]))
        k = float(np.dot(g[use], y[use])) / gg if gg > 0 else 0.0
        pred = k * g
        if math.isfinite(b.clip):
            pred = np.clip(pred, -b.clip, b.clip)
        r = y - pred
        return float(np.mean(r[use] ** 2)), k, r

    best = None
    for omega in VALVE_OMEGA:
        for zeta in VALVE_ZETA:
            c = cost(omega, zeta)[0]
            if best is None or c < best[0]:
                best = (c, omega, zeta)
    z0 = np.log([best[1], best[2]])
    opt = minimize(lambda z: cost(*np.exp(z))[0], z0, method="Nelder-Mead",
                   options={"xatol": 2e-3, "fatol": 1e-9 * best[0], "maxfev": 50,
                            "initial_simplex": np.vstack([z0, z0 + [0.15, 0], z0 + [0, 0.15]])})
    omega, zeta = (float(v) for v in np.exp(opt.x))
    omega = min(max(omega, 0.5 * VALVE_OMEGA[0]), 2.0 * VALVE_OMEGA[-1])
    zeta = min(max(zeta, 0.5 * VALVE_ZETA[0]), 2.0 * VALVE_ZETA[-1])
    _, k, r = cost(omega, zeta)
    return {"omega_sv2": omega * omega, "two_zeta_omega": 2.0 * zeta * omega, "K_sv": k}, r
