"""The identifier's regression rows: each equation's row at one instant, from its filters'
outputs into its estimator, and the residual statistics the read-out's standard errors need.

The equations and why each takes the form it does are in ``monitor.identify``'s docstring. Rows
are scaled (``monitor.scaling``) so that every parameter is O(1). Each row kernel refuses a
non-finite row (the estimator leaves its state as it was) and counts the rows it took.
Residual streams (``layout.N_STREAMS``): 0 force, 1 and 2 the chambers, 3 valve, 4 force with
observed pressures, 5 the valve's static gain.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .estimates import observer_refresh
from .force_observer import OBS_REFRESH, ne_update, obs_row
from .ident_model import IdentModel
from .layout import (
    C_KF, C_KP, C_V10, C_V20, H_GUARD, H_IV, H_IV_START, H_OBS_STEP, H_STEP_TOL, H_WC, N_CH, N_LAGS, O_BC,
    O_OBS_IC, O_OBS_STEP, O_P_C, O_P_F, O_P_K, O_P_V, O_RES_COV, O_RES_E2, O_RES_HIST, O_RES_W, O_RING, O_ROWS,
    O_ROWS_K, O_ROWS_O, O_SLOW, O_TH_C, O_TH_F, O_TH_K, O_TH_V, O_XH,
)
from .rls import riv_update, rls_update
from .scaling import THETA_NOM_C, THETA_NOM_F, THETA_NOM_K, X5_NOM, Y_NOM_C, Y_NOM_F


@njit(cache=True, error_model="numpy")
def ring(st, lag, ch):
    """Channel ch (0 ug [V], 1 x1 [m], 2 x3 [Pa], 3 x4 [Pa], 4 x5 [m]) of the sample ``lag``
    samples before the newest. The ring is a shift register, slot ``lag`` holding that sample,
    so the hot path takes no modulo."""
    return st[O_RING + lag * N_CH + ch]


@njit(cache=True, error_model="numpy")
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(cache=True, error_model="numpy")
def residual_stats(st, stream, e, lam):
    """Add the a-posteriori residual e of a row of residual ``stream`` to its forgetting-weighted
    count, sum of squares and lagged cross products (the autocorrelation over N_LAGS lags)."""
    w = O_RES_W + stream
    st[w] = lam * st[w] + 1.0
    st[O_RES_E2 + stream] = lam * st[O_RES_E2 + stream] + e * e
    hb = O_RES_HIST + stream * N_LAGS
    cb = O_RES_COV + stream * N_LAGS
    for j in range(N_LAGS):
        st[cb + j] = lam * st[cb + j] + e * st[hb + j]
    for j in range(N_LAGS - 1, 0, -1):
        st[hb + j] = st[hb + j - 1]
    st[hb] = e


@njit(cache=True, error_model="numpy")
def _valve_row(st, rc, hyper, phi, z):
    """Valve ARX(2,3) row at the newest sample into phi (5,) with its instruments z (5,) (needs
    three samples in the ring); returns the scaled target and whether ug steps inside the row."""
    kp, kf = rc[C_KP], rc[C_KF]
    du0 = kp * (ring(st, 0, 0) - kf * ring(st, 0, 1))
    du1 = kp * (ring(st, 1, 0) - kf * ring(st, 1, 1))
    du2 = kp * (ring(st, 2, 0) - kf * ring(st, 2, 1))
    y = ring(st, 0, 4) / X5_NOM
    phi[0] = -ring(st, 1, 4) / X5_NOM
    phi[1] = -ring(st, 2, 4) / X5_NOM
    phi[2] = du0
    phi[3] = du1
    phi[4] = du2
    th = st[O_TH_V:O_TH_V + 5]
    # auxiliary model: simulate x5 from du alone with the current estimate
    xh1, xh2 = st[O_XH], st[O_XH + 1]
    a1, a2 = th[0], th[1]
    stable = abs(a2) < 1.0 and abs(a1) < 1.0 + a2
    rows_v = st[O_ROWS + 2]
    use_iv = hyper[H_IV] > 0.0 and rows_v >= hyper[H_IV_START] and stable
    if use_iv:
        z[0] = -xh1
        z[1] = -xh2
    else:
        z[0] = phi[0]
        z[1] = phi[1]
        xh1, xh2 = -phi[0], -phi[1]
    z[2], z[3], z[4] = du0, du1, du2
    xh = -a1 * xh1 - a2 * xh2 + th[2] * du0 + th[3] * du1 + th[4] * du2
    if not (use_iv and math.isfinite(xh)):
        xh = y
    st[O_XH + 1] = xh1
    st[O_XH] = xh
    step = abs(ring(st, 0, 0) - 2.0 * ring(st, 1, 0) + ring(st, 2, 0)) > hyper[H_STEP_TOL]
    return y, step


@njit(cache=True, error_model="numpy", inline="always")
def valve_rows(st, rc, hyper, phi, z, lam, pmax, w):
    """The valve row at the newest sample by recursive IV, unless ug steps inside it (no finite
    model follows a jump between samples)."""
    y, step = _valve_row(st, rc, hyper, phi, z)
    if step:
        return
    th = st[O_TH_V:O_TH_V + 5]
    P = st[O_P_V:O_P_V + 25]
    e = riv_update(th, P, phi, z, y, lam, pmax, w)
    if math.isfinite(e):
        st[O_ROWS + 2] += 1.0
        residual_stats(st, 3, y - _dot(phi, th), lam)


@njit(cache=True, error_model="numpy", inline="always")
def chamber_rows(st, rc, yc, phi, lam, pmax, w):
    """The two chamber rows of one instant from the chamber filters' outputs yc (N_CH_SVF, 3),
    each forgetting by sqrt(lam)."""
    lam2 = math.sqrt(lam)
    v10, v20 = rc[C_V10], rc[C_V20]
    th = st[O_TH_C:O_TH_C + 4]
    P = st[O_P_C:O_P_C + 16]
    s1 = THETA_NOM_C / Y_NOM_C
    # each chamber equation times V_i0 / V_i: the rows stay in flow units [m^3/s], as the paper weights them
    phi[0] = v10 * yc[0, 1] * s1[0]
    phi[1] = -yc[4, 0] * s1[1]
    phi[2] = yc[6, 0] * s1[2]
    phi[3] = yc[8, 0] * s1[3]
    yv = -v10 * yc[2, 1] / Y_NOM_C
    e = rls_update(th, P, phi, yv, lam2, pmax, w)
    ok = math.isfinite(e)
    if ok:
        # sensor noise reaches the pressure-rate regressor as V10 sF[n3]: its weight for the bias compensation
        st[O_BC + 1] = lam2 * st[O_BC + 1] + v10 * v10
        st[O_BC + 2] = lam2 * st[O_BC + 2]
        residual_stats(st, 1, yv - _dot(phi, th), lam2)
    phi[0] = v20 * yc[1, 1] * s1[0]
    phi[1] = yc[5, 0] * s1[1]
    phi[2] = -yc[7, 0] * s1[2]
    phi[3] = yc[9, 0] * s1[3]
    yv = -v20 * yc[3, 1] / Y_NOM_C
    e = rls_update(th, P, phi, yv, lam2, pmax, w)
    if ok and math.isfinite(e):
        st[O_ROWS + 1] += 1.0
        st[O_BC + 1] = lam2 * st[O_BC + 1]
        st[O_BC + 2] = lam2 * st[O_BC + 2] + v20 * v20
        residual_stats(st, 2, yv - _dot(phi, th), lam2)


@njit(cache=True, error_model="numpy", inline="always")
def force_rows(st, hyper, yf, phi, lam, pmax, w):
    """The force balance row from the force filters' outputs yf (N_FORCE_SVF, 3), unless a
    reversal or a stick is inside the filter's memory."""
    force_ok = st[O_SLOW] >= hyper[H_GUARD]
    phi[0] = yf[0, 2] * THETA_NOM_F[0] / Y_NOM_F
    phi[1] = yf[0, 1] * THETA_NOM_F[1] / Y_NOM_F
    phi[2] = yf[2, 0] * THETA_NOM_F[2] / Y_NOM_F
    phi[3] = yf[0, 0] * THETA_NOM_F[3] / Y_NOM_F
    phi[4] = THETA_NOM_F[4] / Y_NOM_F  # F_0: the filters pass a constant unchanged
    yv = yf[1, 0] / Y_NOM_F
    th = st[O_TH_F:O_TH_F + 5]
    P = st[O_P_F:O_P_F + 25]
    e = rls_update(th, P, phi, yv, lam, pmax, w) if force_ok else np.nan
    if math.isfinite(e):
        st[O_ROWS] += 1.0
        st[O_BC] = lam * st[O_BC] + 1.0
        residual_stats(st, 0, yv - _dot(phi, th), lam)


