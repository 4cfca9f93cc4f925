"""Whole-model prediction-error (output-error with Kalman correction) estimate of the force AND chamber
parameters: EKF over (x1, x2, p1, p2) driven by measured x5, measured x1/p1/p2, parameters fitted by
Gauss-Newton on the whitened innovations (scipy least_squares). SE from the Gauss-Newton Hessian.

theta = [m, B_fv, f_c, K_t, 1/beta, CdW/sqrt(rho), C_ip, C_ep]
"""
import math
import numpy as np
from numba import njit
import sys
import os  # noqa: F401
from plant_sim.model import orifice_z


@njit(cache=True)
def _deriv(x, x5, th, rc, out):
    m, B, fc, Kt, ib, cd, cip, cep = th[0], th[1], th[2], th[3], th[4], th[5], th[6], th[7]
    a1, a2, v10, v20, ps, fl = rc[0], rc[1], rc[2], rc[3], rc[4], rc[5]
    x1, x2, p1, p2 = x[0], x[1], x[2], x[3]
    z1, z2 = orifice_z(x5, p1, p2, ps)
    v1 = v10 + a1 * x1
    v2 = v20 - a2 * x1
    sg = 1.0 if x2 > 0.0 else (-1.0 if x2 < 0.0 else 0.0)
    out[0] = x2
    out[1] = (a1 * p1 - a2 * p2 - fl - B * x2 - fc * sg - Kt * x1) / m
    leak = cip * (p1 - p2)
    out[2] = (cd * x5 * z1 - a1 * x2 - leak - cep * p1) / (v1 * ib)
    out[3] = (-cd * x5 * z2 + a2 * x2 + leak - cep * p2) / (v2 * ib)


@njit(cache=True)
def _x5_at(x5, k, tau):
    """Cubic (Catmull-Rom) interpolation of x5 between samples k and k+1, tau in [0, 1]."""
    n = x5.shape[0]
    p0 = x5[max(k - 1, 0)]; p1 = x5[k]; p2 = x5[min(k + 1, n - 1)]; p3 = x5[min(k + 2, n - 1)]
    t2 = tau * tau; t3 = t2 * tau
    return 0.5 * (2 * p1 + (-p0 + p2) * tau + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2 + (-p0 + 3 * p1 - 3 * p2 + p3) * t3)


@njit(cache=True)
def _step(x, x5, k, th, rc, h, ns, out):
    """RK4 with ns substeps from sample k to k+1; x5 interpolated."""
    y = x.copy()
    k1 = np.empty(4); k2 = np.empty(4); k3 = np.empty(4); k4 = np.empty(4); t = np.empty(4)
    dt = h / ns
    for i in range(ns):
        ta = i / ns; tm = (i + 0.5) / ns; tb = (i + 1.0) / ns
        xa = _x5_at(x5, k, ta); xm = _x5_at(x5, k, tm); xb = _x5_at(x5, k, tb)
        _deriv(y, xa, th, rc, k1)
        for j in range(4): t[j] = y[j] + 0.5 * dt * k1[j]
        _deriv(t, xm, th, rc, k2)
        for j in range(4): t[j] = y[j] + 0.5 * dt * k2[j]
        _deriv(t, xm, th, rc, k3)
        for j in range(4): t[j] = y[j] + dt * k3[j]
        _deriv(t, xb, th, rc, k4)
        for j in range(4):
            y[j] += dt / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
    out[:] = y


@njit(cache=True)
def ekf_innov(meas, x5, th, rc, h, ns, sig, q, n0):
    """Whitened innovations (3 per sample from n0 on). meas (N,3) = x1, p1, p2."""
    N = meas.shape[0]
    R = np.diag(np.array([sig[0] ** 2, sig[1] ** 2, sig[2] ** 2]))
    # process noise per step: x2 (model error), p1/p2 (x5 noise and model error)
    Q = np.diag(np.array([0.0, q[0] ** 2, q[1] ** 2, q[2] ** 2]))
    x = np.array([meas[0, 0], 0.0, meas[0, 1], meas[0, 2]])
    P = np.diag(np.array([sig[0] ** 2, 1e-4, sig[1] ** 2, sig[2] ** 2]))
    out = np.zeros((N - n0) * 3)
    xn = np.empty(4); xp = np.empty(4)
    F = np.empty((4, 4))
    H = np.zeros((3, 4)); H[0, 0] = 1.0; H[1, 2] = 1.0; H[2, 3] = 1.0
    scale = np.array([1e-6, 1e-4, 10.0, 10.0])
    for k in range(N):
        if k > 0:
            _step(x, x5, k - 1, th, rc, h, ns, xn)
            for j in range(4):
                xd = x.copy(); xd[j] += scale[j]
                _step(xd, x5, k - 1, th, rc, h, ns, xp)
                for i in range(4):
                    F[i, j] = (xp[i] - xn[i]) / scale[j]
            # x5 noise -> pressure process noise (flow sensitivity)
            ps = rc[4]
            z1, z2 = orifice_z(x5[k], xn[2], xn[3], ps)
            v1 = rc[2] + rc[0] * xn[0]; v2 = rc[3] - rc[1] * xn[0]
            g1 = th[5] * z1 / (v1 * th[4]) * h * sig[3]
            g2 = -th[5] * z2 / (v2 * th[4]) * h * sig[3]
            P = F @ P @ F.T + Q
            P[2, 2] += g1 * g1; P[3, 3] += g2 * g2; P[2, 3] += g1 * g2; P[3, 2] += g1 * g2
            x[:] = xn
        y = meas[k] - H @ x
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        if k >= n0:
            L = np.linalg.cholesky(S)
            w = np.linalg.solve(L, y)
            out[(k - n0) * 3:(k - n0) * 3 + 3] = w
        x[:] = x + K @ y
        P = (np.eye(4) - K @ H) @ P
        P = 0.5 * (P + P.T)
    return out


NOMP = np.array([100.0, 1e4, 10.0, 1e6, 1e-9, 1e-3, 1e-11, 1e-11])


def pem_fit(samples, th0, rc, h, sig, q=(1e-5, 30.0, 30.0), ns=4, n0=50, free=None, max_nfev=30):
    """Least-squares fit of the whitened innovations. Returns theta, SE (from J'J), result."""
    from scipy.optimize import least_squares
    meas = np.ascontiguousarray(samples[:, 1:4])
    x5 = np.ascontiguousarray(samples[:, 4])
    th0 = np.asarray(th0, float)
    free = np.arange(8) if free is None else np.asarray(free)
    rc = np.asarray(rc, float); sig = np.asarray(sig, float); q = np.asarray(q, float)

    def fun(u):
        th = th0.copy()
        th[free] = u * NOMP[free]
        return ekf_innov(meas, x5, th, rc, h, ns, sig, q, n0)

    u0 = th0[free] / NOMP[free]
    res = least_squares(fun, u0, method="lm", x_scale="jac", max_nfev=max_nfev * (len(free) + 1))
    th = th0.copy(); th[free] = res.x * NOMP[free]
    J = res.jac
    cov = np.linalg.inv(J.T @ J)
    # innovations are whitened: their variance should be ~1; scale by the fitted residual variance
    s2 = res.fun @ res.fun / (len(res.fun) - len(free))
    se = np.full(8, np.nan)
    se[free] = np.sqrt(np.diag(cov) * max(s2, 1.0)) * NOMP[free]
    return th, se, res, s2
