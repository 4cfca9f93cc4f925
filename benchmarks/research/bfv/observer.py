"""Pressure observer: EKF (+ RTS smoother / fixed-lag) on the chamber equations.

State s = (s1, s2), s1 = p1 + beta ln V1(x1), s2 = p2 + beta ln V2(x1), so that
    ds1/dt = (beta/V1) (theta x5 z1 - C_ip (p1 - p2) - C_ep p1)
    ds2/dt = (beta/V2) (-theta x5 z2 + C_ip (p1 - p2) - C_ep p2)
exactly (V1 p1'/beta + A1 x1' = q1 - leak and (V1/beta) d/dt(beta ln V1) = A1 x1'):
the piston motion enters only through the (bounded, non-differentiated) volume term,
the spool position x5 drives it, and the measured pressures correct it.
"""
import math
import numpy as np
from numba import njit
import sys
import os  # noqa: F401
from plant_sim.model import orifice_z


@njit(cache=True)
def _rates(s1, s2, x1, x5, ib, th, cip, cep, a1, a2, v10, v20, ps):
    beta = 1.0 / ib
    v1 = v10 + a1 * x1
    v2 = v20 - a2 * x1
    p1 = s1 - beta * math.log(v1)
    p2 = s2 - beta * math.log(v2)
    z1, z2 = orifice_z(x5, p1, p2, ps)
    leak = cip * (p1 - p2)
    r1 = beta / v1 * (th * x5 * z1 - leak - cep * p1)
    r2 = beta / v2 * (-th * x5 * z2 + leak - cep * p2)
    # Jacobian d(r)/d(s) (dz/dp)
    if x5 >= 0.0:
        d1 = ps - p1
        dz1 = -1.0 / math.sqrt(2.0 * abs(d1)) if abs(d1) > 1.0 else 0.0
        dz2 = 1.0 / math.sqrt(2.0 * abs(p2)) if abs(p2) > 1.0 else 0.0
        j11 = beta / v1 * (th * x5 * dz1 - cip - cep)
        j12 = beta / v1 * cip
        j21 = beta / v2 * cip
        j22 = beta / v2 * (-th * x5 * dz2 - cip - cep)
    else:
        dz1 = 1.0 / math.sqrt(2.0 * abs(p1)) if abs(p1) > 1.0 else 0.0
        d2 = ps - p2
        dz2 = -1.0 / math.sqrt(2.0 * abs(d2)) if abs(d2) > 1.0 else 0.0
        j11 = beta / v1 * (th * x5 * dz1 - cip - cep)
        j12 = beta / v1 * cip
        j21 = beta / v2 * cip
        j22 = beta / v2 * (-th * x5 * dz2 - cip - cep)
    # sensitivity of rates to x5 (for process noise)
    g1 = beta / v1 * th * z1
    g2 = -beta / v2 * th * z2
    return r1, r2, j11, j12, j21, j22, g1, g2