@njit(cache=True, error_model="numpy", inline="always")
def static_gain_rows(st, yk, phi, lam, pmax, w):
    """The valve's static gain K_sv from the continuous-time valve equation under the force SVF,
    x5 = K_sv du - (2 zeta / omega) x5' - (1 / omega^2) x5'' (eq 39-42), with yk (2, 3) the filter
    outputs of x5 [m] and du [V].

    Why a row of its own rather than the ARX's DC gain (b0 + b1 + b2) / (1 + a1 + a2): x1's noise
    reaches du through K_f and the ARX's three nearly collinear du columns, which left K_sv 0.06 %
    off at stress noise with an SE of 0.02 % (truth within +-3 SE in 6 of 10 seeds). Here du is
    low-passed at 80 rad/s and K_sv is its low-frequency ratio to x5: 0.027 % at stress noise
    (10 of 10), 0.011 % at realistic noise (ARX 0.02 %), 1e-6 noise-free (10 seeds). This row's
    omega and zeta are poor (x5's noise through s^2F: 4-9 %), so those come from the ARX with IV.
    """
    phi[0] = yk[1, 0] * (THETA_NOM_K[0] / X5_NOM)
    phi[1] = -yk[0, 1] * (THETA_NOM_K[1] / X5_NOM)
    phi[2] = -yk[0, 2] * (THETA_NOM_K[2] / X5_NOM)
    yv = yk[0, 0] / X5_NOM
    th = st[O_TH_K:O_TH_K + 3]
    P = st[O_P_K:O_P_K + 9]
    e = rls_update(th, P, phi, yv, lam, pmax, w)
    if math.isfinite(e):
        st[O_ROWS_K] += 1.0
        residual_stats(st, 5, yv - _dot(phi, th), lam)


