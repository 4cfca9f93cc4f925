"""Record-level refinement: a whole-model prediction-error fit of a finished record (batch).

The streaming identifier fits each equation on its own, so the force balance sees the
chamber pressures only through their sensors: at realistic noise (5 kPa) B + f_v is 4.4 %
off on the paper's 10 s input, while the record holds enough to know it to 0.56 % (the
Cramer-Rao bound of the whole model, ``benchmarks/crlb.py``, without the start from rest).
The information is in the chamber equations: the spool position (0.5 um noise) and the
piston motion pin the true pressures far better than the pressure sensors.

This fits all 11 parameters at once: an extended Kalman filter over the whole model (piston
x1, x2; chamber pressures p1, p2; spool x5, x6; the paper's eqs 16-21, driven by the
recorded command ug through the loop du = K_p (ug - K_f x1)) predicts each sample from the
previous ones; the parameters minimise the whitened innovations of all four sensors
(Levenberg-Marquardt, scipy.optimize.least_squares), started from the streaming estimates.
Standard errors come from the Gauss-Newton covariance scaled by the innovations' variance.

Measured (paper's identification input, 10 s, realistic noise; research scripts in
``benchmarks/research/bfv``): B + f_v 0.79 % mean error over seeds 0-9 (streaming 4.3 %),
0.48 % over seeds 10-39; stress noise 7.1 % (streaming 11.7 %); noise-free 0.01 %.
The valve parameters are better from the streaming identifier (its exact discrete valve
model with instrumental variables): use the refinement for the force and chamber rows.

Pure and deterministic; costs about 0.7 s of CPU for 10 s of one rig (a few dozen EKF passes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.optimize import least_squares

from hydromon.contract import PARAM_NAMES
from monitor.fourth_difference import CHI2_1_MEDIAN, D4_VARIANCE_GAIN
from monitor.ident_options import IdentOptions
from monitor.outlier_gate import gated
from plant_sim.model import derivatives
from hydromon.contract import SENSORS
from hydromon.contract import RigConfig
from plant_sim.params import (
    P_B, P_BETA, P_CDW_RHO, P_CEP, P_CIP, P_FC, P_FV, P_KSV, P_KT, P_M, P_WSV, P_ZSV, PlantParams, plant_vector,
)

__all__ = ["Refinement", "refine", "sensor_noise", "command_jumps", "REFINED"]

N_STATES = 6
#: the fitted parameters: PARAM_NAMES but the valve's static gain, which is their ratio
#: K_sv_omega_sv2 / omega_sv2 (derived after the fit, with its delta-method SE)
FIT_NAMES = PARAM_NAMES[:11]
#: nominal scales of the parameters, in FIT_NAMES order (the kernels index them so)
NOMINAL = np.array([100.0, 1e4, 10.0, 1e6, 1e-9, 1e-3, 1e-11, 1e-11, 100.0, 1e4, 1.0])
#: the ones the refinement is better at than the streaming identifier
REFINED = ("m", "B_fv", "f_c", "K_t", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")
#: process noise per sample step [m, m/s, Pa, Pa, m, m/s]: room for what the model misses
PROCESS_NOISE = np.array([0.0, 1e-5, 10.0, 10.0, 1e-9, 1e-6])
#: sensor-noise floor [m, Pa, Pa, m]: noise-free records still need a positive R
NOISE_FLOOR = np.array([1e-7, 100.0, 100.0, 1e-8])
SUBSTEPS = 6  # RK4 steps per sample in the predictor


@njit(cache=True)
def _plant(th, base):
    """The plant vector (plant_sim.params) of identified parameters th, on base (the rig's
    constants, effects off): B + f_v as B, 1/beta_e, and the valve's (2 zeta omega, omega^2,
    K_sv omega^2) as zeta, omega, K_sv. No clamping: the fit moves freely (C_ep may go < 0)."""
    p = base.copy()
    p[P_M], p[P_B], p[P_FV], p[P_FC], p[P_KT] = th[0], th[1], 0.0, th[2], th[3]
    p[P_BETA], p[P_CDW_RHO], p[P_CIP], p[P_CEP] = 1.0 / th[4], th[5], th[6], th[7]
    w = math.sqrt(th[9])
    p[P_WSV], p[P_ZSV], p[P_KSV] = w, th[8] / (2.0 * w), th[10] / th[9]
    return p


@njit(cache=True)
def _command(u, jump, k, tau):
    # Catmull-Rom cubic through samples k-1..k+2 at k + tau (tau in [0, 1]), never through a
    # step of the command: jump[j] says ug jumps between samples j and j+1, so a neighbour
    # across a step is replaced by the straight line from this side, and the interval that
    # holds the step follows each side's line up to its middle (a cubic through a step smears it
    # over three intervals: on paper-var, x5 innovations of 2400 sigma and B + f_v refined 17 %
    # off with an SE of 1-2 %)
    n = u.shape[0]
    if jump[k] and k + 1 < n:
        # each side's straight line extended to where in the interval it steps (jump[k] - 1
        # quarters of it: the samples do not say, refine() picks the one that fits best)
        if tau < 0.25 * (jump[k] - 1):
            a = u[k]
            b = u[k - 1] if k >= 1 and not jump[k - 1] else a
            return a + (a - b) * tau
        a = u[k + 1]
        b = u[min(k + 2, n - 1)] if not jump[min(k + 1, n - 1)] else a
        return a + (a - b) * (1.0 - tau)
    p1 = u[k]
    p2 = u[min(k + 1, n - 1)]
    p0 = u[k - 1] if k >= 1 and not jump[k - 1] else 2.0 * p1 - p2
    p3 = u[min(k + 2, n - 1)] if k + 1 < n and not jump[k + 1] else 2.0 * p2 - p1
    t2 = tau * tau
    return 0.5 * (2 * p1 + (p2 - p0) * tau + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2
                  + (3 * p1 - p0 - 3 * p2 + p3) * t2 * tau)


def command_jumps(ug: np.ndarray, tol: float = 0.1) -> np.ndarray:
    """uint8 (N,): 1 (nonzero) where ug jumps between samples j and j+1, i.e. the step d_j = ug[j+1] - ug[j]
    departs from its neighbours' mean by more than ``tol`` [V] and is the largest of the three.
    ``tol`` is the streaming identifier's (``IdentOptions.step_tol``), whose test (the second
    difference of ug) says that a step is near, not which interval holds it."""
    ug = np.asarray(ug, dtype=np.float64)
    out = np.zeros(ug.shape[0], dtype=np.uint8)
    if ug.shape[0] < 2:
        return out
    d = np.diff(ug)
    left = np.concatenate(([d[0]], d[:-1]))
    right = np.concatenate((d[1:], [d[-1]]))
    big = (np.abs(d - 0.5 * (left + right)) > tol) & (np.abs(d) >= np.abs(left)) & (np.abs(d) >= np.abs(right))
    out[:-1] = big
    return out


@njit(cache=True)
def _predict(x, ug, jump, k, p, h, out):
    y = x.copy()
    k1, k2, k3, k4, t = np.empty(6), np.empty(6), np.empty(6), np.empty(6), np.empty(6)
    dt = h / SUBSTEPS
    for i in range(SUBSTEPS):
        ua = _command(ug, jump, k, i / SUBSTEPS)
        um = _command(ug, jump, k, (i + 0.5) / SUBSTEPS)
        ub = _command(ug, jump, k, (i + 1.0) / SUBSTEPS)
        derivatives(y, ua, y[0], p, k1)
        for j in range(6):
            t[j] = y[j] + 0.5 * dt * k1[j]
        derivatives(t, um, t[0], p, k2)
        for j in range(6):
            t[j] = y[j] + 0.5 * dt * k2[j]
        derivatives(t, um, t[0], p, k3)
        for j in range(6):
            t[j] = y[j] + dt * k3[j]
        derivatives(t, ub, t[0], p, k4)
        for j in range(6):
            y[j] += dt / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
    out[:] = y


@njit(cache=True)
def innovations(meas, ug, th, base, h, sig, q, n0, jump):
    """Whitened one-step innovations (from sample n0 on) of the EKF over the whole model
    (``plant_sim.model.derivatives``, the simulator's own equations).

    meas (N, 4) = x1 [m], p1 [Pa], p2 [Pa], x5 [m]; ug (N,) [V]; th (11,) SI in FIT_NAMES
    order; base: the rig's plant vector (its constants; effects off); sig (4,) sensor noise
    rms; q (6,) process noise per step; jump (N,) uint8 from :func:`command_jumps`. NaN in the
    output if the filter blows up.
    """
    pv = _plant(th, base)
    n = meas.shape[0]
    r = np.diag(sig ** 2)
    qq = np.diag(q ** 2)
    x = np.array([meas[0, 0], 0.0, meas[0, 1], meas[0, 2], meas[0, 3], 0.0])
    p = np.diag(np.array([sig[0] ** 2, 1e-4, sig[1] ** 2, sig[2] ** 2, sig[3] ** 2, 1e-6]))
    out = np.zeros((n - n0) * 4)
    xn, xp = np.empty(6), np.empty(6)
    f = np.empty((6, 6))
    hm = np.zeros((4, 6))
    hm[0, 0] = hm[1, 2] = hm[2, 3] = hm[3, 4] = 1.0
    step = np.array([1e-6, 1e-4, 10.0, 10.0, 1e-8, 1e-6])  # finite-difference steps per state
    for k in range(n):
        if k > 0:
            _predict(x, ug, jump, k - 1, pv, h, xn)
            for j in range(6):
                xd = x.copy()
                xd[j] += step[j]
                _predict(xd, ug, jump, k - 1, pv, h, xp)
                for i in range(6):
                    f[i, j] = (xp[i] - xn[i]) / step[j]
            p = f @ p @ f.T + qq
            x[:] = xn
        y = meas[k] - hm @ x
        s = hm @ p @ hm.T + r
        if not np.all(np.isfinite(s)) or not np.all(np.isfinite(y)):
            out[:] = np.nan
            return out
        gain = p @ hm.T @ np.linalg.inv(s)
        if k >= n0:
            w = np.linalg.solve(np.linalg.cholesky(s), y)
            out[(k - n0) * 4:(k - n0) * 4 + 4] = w
        x[:] = x + gain @ y
        p = (np.eye(6) - gain @ hm) @ p
        p = 0.5 * (p + p.T)
    return out


def sensor_noise(samples: np.ndarray) -> np.ndarray:
    """White-noise rms of x1 [m], x3 [Pa], x4 [Pa], x5 [m] from 4th differences of a record
    (N, 5) = ug, x1, x3, x4, x5 (``monitor.fourth_difference``: the median of the squared 4th
    differences, so transients do not count), floored at NOISE_FLOOR."""
    d4 = np.diff(samples[:, 1:5], n=4, axis=0)
    est = np.sqrt(np.median(d4 ** 2, axis=0) / D4_VARIANCE_GAIN / CHI2_1_MEDIAN)
    return np.maximum(est, NOISE_FLOOR)


@dataclass
class Refinement:
    """Result of :func:`refine`: params and std_errors by name (SI); ``ok`` False when the fit
    failed (then params are the start and std_errors infinite)."""

    params: dict[str, float]
    std_errors: dict[str, float]
    ok: bool
    message: str
    evaluations: int = 0
    noise: dict[str, float] = field(default_factory=dict)


def _with_static_gain(th: np.ndarray, cov: np.ndarray | None) -> tuple[dict[str, float], float]:
    """Parameters by PARAM_NAMES from the fitted th (FIT_NAMES, SI), K_sv = K_sv omega^2 /
    omega^2 [m/V] appended, and K_sv's SE by the delta method from cov [SI] (inf without)."""
    j_w2, j_kw2 = FIT_NAMES.index("omega_sv2"), FIT_NAMES.index("K_sv_omega_sv2")
    k = float(th[j_kw2] / th[j_w2]) if th[j_w2] != 0 else math.nan
    params = dict(zip(PARAM_NAMES, (*map(float, th), k)))
    if cov is None:
        return params, math.inf
    g = np.zeros(th.size)
    g[j_kw2], g[j_w2] = 1.0 / th[j_w2], -k / th[j_w2]
    return params, float(math.sqrt(max(g @ cov @ g, 0.0)))


def refine(samples: np.ndarray, config: RigConfig, start: dict[str, float], skip: float = 0.5,
           noise: np.ndarray | None = None, max_evaluations: int = 400,
           options: IdentOptions | None = None) -> Refinement:
    """Fit all parameters to a record by prediction error.

    The record is taken as the streaming identifier's outlier gate leaves it
    (``monitor.outlier_gate.gated`` with ``options``), so the fit sees what the streaming
    estimates saw and a sensor glitch cannot pull it.

    Parameters
    ----------
    samples : array (N, 5)
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] at the config's sample rate, in order.
    config : RigConfig
        The rig constants.
    start : dict
        Starting values by name (e.g. the streaming estimates); a missing or non-finite one
        takes the nominal scale's value.
    skip : float
        Seconds at the start whose innovations are not counted (the filter settling) [s].
    noise : array (4,) or None
        Sensor noise rms of x1, x3, x4, x5 (default: :func:`sensor_noise` of the record).
    """
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != 5 or not np.all(np.isfinite(samples)):
        raise ValueError(f"need finite samples (N, 5) = ug, x1, x3, x4, x5; got shape {samples.shape}")
    samples = gated(samples, options)[0]
    h = config.h
    n0 = int(round(skip / h))
    if samples.shape[0] < n0 + 100:
        raise ValueError(f"{samples.shape[0]} samples: the refinement needs at least {n0 + 100}")
    sig = sensor_noise(samples) if noise is None else np.maximum(np.asarray(noise, dtype=np.float64), NOISE_FLOOR)
    th0 = np.array([start.get(k, math.nan) for k in FIT_NAMES], dtype=np.float64)
    th0 = np.where(np.isfinite(th0) & (th0 != 0), th0, NOMINAL)
    base = plant_vector(config, PlantParams())  # the rig's constants; the parameters come from th
    meas, ug = np.ascontiguousarray(samples[:, 1:5]), np.ascontiguousarray(samples[:, 0])
    jump = command_jumps(ug, (options or IdentOptions()).step_tol)
    if jump.any():  # where in its interval the command steps: the fraction that predicts best
        best = None
        for q in range(5):
            trial = jump * np.uint8(q + 1)
            w = innovations(meas, ug, th0, base, h, sig, PROCESS_NOISE, n0, trial)
            score = float(w @ w) if np.all(np.isfinite(w)) else math.inf
            if best is None or score < best[0]:
                best = (score, trial)
        jump = best[1]

    def cost(u):
        w = innovations(meas, ug, u * NOMINAL, base, h, sig, PROCESS_NOISE, n0, jump)
        return np.where(np.isfinite(w), w, 1e6)

    noise_d = dict(zip(SENSORS, map(float, sig)))
    fail = Refinement(_with_static_gain(th0, None)[0], dict.fromkeys(PARAM_NAMES, math.inf), False, "", 0, noise_d)
    try:
        res = least_squares(cost, th0 / NOMINAL, method="lm", x_scale="jac", max_nfev=max_evaluations)
    except (ValueError, np.linalg.LinAlgError) as exc:
        fail.message = f"fit failed: {exc}"
        return fail
    th = res.x * NOMINAL
    dof = res.fun.size - th.size
    s2 = float(res.fun @ res.fun) / dof
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac)
    except np.linalg.LinAlgError:
        fail.message = "singular information matrix"
        return fail
    cov = cov * max(s2, 1.0) * np.outer(NOMINAL, NOMINAL)
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    ok = bool(res.success and np.all(np.isfinite(th)) and s2 < 100.0)
    message = f"{res.message} (innovation variance {s2:.3f})"
    rough = _not_smooth(cost, res.x, res.jac)
    if ok and rough:
        ok = False
        message = (f"the fit ended where the prediction error is not smooth in {', '.join(rough)} (its slope "
                   "changes with the step it is measured over), so neither these values nor their standard "
                   f"errors can be trusted; {message}")
    params, k_se = _with_static_gain(th, cov)
    ses = dict(zip(PARAM_NAMES, (*map(float, se), k_se)))
    if rough:  # a slope that depends on the step gives no standard error at all
        ses = dict.fromkeys(PARAM_NAMES, math.inf)
    return Refinement(params, ses, ok, message, int(res.nfev), noise_d)


