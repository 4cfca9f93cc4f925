"""Batch replica of the streaming force regression (monitor/identify.py + estimates.py), with hooks:

* target_extra: per-sample extra force added to the target (e.g. -g(x1) of the s-form)
* cross: bias-compensation cross-term coefficient kh: target noise = -kh * (x1 noise)
* SE variants: recipe (Bartlett 8 lags, frequency-0 kappa), HAC sandwich (Bartlett, L lags).
"""
import math
import numpy as np
import sys
import os  # noqa: F401
from monitor import svf as svf_cubic
from monitor.layout import SG_HALF, SVF_STATE
import svf_foh

# svf="cubic": the package's SVF (cubic hold, state of SVF_STATE floats, outputs one sample late,
# every signal alike); svf="foh": the first-order hold of 1c54311 the session-3 numbers used.
SVF = {"cubic": (svf_cubic, SVF_STATE), "foh": (svf_foh, 3)}


def noise_gram(m):
    """The Gram matrix of whichever SVF built m (cubic: (3, 7); foh: (4, 3, 3))."""
    return (svf_foh if m.ndim == 3 else svf_cubic).noise_gram(m)

NOM = np.array([100.0, 1e4, 10.0, 1e6])


def noise_est(x, window=2000):
    """The identifier's running mean of squared 4th differences (white s^2 -> 70 s^2)."""
    cur = 0.0; cnt = 0
    out = np.zeros(len(x))
    for n in range(len(x)):
        if n >= 4:
            cnt += 1
            w = 1.0 / min(cnt, window)
            d4 = x[n] - 4 * x[n - 1] + 6 * x[n - 2] - 4 * x[n - 3] + x[n - 4]
            v = d4 * d4
            if cnt > 50 and v > 100 * cur:
                v = 100 * cur
            cur = cur + w * (v - cur)
        out[n] = cur
    return out


def hp_filter(u, b, h):
    """First-order high-pass s/(s+b), bilinear, started at rest on u[0] (output 0)."""
    if b <= 0:
        return u
    c = b * h / 2.0
    a1 = (1 - c) / (1 + c); g = 1.0 / (1 + c)
    y = np.zeros_like(u)
    for k in range(1, len(u)):
        y[k] = a1 * y[k - 1] + g * (u[k] - u[k - 1])
    return y


def force_rows(x1, q, h, a=80.0, warm=0.4, guard=0.1, vstick=2e-3, x1_noise=None, hp=0.0, svf="cubic"):
    """Rows (phi [s2F x1, sF x1, F sgn, F x1], y = F q) as the streaming recipe forms them.

    q: the per-sample force A1 x3 - A2 x4 - F_L (or any target), aligned with x1.
    Returns phi (nr, 4), y (nr,), idx (instants c of the rows), var_x1 (noise variance used)."""
    mod, nst = SVF[svf]
    m = mod.svf_matrices(a, h)
    svf_init, svf_step = mod.svf_init, mod.svf_step
    b_hp = hp
    N = len(x1)
    ne = noise_est(x1) if x1_noise is None else np.full(N, 70.0 * x1_noise ** 2)
    den = sum(j * j for j in range(-SG_HALF, SG_HALF + 1))
    st = np.zeros((3, nst)); y = np.zeros((3, 3))
    slow = 0.0
    rows, ys, idx = [], [], []
    warm_n = math.ceil(warm / h); guard_n = math.ceil(guard / h)
    for n in range(2 * SG_HALF, N):
        c = n - SG_HALF
        v = sum(j * x1[c + j] for j in range(-SG_HALF, SG_HALF + 1)) / (den * h)
        sg = 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
        vn = 3.0 * math.sqrt(ne[n] / 70.0 / (den * h * h))
        slow = 0.0 if abs(v) < max(vstick, vn) else slow + 1.0
        if hp > 0:
            # high-pass every signal of the equation (same LTI filter: the equation survives)
            if n == 2 * SG_HALF:
                hps = [[x1[c], 0.0], [q[c], 0.0], [sg, 0.0]]
            cc = b_hp * h / 2.0; a1h = (1 - cc) / (1 + cc); gh = 1.0 / (1 + cc)
            raw = (x1[c], q[c], sg)
            inp = []
            for i in range(3):
                yv = a1h * hps[i][1] + gh * (raw[i] - hps[i][0])
                hps[i] = [raw[i], yv]
                inp.append(yv)
        else:
            inp = (x1[c], q[c], sg)
        if n == 2 * SG_HALF:
            for i in range(3):
                svf_init(m, st[i], inp[i])
        for i in range(3):
            svf_step(m, st[i], inp[i], y[i])
        if n - 2 * SG_HALF < warm_n:
            continue
        if slow >= guard_n:
            rows.append([y[0, 2], y[0, 1], y[2, 0], y[0, 0]])
            ys.append(y[1, 0])
            idx.append(c)
    return np.array(rows), np.array(ys), np.array(idx), ne[-1] / 70.0, m


def fit(phi, y, var1, m, bc=True, kh=0.0, hac_lags=(8,), lags=8):
    """LS + bias compensation (+ optional cross-term) and SEs. Returns theta, dict of SEs, residuals."""
    sc = NOM
    X = phi * sc  # scaled regressors (theta scaled = theta / NOM)
    R = X.T @ X
    r = X.T @ y
    th = np.linalg.solve(R, r)
    e = y - X @ th
    n = len(y)
    g = noise_gram(m)
    out = (2, 1, -1, 0)
    S = np.zeros((4, 4)); s_y = np.zeros(4)
    for i in range(4):
        for j in range(4):
            if out[i] >= 0 and out[j] >= 0:
                S[i, j] = var1 * n * sc[i] * sc[j] * g[out[i], out[j]]
        if out[i] >= 0:
            # target noise F[-kh n1] (output 0 of the same filter) against regressor noise
            s_y[i] = -kh * var1 * n * sc[i] * g[out[i], 0]
    P = np.linalg.inv(R)
    th_bc = th
    Mi = np.eye(4)
    if bc:
        M = np.eye(4) - P @ S
        if np.linalg.norm(P @ S) < 0.5:
            th_bc = np.linalg.solve(R - S, r - s_y)
            Mi = np.linalg.inv(M)
    # residual of the compensated fit for SE (streaming uses RLS residuals of the uncompensated theta)
    s2 = e @ e / (n - 4)
    kap = 1.0
    for j in range(1, lags + 1):
        kap += 2.0 * (1.0 - j / (lags + 1.0)) * (e[j:] @ e[:-j]) / (e @ e)
    kap = min(max(kap, 0.25), 2 * lags + 1)
    ses = {}
    cov = Mi @ (P * s2 * kap) @ Mi.T
    ses["recipe"] = np.sqrt(np.diag(cov)) * sc
    for L in hac_lags:
        Xe = X * e[:, None]
        Om = Xe.T @ Xe
        for j in range(1, L + 1):
            G = Xe[j:].T @ Xe[:-j]
            Om += (1.0 - j / (L + 1.0)) * (G + G.T)
        cov = Mi @ P @ Om @ P @ Mi.T
        ses[f"hac{L}"] = np.sqrt(np.diag(cov)) * sc
    return th_bc * sc, ses, e
