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
  a sampled signal, and no velocity enters. Measured noise-free on the paper's input, the
  direct form V1 x3' = V10 x3' + A1 ((x1 x3)' - x2 x3) with x2 from the Savitzky-Golay fit
  leaves C_d W/sqrt(rho) 0.0075 % off, this one 0.001 %.
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
equations' rows are ``monitor.equation_rows``, the per-sample scratch ``monitor.scratch``, and
the fleet kernel (``monitor.fleet_kernel``) loops over a batch of samples in arrival order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim.model import orifice_z

from .equation_rows import chamber_rows, force_rows, observer_rows, ring, static_gain_rows, valve_rows
from .force_observer import ne_new_transient, obs_bank_init, obs_bank_step, obs_inputs
from .fourth_difference import D4_VARIANCE_GAIN
from .layout import (
    C_A1, C_A2, C_FL, C_KF, C_KP, C_PS, C_V10, C_V20, H_H, H_LAM, H_NOISE_N, H_OBS, H_OBS_STEP, H_PMAX, H_REST,
    H_REST_DECAY, H_STEP_GUARD, H_STEP_TOL, H_VSTICK, H_WARM, H_WC, H_WC_DECAY, N_CH, N_OBS, O_CLAMPED, O_EXC_C,
    O_N, O_NOISE, O_NOISE_N, O_OBS_IC, O_OBS_IN, O_OBS_KL, O_OBS_STEP, O_REST, O_RING, O_SINCE_STEP, O_SLOW,
    O_SVF_C, O_SVF_F, O_SVF_K, O_SVF_O, RING, SG_HALF,
)
from .outlier_gate import gate_step
from .scratch import (
    W_GATE, W_NE, W_PHI_C, W_PHI_F, W_PHI_K, W_PHI_O, W_PHI_V, W_RLS, W_U_C, W_U_F, W_U_K, W_Z_V, new_scratch,
)
from .svf import svf_bank_init, svf_bank_step

N_PARAMS = 12  # PARAM_NAMES: the paper's 11 and the valve's static gain K_sv

# the chamber rows count as unexcited while the mean square of the filtered pressure rates is
# under this many times what the sensors' noise alone gives (IdentOptions.rest_pause)
REST_EXCITATION = 4.0

V_MIN = 0.01  # smallest chamber volume the chamber rows take, relative to V_i0 [-]


@njit(cache=True, error_model="numpy")
def _noise_update(st, n, hyper):
    """Running mean of the squared 4th differences of x1, x3, x4, x5 (``monitor.fourth_difference``:
    D4_VARIANCE_GAIN times the noise variance); a value 100 times the mean is a transient, capped."""
    if n < 4:
        return
    cnt = st[O_NOISE_N] + 1.0
    st[O_NOISE_N] = cnt
    w = 1.0 / min(cnt, hyper[H_NOISE_N])
    for c in range(4):
        ch = c + 1
        d4 = (ring(st, 0, ch) - 4.0 * ring(st, 1, ch) + 6.0 * ring(st, 2, ch)
              - 4.0 * ring(st, 3, ch) + ring(st, 4, ch))
        v = d4 * d4
        cur = st[O_NOISE + c]
        if cnt > 50.0 and v > 100.0 * cur:
            v = 100.0 * cur  # a transient, not noise
        st[O_NOISE + c] = cur + w * (v - cur)


# The per-sample pieces (gate_step, identify_step, _consume and the row kernels of
# monitor.equation_rows) are inlined into their caller at numba's IR level: as separate compiled
# calls the 1000-rig batch runs at 782,000 samples/s, inlined at 925,000 (one thread, process
# time); a fresh compile takes about 22 s. Inlining the small helpers (ring, residual_stats) as
# well would triple the compile time for 3 % more.
@njit(cache=True, error_model="numpy", inline="always")
def identify_step(st: np.ndarray, rc: np.ndarray,
                  hyper: np.ndarray, m_f: np.ndarray, m_c: np.ndarray, m_o: np.ndarray, g_f: np.ndarray,
                  g_c: np.ndarray,  # the fields of IdentModel
                  ug: float, x1: float, x3: float, x4: float, x5: float,
                  work: np.ndarray, y_f: np.ndarray, y_c: np.ndarray, y_o: np.ndarray,
                  y_k: np.ndarray) -> None:  # the fields of Scratch
    """Take one sample of one rig, ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m], updating its state
    row ``st`` in place (``rc`` its constant row, SI).

    The outlier gate holds it for two samples; the sample two before it is consumed now. The
    scratch arrays (``monitor.scratch.new_scratch``) are all the memory it writes besides
    ``st``: the per-sample path allocates nothing.

    The records' fields come one by one, unpacked by the caller before its loop: this body is
    inlined into that loop, and a field read from a record there costs a reference count on
    every sample (paired runs of fleet_step over 180,000 samples: 4.6 % slower than the flat
    arrays of the base commit with the records, 3.3 % faster with their fields).
    """
    s = work[W_GATE]
    if gate_step(st, hyper, ug, x1, x3, x4, x5, s):
        _consume(st, rc, hyper, m_f, m_c, m_o, g_f, g_c, s[0], s[1], s[2], s[3], s[4], work, y_f, y_c, y_o, y_k)


@njit(cache=True, error_model="numpy", inline="always")
def _consume(st, rc, hyper, m_f, m_c, m_o, g_f, g_c, ug, x1, x3, x4, x5, work, y_f, y_c, y_o, y_k):
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

    w = work[W_RLS]
    if n >= 2:
        valve_rows(st, rc, hyper, work[W_PHI_V], work[W_Z_V], lam, pmax, w)

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
    u = work[W_U_C]
    u[0], u[1] = x3, x4
    u[2], u[3] = math.log1p(r1), math.log1p(r2)
    u[4], u[5] = w1 * x5 * z1, w2 * x5 * z2
    u[6], u[7], u[8], u[9] = w1 * dp, w2 * dp, w1 * x3, w2 * x4
    if hyper[H_OBS] > 0.0:
        # the observer's five inputs at this sample, from this part's volumes and orifice factors
        # (recomputing them at the force rows' instant would cost two log1p and the orifice law),
        # kept SG_HALF samples for that instant
        for i in range(O_OBS_IN + N_OBS * (SG_HALF + 1) - 1, O_OBS_IN + N_OBS - 1, -1):
            st[i] = st[i - N_OBS]
        obs_inputs(st, O_OBS_IN, a1, a2, rc[C_FL], a1 * w1 / rc[C_V10], a2 * w2 / rc[C_V20], u[2], u[3],
                   x3, x4, x5, z1, z2)
    if n == 0:
        svf_bank_init(st, O_SVF_C, u)
    yc = y_c
    svf_bank_step(m_c, st, O_SVF_C, u, yc)
    if n >= hyper[H_WARM] and not _chambers_rest(st, hyper, yc, g_c):
        chamber_rows(st, rc, yc, work[W_PHI_C], lam, pmax, w)

    if n < 2 * SG_HALF:
        return
    # force balance at the delayed instant c = n - SG_HALF: centred velocity and aligned signals
    num = 0.0
    den = 0.0
    for j in range(-SG_HALF, SG_HALF + 1):
        num += j * ring(st, SG_HALF - j, 1)
        den += j * j
    v = num / (den * hyper[H_H])
    c1 = ring(st, SG_HALF, 1)
    q1 = a1 * ring(st, SG_HALF, 2) - a2 * ring(st, SG_HALF, 3) - rc[C_FL]
    sg = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    v_noise = 3.0 * math.sqrt(st[O_NOISE] / D4_VARIANCE_GAIN / (den * hyper[H_H] * hyper[H_H]))
    if abs(v) < max(hyper[H_VSTICK], v_noise):
        st[O_SLOW] = 0.0
        st[O_REST] += 1.0
    else:
        st[O_SLOW] += 1.0
        st[O_REST] = 0.0
    u = work[W_U_F]
    u[0], u[1], u[2] = c1, q1, sg
    if n == 2 * SG_HALF:
        svf_bank_init(st, O_SVF_F, u)
    yf = y_f
    svf_bank_step(m_f, st, O_SVF_F, u, yf)
    # the valve's static gain at the same instant (its own SVF rows, see static_gain_rows)
    uk = work[W_U_K]
    uk[0] = ring(st, SG_HALF, 4)
    uk[1] = rc[C_KP] * (ring(st, SG_HALF, 0) - rc[C_KF] * c1)
    if n == 2 * SG_HALF:
        svf_bank_init(st, O_SVF_K, uk)
        st[O_SINCE_STEP] = 0.0
        st[O_OBS_STEP] = hyper[H_OBS_STEP]
    yk = y_k
    svf_bank_step(m_f, st, O_SVF_K, uk, yk)
    if abs(ring(st, SG_HALF - 1, 0) - 2.0 * ring(st, SG_HALF, 0) + ring(st, SG_HALF + 1, 0)) > hyper[H_STEP_TOL]:
        st[O_SINCE_STEP] = 0.0
        st[O_OBS_STEP] = 0.0
    else:
        st[O_SINCE_STEP] += 1.0
        st[O_OBS_STEP] += 1.0
    if n - 2 * SG_HALF >= hyper[H_WARM] and st[O_SINCE_STEP] >= hyper[H_STEP_GUARD]:
        static_gain_rows(st, yk, work[W_PHI_K], lam, pmax, w)
    obs = hyper[H_OBS] > 0.0
    yo = y_o
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
        pf = work[W_PHI_F]
        force_rows(st, hyper, yf, pf, lam, pmax, w)
        if obs:
            observer_rows(st, hyper, m_f, m_c, m_o, g_f, g_c, pf, yo, work[W_PHI_O], lam, work[W_NE])


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


@njit(cache=True, error_model="numpy")
def fleet_step(states: np.ndarray, consts: np.ndarray, hyper: np.ndarray, m_f: np.ndarray, m_c: np.ndarray,
               m_o: np.ndarray, g_f: np.ndarray, g_c: np.ndarray, rig: np.ndarray, samples: np.ndarray) -> None:
    """Consume a batch of samples in arrival order: sample i, (ug [V], x1 [m], x3 [Pa], x4 [Pa],
    x5 [m]), belongs to rig[i]; ``states`` (n_rigs, STATE_SIZE) and ``consts`` (n_rigs,
    RIG_CONST_SIZE) by rig, the rest the fields of ``IdentModel``.

    The model's arrays come one by one, not as the record: numba's dispatcher types a
    NamedTuple argument in Python, field by field, and a plain array in C. At one sample a call
    (the bench's identify_single), the record takes 4.3 us a call, its arrays 2.9 us (measured).
    """
    work, y_f, y_c, y_o, y_k = new_scratch()
    for i in range(rig.shape[0]):
        r = rig[i]
        identify_step(states[r], consts[r], hyper, m_f, m_c, m_o, g_f, g_c, samples[i, 0], samples[i, 1], samples[i, 2],
                      samples[i, 3], samples[i, 4], work, y_f, y_c, y_o, y_k)