@njit(cache=True, error_model="numpy", inline="always")
def observer_rows(st, hyper, m_f, m_c, m_o, g_f, g_c, phi, yo, phi_o, lam, w):
    """The force balance with observed pressures (``monitor.force_observer``) on the rows the
    plain force balance takes: phi holds that row's five scaled regressors, yo (N_OBS,
    OBS_ORDER) the observer filters' outputs, phi_o (N_OBS_PARAMS,) and w are scratch; hyper ..
    g_c the fields of ``IdentModel`` (one by one: see ``monitor.identify.identify_step``). Every
    OBS_REFRESH rows its solution is refreshed into the state (``monitor.estimates.observer_refresh``)."""
    if st[O_SLOW] < hyper[H_GUARD] or st[O_OBS_STEP] < hyper[H_OBS_STEP]:
        return
    for i in range(4):
        phi_o[i] = phi[i]
    phi_o[8] = phi[4]
    yv = obs_row(yo, hyper[H_WC], st[O_OBS_IC], Y_NOM_F, phi_o)
    e = ne_update(st, phi_o, yv, lam, O_TH_C, THETA_NOM_C, w)
    if math.isfinite(e):
        residual_stats(st, 4, e, lam)
    if st[O_ROWS_O] % OBS_REFRESH == 0.0:
        observer_refresh(st, IdentModel(hyper, m_f, m_c, m_o, g_f, g_c))