@njit(cache=True)
def ekf(x1m, x3m, x4m, x5m, cp, rc, h, sig, qmod, order4=True):
    """Filtered states, predicted states and covariances for RTS.

    cp = [1/beta, theta, C_ip, C_ep]; rc = [A1, A2, V10, V20, ps];
    sig = [s_x1, s_p, s_p, s_x5]; qmod = extra process noise std per step [Pa] (model error).
    Returns sf (N,2), Pf (N,2,2), sp (N,2) predicted, Pp (N,2,2), F (N,2,2) transition k-1->k.
    """
    ib, th, cip, cep = cp[0], cp[1], cp[2], cp[3]
    a1, a2, v10, v20, ps = rc[0], rc[1], rc[2], rc[3], rc[4]
    beta = 1.0 / ib
    n = x1m.shape[0]
    sf = np.zeros((n, 2)); Pf = np.zeros((n, 2, 2)); sp = np.zeros((n, 2)); Pp = np.zeros((n, 2, 2))
    F = np.zeros((n, 2, 2))
    # measurement noise of y = p + beta ln V(x1m)
    c1 = beta * a1 / (v10 + a1 * x1m[0])
    c2 = -beta * a2 / (v20 - a2 * x1m[0])
    R = np.zeros((2, 2))
    s = np.zeros(2); P = np.zeros((2, 2))
    for k in range(n):
        v1 = v10 + a1 * x1m[k]
        v2 = v20 - a2 * x1m[k]
        c1 = beta * a1 / v1
        c2 = -beta * a2 / v2
        R[0, 0] = sig[1] ** 2 + (c1 * sig[0]) ** 2
        R[1, 1] = sig[2] ** 2 + (c2 * sig[0]) ** 2
        R[0, 1] = R[1, 0] = c1 * c2 * sig[0] ** 2
        y0 = x3m[k] + beta * math.log(v1)
        y1 = x4m[k] + beta * math.log(v2)
        if k == 0:
            s[0], s[1] = y0, y1
            P[:, :] = R
            F[0, 0, 0] = 1.0; F[0, 1, 1] = 1.0
            sp[0] = s; Pp[0] = P
        else:
            # predict: trapezoid (Heun) over [k-1, k] with measured x1, x5 at both ends
            r1a, r2a, j11, j12, j21, j22, g1a, g2a = _rates(s[0], s[1], x1m[k-1], x5m[k-1], ib, th, cip, cep, a1, a2, v10, v20, ps)
            e1 = s[0] + h * r1a; e2 = s[1] + h * r2a
            r1b, r2b, k11, k12, k21, k22, g1b, g2b = _rates(e1, e2, x1m[k], x5m[k], ib, th, cip, cep, a1, a2, v10, v20, ps)
            s0n = s[0] + 0.5 * h * (r1a + r1b)
            s1n = s[1] + 0.5 * h * (r2a + r2b)
            if order4 and k >= 2 and k + 1 < n:
                # 4th-order stencil h/24 (-r[k-2] + 13 r[k-1] + 13 r[k] - r[k+1]) (end-corrected trapezoid)
                r1m, r2m, _a, _b, _c, _d, _e, _f = _rates(sf[k-2, 0], sf[k-2, 1], x1m[k-2], x5m[k-2], ib, th, cip, cep, a1, a2, v10, v20, ps)
                r1b, r2b, _a, _b, _c, _d, _e, _f = _rates(s0n, s1n, x1m[k], x5m[k], ib, th, cip, cep, a1, a2, v10, v20, ps)
                e1 = 2.0 * s0n - s[0]; e2 = 2.0 * s1n - s[1]
                r1p, r2p, _a, _b, _c, _d, _e, _f = _rates(e1, e2, x1m[k+1], x5m[k+1], ib, th, cip, cep, a1, a2, v10, v20, ps)
                s0n = s[0] + h / 24.0 * (-r1m + 13.0 * r1a + 13.0 * r1b - r1p)
                s1n = s[1] + h / 24.0 * (-r2m + 13.0 * r2a + 13.0 * r2b - r2p)
            f11 = 1.0 + 0.5 * h * (j11 + k11); f12 = 0.5 * h * (j12 + k12)
            f21 = 0.5 * h * (j21 + k21); f22 = 1.0 + 0.5 * h * (j22 + k22)
            F[k, 0, 0] = f11; F[k, 0, 1] = f12; F[k, 1, 0] = f21; F[k, 1, 1] = f22
            # P <- F P F' + Q
            a = f11 * P[0, 0] + f12 * P[1, 0]; b = f11 * P[0, 1] + f12 * P[1, 1]
            c = f21 * P[0, 0] + f22 * P[1, 0]; d = f21 * P[0, 1] + f22 * P[1, 1]
            P00 = a * f11 + b * f12; P01 = a * f21 + b * f22
            P11 = c * f21 + d * f22
            # x5 noise at both ends, half weight each (trapezoid)
            gq1 = 0.5 * h * sig[3]; 
            q11 = gq1 ** 2 * (g1a ** 2 + g1b ** 2) + qmod[0] ** 2
            q22 = gq1 ** 2 * (g2a ** 2 + g2b ** 2) + qmod[0] ** 2
            q12 = gq1 ** 2 * (g1a * g2a + g1b * g2b)
            P[0, 0] = P00 + q11; P[0, 1] = P01 + q12; P[1, 0] = P01 + q12; P[1, 1] = P11 + q22
            s[0] = s0n; s[1] = s1n
            sp[k] = s; Pp[k] = P
            # update
            S00 = P[0, 0] + R[0, 0]; S01 = P[0, 1] + R[0, 1]; S11 = P[1, 1] + R[1, 1]
            det = S00 * S11 - S01 * S01
            i00 = S11 / det; i01 = -S01 / det; i11 = S00 / det
            K00 = P[0, 0] * i00 + P[0, 1] * i01; K01 = P[0, 0] * i01 + P[0, 1] * i11
            K10 = P[1, 0] * i00 + P[1, 1] * i01; K11 = P[1, 0] * i01 + P[1, 1] * i11
            e0 = y0 - s[0]; e1 = y1 - s[1]
            s[0] += K00 * e0 + K01 * e1
            s[1] += K10 * e0 + K11 * e1
            # Joseph-free: P = (I-K) P
            n00 = (1 - K00) * P[0, 0] - K01 * P[1, 0]; n01 = (1 - K00) * P[0, 1] - K01 * P[1, 1]
            n10 = -K10 * P[0, 0] + (1 - K11) * P[1, 0]; n11 = -K10 * P[0, 1] + (1 - K11) * P[1, 1]
            P[0, 0] = n00; P[0, 1] = 0.5 * (n01 + n10); P[1, 0] = P[0, 1]; P[1, 1] = n11
        sf[k] = s; Pf[k] = P
    return sf, Pf, sp, Pp, F