SMOOTH_STEP = 1e-3
"""Relative step [-] of the central differences that check the fit's Jacobian."""
SMOOTH_TOL = 3.0
"""Largest ratio between a Jacobian column's norm by central differences and the fit's own
(measured on good fits: 0.99-1.13; on the fit that failed: 0 and 15-96)."""
ROUGH_BY_NATURE = ("m", "B_fv", "f_c")
"""Not checked: the friction's error is only piecewise smooth (the predicted velocity's sign
flips at each reversal), so their columns differ on good fits too (m 4.1, B_fv 1.8, f_c over
10 on paper-id records)."""


def _not_smooth(cost, u: np.ndarray, jac: np.ndarray) -> list[str]:
    """Parameters whose prediction-error slope at ``u`` (scaled, FIT_NAMES order) differs between
    the fit's own Jacobian ``jac`` and central differences of relative step SMOOTH_STEP by more
    than a factor SMOOTH_TOL.

    Where the error is smooth the two agree to within 1-13 % (the friction's columns are not
    checked: ROUGH_BY_NATURE). A fit that ends on a kink or a jump of the error (one record,
    paper-var at severity 0.79, 30 s: ratios 0 to 96) has a Jacobian that depends on the step:
    unchecked, its standard errors come out up to 40,000 times too small with ``ok`` True.
    """
    out = []
    for j, name in enumerate(FIT_NAMES):
        if name in ROUGH_BY_NATURE:
            continue
        d = SMOOTH_STEP * max(abs(u[j]), 1e-3)
        up, dn = u.copy(), u.copy()
        up[j] += d
        dn[j] -= d
        a = float(np.linalg.norm((cost(up) - cost(dn)) / (2.0 * d)))
        b = float(np.linalg.norm(jac[:, j]))
        if not (a <= SMOOTH_TOL * b and b <= SMOOTH_TOL * a):
            out.append(name)
    return out
