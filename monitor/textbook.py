"""The naive twin's numerical building blocks, written the textbook way in numpy on small arrays.

``monitor.reference.NaiveIdentifier`` is built from these: recursive least squares and recursive
instrumental variables with ``np.outer``, the state-variable filter as matrix products, the
orifice factors in plain Python. They do what the compiled kernels (``monitor.rls``,
``monitor.svf``, ``plant_sim.model.orifice_z``) do, in the straightforward way.
"""

from __future__ import annotations

import math

import numpy as np


def orifice_z(xv: float, p1: float, p2: float, ps: float) -> tuple[float, float]:
    """The orifice pressure factors (z1, z2) [Pa^0.5] of ``plant_sim.model.orifice_z`` for spool
    position xv [m], chamber pressures p1, p2 [Pa] and supply pressure ps [Pa]."""
    if xv >= 0.0:
        return math.sqrt(2.0 * abs(ps - p1)) * np.sign(ps - p1), math.sqrt(2.0 * abs(p2))
    return math.sqrt(2.0 * abs(p1)), math.sqrt(2.0 * abs(ps - p2)) * np.sign(ps - p2)


def _forget(P: np.ndarray, lam: float, p_max: float) -> np.ndarray:
    """P / lam, unless that would take its trace past p_max (no windup without excitation)."""
    if lam < 1.0 and np.trace(P) * (1.0 / lam) <= p_max:
        return P * (1.0 / lam)
    return P


def rls(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, lam: float, p_max: float):
    """Textbook RLS with a symmetrised P, forgetting factor lam [-] and trace bound p_max;
    returns (theta, P, e), e the a-priori residual, or e = nan for a non-finite row."""
    if not (np.all(np.isfinite(phi)) and math.isfinite(y)):
        return theta, P, math.nan
    Pphi = P @ phi
    K = Pphi / (lam + phi @ Pphi)
    e = y - phi @ theta
    theta = theta + K * e
    P = P - np.outer(K, Pphi)
    P = 0.5 * (P + P.T)
    return theta, _forget(P, lam, p_max), e


def riv(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, z: np.ndarray, y: float, lam: float, p_max: float):
    """Recursive IV with instrument z; returns (theta, P, e) or e = nan for a bad row."""
    if not (np.all(np.isfinite(phi)) and math.isfinite(y) and np.all(np.isfinite(z))):
        return theta, P, math.nan
    Pz = P @ z
    denom = lam + phi @ Pz
    if not abs(denom) > 1e-300:
        return theta, P, math.nan
    e = y - phi @ theta
    K = Pz / denom
    theta = theta + K * e
    P = P - np.outer(K, phi @ P)
    return theta, _forget(P, lam, p_max), e


def svf_step(mats: tuple, x: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """One step of a cubic-hold state-variable filter (``monitor.svf``): mats = (Phi (3, 3), G
    (3, 4)), x = [state (3), u(k-1), u(k), u(k+1)], u = u(k+2). Returns the new x and the
    outputs [F u, sF u, s^2F u]."""
    phi, g = mats
    y = phi @ x[:3] + g @ np.array([x[3], x[4], x[5], u])
    return np.concatenate([y, x[4:6], [u]]), y


def svf_init(mats: tuple, u0: float) -> np.ndarray:
    """A filter state at rest on the constant input u0: (I - Phi) x = G 1 u0."""
    phi, g = mats
    return np.concatenate([np.linalg.solve(np.eye(3) - phi, g.sum(axis=1) * u0), [u0, u0, u0]])