def rts(sf, Pf, sp, Pp, F):
    n = sf.shape[0]
    ss = sf.copy(); Ps = Pf.copy()
    for k in range(n - 2, -1, -1):
        G = Pf[k] @ F[k + 1].T @ np.linalg.inv(Pp[k + 1])
        ss[k] = sf[k] + G @ (ss[k + 1] - sp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
    return ss, Ps


@njit(cache=True)
def _fixed_lag_nb(sf, Pf, sp, Pp, F, lag):
    """fixed_lag's arithmetic compiled (same gains, same recursion; checked equal to 1e-12 rel)."""
    n = sf.shape[0]
    out = sf.copy()
    Gs = np.zeros((n, 2, 2))
    for k in range(n - 1):
        Gs[k] = Pf[k] @ F[k + 1].T @ np.linalg.inv(Pp[k + 1])
    for k in range(n):
        e = min(n - 1, k + lag)
        s = sf[e].copy()
        for j in range(e - 1, k - 1, -1):
            d0 = s[0] - sp[j + 1, 0]; d1 = s[1] - sp[j + 1, 1]
            s0 = sf[j, 0] + Gs[j, 0, 0] * d0 + Gs[j, 0, 1] * d1
            s1 = sf[j, 1] + Gs[j, 1, 0] * d0 + Gs[j, 1, 1] * d1
            s[0] = s0; s[1] = s1
        out[k] = s
    return out


def fixed_lag_py(sf, Pf, sp, Pp, F, lag):
    """Fixed-lag smoother: the estimate at k uses samples up to k+lag (RTS over a window)."""
    n = sf.shape[0]
    out = sf.copy()
    Gs = np.empty((n, 2, 2))
    for k in range(n - 1):
        Gs[k] = Pf[k] @ F[k + 1].T @ np.linalg.inv(Pp[k + 1])
    for k in range(n):
        e = min(n - 1, k + lag)
        s = sf[e].copy()
        for j in range(e - 1, k - 1, -1):
            s = sf[j] + Gs[j] @ (s - sp[j + 1])
        out[k] = s
    return out


def fixed_lag(sf, Pf, sp, Pp, F, lag):
    """Fixed-lag smoother: the estimate at k uses samples up to k+lag (RTS over a window).
    lag 0 is the filter itself."""
    return _fixed_lag_nb(sf, Pf, sp, Pp, F, int(lag))


def to_pressures(s, x1, cp, rc):
    beta = 1.0 / cp[0]
    a1, a2, v10, v20 = rc[0], rc[1], rc[2], rc[3]
    p1 = s[:, 0] - beta * np.log(v10 + a1 * x1)
    p2 = s[:, 1] - beta * np.log(v20 - a2 * x1)
    return p1, p2


def observe(samples, cp, rc, h, sig, qmod=0.0, mode="filter", lag=100, x1_out=None, order4=True):
    """Observed (x3, x4) for a run's samples (ug, x1, x3, x4, x5)."""
    x1, x3, x4, x5 = (np.ascontiguousarray(samples[:, i]) for i in (1, 2, 3, 4))
    sf, Pf, sp, Pp, F = ekf(x1, x3, x4, x5, np.asarray(cp, float), np.asarray(rc, float), h,
                            np.asarray(sig, float), np.array([qmod]), order4)
    if mode == "filter":
        s = sf
    elif mode == "rts":
        s, _ = rts(sf, Pf, sp, Pp, F)
    elif mode == "lag":
        s = fixed_lag(sf, Pf, sp, Pp, F, lag)
    else:
        raise ValueError(mode)
    return to_pressures(s, x1 if x1_out is None else x1_out, cp, rc)
