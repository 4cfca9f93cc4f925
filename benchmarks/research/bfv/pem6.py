"""Whole-model PEM with the valve in the model: EKF over (x1, x2, p1, p2, x5, x6) driven by the command
ug (cubic-interpolated samples) through the loop du = K_p (ug - K_f x1); all four sensors are outputs.
theta = [m, B_fv, f_c, K_t, 1/beta, CdW/sqrt(rho), C_ip, C_ep, 2 zeta omega, omega^2, K_sv omega^2]
"""
import math
import numpy as np
from numba import njit
import sys, os

from plant_sim.model import orifice_z

NS = 6
NOMP6 = np.array([100.0, 1e4, 10.0, 1e6, 1e-9, 1e-3, 1e-11, 1e-11, 100.0, 1e4, 1.0])


@njit(cache=True)
def _deriv6(x, ug, th, rc, out):
    m, B, fc, Kt, ib, cd, cip, cep = th[0], th[1], th[2], th[3], th[4], th[5], th[6], th[7]
    c1, c2, c3 = th[8], th[9], th[10]
    a1, a2, v10, v20, ps, fl, kp, kf = rc[0], rc[1], rc[2], rc[3], rc[4], rc[5], rc[6], rc[7]
    x1, x2, p1, p2, x5, x6 = x[0], x[1], x[2], x[3], x[4], x[5]
    z1, z2 = orifice_z(x5, p1, p2, ps)
    v1 = v10 + a1 * x1
    v2 = v20 - a2 * x1
    sg = 1.0 if x2 > 0.0 else (-1.0 if x2 < 0.0 else 0.0)
    out[0] = x2
    out[1] = (a1 * p1 - a2 * p2 - fl - B * x2 - fc * sg - Kt * x1) / m
    leak = cip * (p1 - p2)
    out[2] = (cd * x5 * z1 - a1 * x2 - leak - cep * p1) / (v1 * ib)
    out[3] = (-cd * x5 * z2 + a2 * x2 + leak - cep * p2) / (v2 * ib)
    out[4] = x6
    out[5] = -c1 * x6 - c2 * x5 + c3 * kp * (ug - kf * x1)


@njit(cache=True)
def _interp(u, k, tau):
    n = u.shape[0]
    p0 = u[max(k - 1, 0)]; p1 = u[k]; p2 = u[min(k + 1, n - 1)]; p3 = u[min(k + 2, n - 1)]
    t2 = tau * tau; t3 = t2 * tau
    return 0.5 * (2 * p1 + (-p0 + p2) * tau + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2 + (-p0 + 3 * p1 - 3 * p2 + p3) * t3)


@njit(cache=True)
def _step6(x, ug, k, th, rc, h, ns, out):
    y = x.copy()
    k1 = np.empty(6); k2 = np.empty(6); k3 = np.empty(6); k4 = np.empty(6); t = np.empty(6)
    dt = h / ns
    for i in range(ns):
        ua = _interp(ug, k, i / ns); um = _interp(ug, k, (i + 0.5) / ns); ub = _interp(ug, k, (i + 1.0) / ns)
        _deriv6(y, ua, th, rc, k1)
        for j in range(6): t[j] = y[j] + 0.5 * dt * k1[j]
        _deriv6(t, um, th, rc, k2)
        for j in range(6): t[j] = y[j] + 0.5 * dt * k2[j]
        _deriv6(t, um, th, rc, k3)
        for j in range(6): t[j] = y[j] + dt * k3[j]
        _deriv6(t, ub, th, rc, k4)
        for j in range(6):
            y[j] += dt / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
    out[:] = y


@njit(cache=True)
def ekf6_innov(meas, ug, th, rc, h, ns, sig, q, n0):
    """meas (N, 4) = x1, p1, p2, x5. Whitened innovations from sample n0 on."""
    N = meas.shape[0]
    R = np.diag(sig ** 2)
    Q = np.diag(q ** 2)
    x = np.array([meas[0, 0], 0.0, meas[0, 1], meas[0, 2], meas[0, 3], 0.0])
    P = np.diag(np.array([sig[0] ** 2, 1e-4, sig[1] ** 2, sig[2] ** 2, sig[3] ** 2, 1e-6]))
    out = np.zeros((N - n0) * 4)
    xn = np.empty(6); xp = np.empty(6)
    F = np.empty((6, 6))
    H = np.zeros((4, 6)); H[0, 0] = 1.0; H[1, 2] = 1.0; H[2, 3] = 1.0; H[3, 4] = 1.0
    scale = np.array([1e-6, 1e-4, 10.0, 10.0, 1e-8, 1e-6])
    for k in range(N):
        if k > 0:
            _step6(x, ug, k - 1, th, rc, h, ns, xn)
            for j in range(6):
                xd = x.copy(); xd[j] += scale[j]
                _step6(xd, ug, k - 1, th, rc, h, ns, xp)
                for i in range(6):
                    F[i, j] = (xp[i] - xn[i]) / scale[j]
            P = F @ P @ F.T + Q
            x[:] = xn
        y = meas[k] - H @ x
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        if k >= n0:
            L = np.linalg.cholesky(S)
            w = np.linalg.solve(L, y)
            out[(k - n0) * 4:(k - n0) * 4 + 4] = w
        x[:] = x + K @ y
        P = (np.eye(6) - K @ H) @ P
        P = 0.5 * (P + P.T)
    return out


def pem6_fit(samples, th0, rc, h, sig, q=(0.0, 1e-5, 10.0, 10.0, 1e-9, 1e-6), ns=NS, n0=int(os.environ.get("PEM_N0", "50")), max_nfev=30):
    from scipy.optimize import least_squares
    meas = np.ascontiguousarray(samples[:, 1:5])
    ug = np.ascontiguousarray(samples[:, 0])
    th0 = np.asarray(th0, float)
    rc = np.asarray(rc, float); sig = np.asarray(sig, float); q = np.asarray(q, float)

    def fun(u):
        return ekf6_innov(meas, ug, u * NOMP6, rc, h, ns, sig, q, n0)

    res = least_squares(fun, th0 / NOMP6, method="lm", x_scale="jac", max_nfev=max_nfev * 12)
    th = res.x * NOMP6
    J = res.jac
    cov = np.linalg.inv(J.T @ J)
    s2 = res.fun @ res.fun / (len(res.fun) - len(th))
    se = np.sqrt(np.diag(cov) * max(s2, 1.0)) * NOMP6
    return th, se, res, s2
