"""The valve equation of the audit, fitted by output error on raw samples.

The valve is the 2nd-order lag x5 = K_sv omega^2 / (s^2 + 2 zeta omega s + omega^2) du,
discretised with a first-order hold; its simulated response to the measured du is compared
with the measured spool position (no derivative of noisy samples is taken).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.optimize import minimize
from scipy.signal import cont2discrete, lfilter

__all__ = ["valve_response", "fit_valve", "VALVE_OMEGA", "VALVE_ZETA"]

VALVE_OMEGA = np.geomspace(20.0, 600.0, 18)  # [rad/s] valve natural frequencies searched
VALVE_ZETA = np.array([0.15, 0.3, 0.5, 0.7, 1.0, 1.5])  # [-] damping ratios searched


@lru_cache(maxsize=4096)
def _valve_filter(omega: float, zeta: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    # pure function of its arguments; memoised because the grid points recur in every fit
    num, den = [omega * omega], [1.0, 2.0 * zeta * omega, omega * omega]
    b, a, _ = cont2discrete((num, den), h, method="foh")
    return np.ravel(b), np.ravel(a)


def valve_response(omega: float, zeta: float, h: float, du: np.ndarray) -> np.ndarray:
    """Unit-gain valve response [m/V * V] to du sampled with period h, first-order hold."""
    b, a = _valve_filter(float(omega), float(zeta), float(h))
    return lfilter(b, a, du)


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
