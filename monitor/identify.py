"""Streaming identification of the paper's three models, one sample at a time, many rigs at once.

Our recipe (the paper's literal one is ``monitor.paper_recipe``), chosen by measurement
(see README "Noise"):

* **Force balance, eq (24)-(27)** and **chambers, eq (28)-(38)**: every signal of an
  equation goes through the same state-variable filter (``monitor.svf``), so derivatives
  come from the filter state and never from differencing noisy samples:

      F[A1 x3 - A2 x4 - F_L] = m s^2F[x1] + (B + f_v) sF[x1] + f_c F[sign x2] + K_t F[x1]
      -V10 sF[L1] = (1/beta_e) V10 sF[x3] - theta F[w1 x5 z1] + C_ip F[w1 (x3 - x4)] + C_ep F[w1 x3]
      -V20 sF[L2] = (1/beta_e) V20 sF[x4] + theta F[w2 x5 z2] - C_ip F[w2 (x3 - x4)] + C_ep F[w2 x4]

  with w_i = V_i0 / V_i(x1) and L_i = ln(V_i(x1) / V_i0): each chamber equation times
  V_i0 / V_i(x1) (so the rows stay in flow units [m^3/s]), since A1 x2 / V1 = d/dt ln V1
  (and -A2 x2 / V2 = d/dt ln V2). Every derivative is then the filter's exact derivative of
  a sampled signal, and no velocity enters. Measured
  noise-free on the paper's input: the form before, V1 x3' = V10 x3' + A1 ((x1 x3)' - x2 x3)
  with x2 from the Savitzky-Golay fit, left C_d W/sqrt(rho) 0.0075 % off, this 0.001 %.
  The chamber rows take the newest sample. The force rows take sign(x2) from a centred
  quadratic (Savitzky-Golay) fit over 2*SG_HALF+1 samples, so they refer to the instant
  SG_HALF samples back: every target and regressor of a row is aligned to the same instant.
  The pressure-rate regressor still carries filtered-differentiated sensor noise, which
  biases least squares toward zero (errors in variables: -0.5 % on 1/beta_e, C_d W/sqrt(rho)
  and C_ip at realistic noise). Bias compensation removes it: with S the accumulated
  covariance of the regressor noise (known from the filter's impulse response and the
  channel noise variance, itself estimated online from 4th differences),
  theta_bc = (R - S)^-1 r = (I - P S)^-1 theta.
* **Servo valve, eq (39)-(42)**: the paper's form ``-x6' = ...`` puts the noisiest second
  derivative in the target. We identify instead the exact discrete-time model of the
  2nd-order valve, x5(k) = -a1 x5(k-1) - a2 x5(k-2) + b0 du(k) + b1 du(k-1) + b2 du(k-2)
  (exact for piecewise-linear du), with recursive instrumental variables whose
  instruments come from an auxiliary model driven by du alone (Young's RIV), so sensor
  noise on x5 does not bias it. The poles map exactly to the continuous ones
  (z = exp(s h)): omega^2 = s1 s2, 2 zeta omega = -(s1 + s2); the DC gain is K_sv.
  Rows whose window spans a step in ug are skipped (no finite model follows a jump
  between samples).

All kernels are pure and work on one rig's flat state row (``monitor.layout``); the
fleet kernel loops over a batch of samples in arrival order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim.model import orifice_z

from .layout import (
    C_A1,
    C_A2,
    C_FL,
    C_KF,
    C_KP,
    C_PS,
    C_V10,
    C_V20,
    H_GUARD,
    H_H,
    H_IV,
    H_IV_START,
    H_LAM,
    H_NOISE_N,
    H_OBS,
    H_PMAX,
    H_STEP_GUARD,
    H_REST,
    H_REST_DECAY,
    H_OBS_STEP,
    H_STEP_TOL,
    H_VSTICK,
    H_WARM,
    H_WC,
    H_WC_DECAY,
    N_CH,
    N_CH_SVF,
    N_OBS,
    N_LAGS,
    O_BC,
    O_CLAMPED,
    O_N,
    O_NOISE,
    O_NOISE_N,
    O_OBS_IC,
    O_OBS_IN,
    O_OBS_KL,
    O_P_C,
    O_P_F,
    O_P_K,
    O_P_V,
    O_RES_COV,
    O_RES_E2,
    O_RES_HIST,
    O_RES_W,
    O_RING,
    O_ROWS,
    O_ROWS_K,
    O_ROWS_O,
    O_SINCE_STEP,
    O_SLOW,
    O_REST,
    O_EXC_C,
    O_OBS_STEP,
    O_SVF_C,
    O_SVF_F,
    O_SVF_K,
    O_SVF_O,
    O_TH_C,
    O_TH_F,
    O_TH_K,
    O_TH_V,
    O_XH,
    RING,
    SG_HALF,
)
from .estimates import observer_refresh
from .fourth_difference import D4_VARIANCE_GAIN
from .force_observer import OBS_REFRESH, ne_new_transient, ne_update, obs_bank_init, obs_bank_step, obs_inputs, obs_row
from .outlier_gate import gate_step
from .scaling import THETA_NOM_C, THETA_NOM_F, THETA_NOM_K, X5_NOM, Y_NOM_C, Y_NOM_F  # noqa: F401  (re-exported)
from .rls import riv_update, rls_update
from .svf import svf_bank_init, svf_bank_step

N_PARAMS = 12  # PARAM_NAMES: the paper's 11 and the valve's static gain K_sv

# the chamber rows count as unexcited while the mean square of the filtered pressure rates is
# under this many times what the sensors' noise alone gives (IdentOptions.rest_pause)
REST_EXCITATION = 4.0



@njit(cache=True, error_model="numpy")
def _ring(st, lag, ch):
    # value of channel ch, `lag` samples before the newest (the ring is a shift register:
    # slot `lag` holds that sample, so no modulo on the hot path)
    return st[O_RING + lag * N_CH + ch]


@njit(cache=True, error_model="numpy")
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(cache=True, error_model="numpy")
def _residual_stats(st, stream, e, lam):
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
def _noise_update(st, n, hyper):
    # running mean of squared 4th differences: D4_VARIANCE_GAIN times the noise variance
    if n < 4:
        return
    cnt = st[O_NOISE_N] + 1.0
    st[O_NOISE_N] = cnt
    w = 1.0 / min(cnt, hyper[H_NOISE_N])
    for c in range(4):
        ch = c + 1
        d4 = (_ring(st, 0, ch) - 4.0 * _ring(st, 1, ch) + 6.0 * _ring(st, 2, ch)
              - 4.0 * _ring(st, 3, ch) + _ring(st, 4, ch))
        v = d4 * d4
        cur = st[O_NOISE + c]
        if cnt > 50.0 and v > 100.0 * cur:
            v = 100.0 * cur  # a transient, not noise
        st[O_NOISE + c] = cur + w * (v - cur)


@njit(cache=True, error_model="numpy")
def _valve_row(st, rc, hyper, phi, z):
    """Valve ARX(2,3) row at the newest sample (needs three in the ring: n >= 2)."""
    kp, kf = rc[C_KP], rc[C_KF]
    du0 = kp * (_ring(st, 0, 0) - kf * _ring(st, 0, 1))
    du1 = kp * (_ring(st, 1, 0) - kf * _ring(st, 1, 1))
    du2 = kp * (_ring(st, 2, 0) - kf * _ring(st, 2, 1))
    y = _ring(st, 0, 4) / X5_NOM
    phi[0] = -_ring(st, 1, 4) / X5_NOM
    phi[1] = -_ring(st, 2, 4) / X5_NOM
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
    step = abs(_ring(st, 0, 0) - 2.0 * _ring(st, 1, 0) + _ring(st, 2, 0)) > hyper[H_STEP_TOL]
    return y, step


WORK_SIZE = 206


@njit(cache=True, error_model="numpy")
def scratch_2d() -> tuple:
    """The per-sample path's 2-D scratch: filter outputs of the force (3, 3), chamber (N_CH_SVF, 3),
    observer (5, 4) and static-gain (2, 3) banks."""
    return (np.empty((3, 3)), np.empty((N_CH_SVF, 3)), np.empty((5, 4)), np.empty((2, 3)))
V_MIN = 0.01  # smallest chamber volume the chamber rows take, relative to V_i0

# The per-sample pieces (gate_step, identify_step, _consume, _force_rows, _chamber_rows) are inlined
# into their caller at numba's IR level: as separate compiled calls the 1000-rig batch ran at
# 782,000 samples/s, inlined at 925,000 (one thread, process time, same minutes); a fresh
# compile still takes about 22 s. Inlining the small helpers as well tripled the compile time
# for 3 % more.
@njit(cache=True, error_model="numpy", inline="always")
def identify_step(st: np.ndarray, rc: np.ndarray, hyper: np.ndarray, m_f: np.ndarray, m_c: np.ndarray,
                  m_o: np.ndarray, g_f: np.ndarray, g_c: np.ndarray, ug: float, x1: float, x3: float, x4: float,
                  x5: float, work: np.ndarray, bufs: tuple) -> None:
    """Take one sample (SI: V, m, Pa, Pa, m) of one rig, updating its state row in place.

    The outlier gate holds it for two samples; the sample two before it is consumed now.
    ``work`` is scratch space of WORK_SIZE floats and ``bufs`` the 2-D scratch of ``scratch_2d``
    (so the per-sample path allocates nothing, and reshapes nothing: a reshape of a slice calls
    numba's helper, ~100 instructions).
    """
    s = work[74:79]
    if gate_step(st, hyper, ug, x1, x3, x4, x5, s):
        _consume(st, rc, hyper, m_f, m_c, m_o, g_f, g_c, s[0], s[1], s[2], s[3], s[4], work, bufs)


@njit(cache=True, error_model="numpy", inline="always")
def _consume(st, rc, hyper, m_f, m_c, m_o, g_f, g_c, ug, x1, x3, x4, x5, work, bufs):
    """Consume one released sample: noise estimate, valve, chamber and force rows (plain and
    with observed pressures)."""
    n = int(st[O_N])
    for i in range(O_RING + RING * N_CH - 1, O_RING + N_CH - 1, -1):
        st[i] = st[i - N_CH]
    st[O_RING], st[O_RING + 1], st[O_RING + 2], st[O_RING + 3], st[O_RING + 4] = ug, x1, x3, x4, x5
    st[O_N] = n + 1
    lam = hyper[H_LAM]
    pmax = hyper[H_PMAX]
    _noise_update(st, n, hyper)

    phi5 = work[0:5]
    z5 = work[5:10]
    w = work[10:20]
    if n >= 2:
        y, step = _valve_row(st, rc, hyper, phi5, z5)
        if not step:
            th = st[O_TH_V:O_TH_V + 5]
            P = st[O_P_V:O_P_V + 25]
            e = riv_update(th, P, phi5, z5, y, lam, pmax, w)
            if math.isfinite(e):
                st[O_ROWS + 2] += 1.0
                _residual_stats(st, 3, y - _dot(phi5, th), lam)

    phi = work[59:63]
    # chambers in the log-volume form (module docstring): no velocity, so they take the newest
    # sample and their filters start with the first one (a rig starting from rest then has no
    # start-up transient; see warmup in IdentOptions)
    a1, a2 = rc[C_A1], rc[C_A2]
    # V_i / V_i0 - 1; an x1 that would empty a chamber is not physical (wrong config or units):
    # clamped so the filters stay finite (a NaN would stay in them until the next gap)
    r1 = a1 * x1 / rc[C_V10]
    r2 = -a2 * x1 / rc[C_V20]
    if r1 < V_MIN - 1.0 or r2 < V_MIN - 1.0:  # counted: evaluate and the monitor report it
        st[O_CLAMPED] += 1.0
        r1 = max(r1, V_MIN - 1.0)
        r2 = max(r2, V_MIN - 1.0)
    w1 = 1.0 / (1.0 + r1)
    w2 = 1.0 / (1.0 + r2)
    z1, z2 = orifice_z(x5, x3, x4, rc[C_PS])
    dp = x3 - x4
    u = work[63:63 + N_CH_SVF]
    u[0], u[1] = x3, x4
    u[2], u[3] = math.log1p(r1), math.log1p(r2)
    u[4], u[5] = w1 * x5 * z1, w2 * x5 * z2
    u[6], u[7], u[8], u[9] = w1 * dp, w2 * dp, w1 * x3, w2 * x4
    if hyper[H_OBS] > 0.0:
        # the observer's five inputs at this sample, from this part's volumes and orifice factors
        # (recomputing them at the force rows' instant cost two log1p and the orifice law), kept
        # SG_HALF samples for that instant
        for i in range(O_OBS_IN + N_OBS * (SG_HALF + 1) - 1, O_OBS_IN + N_OBS - 1, -1):
            st[i] = st[i - N_OBS]
        obs_inputs(st, O_OBS_IN, a1, a2, rc[C_FL], a1 * w1 / rc[C_V10], a2 * w2 / rc[C_V20], u[2], u[3],
                   x3, x4, x5, z1, z2)
    if n == 0:
        svf_bank_init(st, O_SVF_C, u)
    yc = bufs[1]
    svf_bank_step(m_c, st, O_SVF_C, u, yc)
    if n >= hyper[H_WARM] and not _chambers_rest(st, hyper, yc, g_c):
        _chamber_rows(st, rc, yc, phi, lam, pmax, w)

    if n < 2 * SG_HALF:
        return
    # force balance at the delayed instant c = n - SG_HALF: centred velocity and aligned signals
    num = 0.0
    den = 0.0
    for j in range(-SG_HALF, SG_HALF + 1):
        num += j * _ring(st, SG_HALF - j, 1)
        den += j * j
    v = num / (den * hyper[H_H])
    c1 = _ring(st, SG_HALF, 1)
    q1 = a1 * _ring(st, SG_HALF, 2) - a2 * _ring(st, SG_HALF, 3) - rc[C_FL]
    sg = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    v_noise = 3.0 * math.sqrt(st[O_NOISE] / D4_VARIANCE_GAIN / (den * hyper[H_H] * hyper[H_H]))
    if abs(v) < max(hyper[H_VSTICK], v_noise):
        st[O_SLOW] = 0.0
        st[O_REST] += 1.0
    else:
        st[O_SLOW] += 1.0
        st[O_REST] = 0.0
    u = work[63:66]
    u[0], u[1], u[2] = c1, q1, sg
    if n == 2 * SG_HALF:
        svf_bank_init(st, O_SVF_F, u)
    yf = bufs[0]
    svf_bank_step(m_f, st, O_SVF_F, u, yf)
    # the valve's static gain at the same instant (its own SVF rows, see _static_gain_rows)
    uk = work[148:150]
    uk[0] = _ring(st, SG_HALF, 4)
    uk[1] = rc[C_KP] * (_ring(st, SG_HALF, 0) - rc[C_KF] * c1)
    if n == 2 * SG_HALF:
        svf_bank_init(st, O_SVF_K, uk)
        st[O_SINCE_STEP] = 0.0
        st[O_OBS_STEP] = hyper[H_OBS_STEP]
    yk = bufs[3]
    svf_bank_step(m_f, st, O_SVF_K, uk, yk)
    if abs(_ring(st, SG_HALF - 1, 0) - 2.0 * _ring(st, SG_HALF, 0) + _ring(st, SG_HALF + 1, 0)) > hyper[H_STEP_TOL]:
        st[O_SINCE_STEP] = 0.0
        st[O_OBS_STEP] = 0.0
    else:
        st[O_SINCE_STEP] += 1.0
        st[O_OBS_STEP] += 1.0
    if n - 2 * SG_HALF >= hyper[H_WARM] and st[O_SINCE_STEP] >= hyper[H_STEP_GUARD]:
        _static_gain_rows(st, yk, work[156:159], lam, pmax, w)
    obs = hyper[H_OBS] > 0.0
    yo = bufs[2]
    if obs:
        # the observer's inputs at the same instant c
        uo = st[O_OBS_IN + N_OBS * SG_HALF:O_OBS_IN + N_OBS * (SG_HALF + 1)]
        if n == 2 * SG_HALF:
            obs_bank_init(st, O_SVF_O, uo, hyper[H_WC])
            ne_new_transient(st)
            st[O_OBS_IC] = 1.0
            r1 = max(a1 * c1 / rc[C_V10], V_MIN - 1.0)
            r2 = max(-a2 * c1 / rc[C_V20], V_MIN - 1.0)
            st[O_OBS_KL] = a1 * a1 / (rc[C_V10] * (1.0 + r1)) + a2 * a2 / (rc[C_V20] * (1.0 + r2))
        hold = n - 2 * SG_HALF < 2
        obs_bank_step(m_o, st, O_SVF_O, uo, yo, hold)
        if not hold:
            st[O_OBS_IC] *= hyper[H_WC_DECAY]
    if n - 2 * SG_HALF >= hyper[H_WARM]:
        pf = work[20:25]
        _force_rows(st, hyper, yf, pf, lam, pmax, w)
        if obs:
            _observer_rows(st, hyper, pf, yo, work[100:110], lam, work[160:206], g_f, g_c)


@njit(cache=True, error_model="numpy", inline="always")
def _force_rows(st, hyper, yf, phi, lam, pmax, w):
    """Force balance row, unless a reversal or a stick is inside the filter's memory."""
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
        _residual_stats(st, 0, yv - _dot(phi, th), lam)


@njit(cache=True, error_model="numpy", inline="always")
def _static_gain_rows(st, yk, phi, lam, pmax, w):
    """The valve's static gain K_sv from the continuous-time valve equation under the force SVF,
    x5 = K_sv du - (2 zeta / omega) x5' - (1 / omega^2) x5'' (eq 39-42), with yk (2, 3) the filter
    outputs of x5 and du. The ARX's DC gain (b0 + b1 + b2) / (1 + a1 + a2) gave K_sv 0.06 % off at
    stress noise with an SE of 0.02 % (truth within +-3 SE in 6/10 seeds): x1's noise reaches du
    through K_f and the three nearly collinear du columns. This row's du column is low-passed at
    80 rad/s, and K_sv is its low-frequency ratio to x5: 0.027 % at stress (10/10), 0.011 % at
    realistic noise (ARX 0.02 %), noise-free 1e-6 (prototype, 10 seeds). Its omega and zeta are
    poor (x5's noise through s^2F: 4-9 %), so the ARX with IV still gives those."""
    phi[0] = yk[1, 0] * (THETA_NOM_K[0] / X5_NOM)
    phi[1] = -yk[0, 1] * (THETA_NOM_K[1] / X5_NOM)
    phi[2] = -yk[0, 2] * (THETA_NOM_K[2] / X5_NOM)
    yv = yk[0, 0] / X5_NOM
    th = st[O_TH_K:O_TH_K + 3]
    P = st[O_P_K:O_P_K + 9]
    e = rls_update(th, P, phi, yv, lam, pmax, w)
    if math.isfinite(e):
        st[O_ROWS_K] += 1.0
        _residual_stats(st, 5, yv - _dot(phi, th), lam)


@njit(cache=True, error_model="numpy", inline="always")
def _observer_rows(st, hyper, phi, yo, phi9, lam, w, g_f, g_c):
    """The force balance with observed pressures (monitor.force_observer), on the rows the plain
    force balance takes: phi holds that row's four scaled regressors. Every OBS_REFRESH rows its
    solution is refreshed into the state (monitor.estimates.observer_refresh)."""
    if st[O_SLOW] < hyper[H_GUARD] or st[O_OBS_STEP] < hyper[H_OBS_STEP]:
        return
    for i in range(4):
        phi9[i] = phi[i]
    phi9[8] = phi[4]
    yv = obs_row(yo, hyper[H_WC], st[O_OBS_IC], Y_NOM_F, phi9)
    e = ne_update(st, phi9, yv, lam, O_TH_C, THETA_NOM_C, w)
    if math.isfinite(e):
        _residual_stats(st, 4, e, lam)
    if st[O_ROWS_O] % OBS_REFRESH == 0.0:
        observer_refresh(st, hyper, g_f, g_c)


@njit(cache=True, error_model="numpy", inline="always")
def _chambers_rest(st, hyper, yc, g_c):
    """Whether the chamber rows pause (IdentOptions.rest_pause): the piston still for H_REST
    samples (O_REST, the force part's count, a sample old here, as the naive twin has it) and
    the pressure rates' running mean square within REST_EXCITATION of the sensor noise's."""
    if hyper[H_REST] <= 0.0:
        return False
    d = hyper[H_REST_DECAY]
    st[O_EXC_C] = d * st[O_EXC_C] + (1.0 - d) * (yc[0, 1] * yc[0, 1] + yc[1, 1] * yc[1, 1])
    noise = g_c[1, 1] * (st[O_NOISE + 1] + st[O_NOISE + 2]) / D4_VARIANCE_GAIN
    return st[O_REST] >= hyper[H_REST] and st[O_EXC_C] <= REST_EXCITATION * noise


@njit(cache=True, error_model="numpy", inline="always")
def _chamber_rows(st, rc, yc, phi, lam, pmax, w):
    """The two chamber rows of one instant, each forgetting by sqrt(lam)."""
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
        _residual_stats(st, 1, yv - _dot(phi, th), lam2)
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
        _residual_stats(st, 2, yv - _dot(phi, th), lam2)


@njit(cache=True, error_model="numpy")
def fleet_step(states: np.ndarray, consts: np.ndarray, hyper: np.ndarray, m_f: np.ndarray, m_c: np.ndarray,
               m_o: np.ndarray, g_f: np.ndarray, g_c: np.ndarray, rig: np.ndarray, samples: np.ndarray) -> None:
    """Consume a batch of samples in arrival order: sample i (ug, x1, x3, x4, x5) belongs to rig[i]."""
    work = np.empty(WORK_SIZE)
    bufs = scratch_2d()
    for i in range(rig.shape[0]):
        r = rig[i]
        identify_step(states[r], consts[r], hyper, m_f, m_c, m_o, g_f, g_c,
                      samples[i, 0], samples[i, 1], samples[i, 2], samples[i, 3], samples[i, 4], work, bufs)
