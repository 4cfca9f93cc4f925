"""Read-out of an identifier state: physical parameters and honest standard errors.

Pure kernels, run when a result is wanted (not on every sample). In PARAM_NAMES order
(hydromon.contract.names): m [kg], B_fv [N s/m], f_c [N], K_t [N/m], inv_beta_e [1/Pa],
CdW_sqrt_rho [m^2.5/kg^0.5], C_ip, C_ep [m^3/(s Pa)], two_zeta_omega [rad/s],
omega_sv2 [rad^2/s^2], K_sv_omega_sv2 [m/(V s^2)], K_sv [m/V].

The valve's static gain K_sv is read out on its own, not as K_sv omega^2 / omega^2: it needs
only the valve's low-frequency response, which any input identifies, while omega^2 needs
excitation near the valve's bandwidth. A record that starts mid-run on a smooth input has none
(omega^2 and K_sv omega^2 off by the same factor: a true 1.2 read 1.6-3.6 joining 3 s in,
README), so grading K_sv is what still sees a valve that lost gain. It comes from rows of its
own (the continuous-time valve equation under the force SVF,
``monitor.equation_rows.static_gain_rows``), not from the ARX's DC gain, which x1's noise
biases at stress noise.

Standard errors: sigma^2 kappa P, with sigma^2 the residual variance and kappa the
long-run variance factor 1 + 2 sum_j w_j rho_j of the residuals (Bartlett weights over
N_LAGS lags), because filtered residuals are correlated and the plain sigma^2 P would
overstate the information. Bias compensation (see monitor.identify) carries its
Jacobian into the covariance. Valve parameters get theirs by the delta method.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fourth_difference import D4_VARIANCE_GAIN
from .ident_model import IdentModel
from .force_observer import N_OBS_PARAMS, N_PRIOR, PSI_NOM, REPORTED, both_signs, chamber_prior, solve_with_prior
from .layout import (
    H_BC, H_H, H_OBS, N_LAGS, O_BC, O_NOISE, O_P_C, O_P_F, O_P_V, O_RES_COV, O_RES_E2, O_RES_W,
    O_OBS_KL, O_OBS_SOL, O_P_K, O_ROWS, O_ROWS_K, O_ROWS_O, O_TH_C, O_TH_K, O_TH_F, O_TH_V,
)
from .scaling import THETA_NOM_C, THETA_NOM_F, THETA_NOM_K, X5_NOM, Y_NOM_C, Y_NOM_F
from .smallmat import inv_small


@njit(cache=True, error_model="numpy")
def _sigma2_kappa(st, streams, n_par):
    e2 = 0.0
    w = 0.0
    cov = np.zeros(N_LAGS)
    for s in streams:
        e2 += st[O_RES_E2 + s]
        w += st[O_RES_W + s]
        for j in range(N_LAGS):
            cov[j] += st[O_RES_COV + s * N_LAGS + j]
    if w <= n_par + 1 or e2 <= 0.0:
        return np.inf, 1.0
    s2 = e2 / (w - n_par)
    kappa = 1.0
    for j in range(N_LAGS):
        kappa += 2.0 * (1.0 - (j + 1.0) / (N_LAGS + 1.0)) * cov[j] / e2
    kappa = min(max(kappa, 0.25), 2.0 * N_LAGS + 1.0)
    return s2, kappa


@njit(cache=True, error_model="numpy")
def _compensate(theta, cov, P, S):
    """theta_bc = (I - P S)^-1 theta and its covariance. If the correction is not small the
    estimate is left as it is and the predicted bias widens its variance instead."""
    n = theta.shape[0]
    M = np.empty((n, n))
    norm = 0.0
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += P[i, k] * S[k, j]
            norm += acc * acc
            M[i, j] = (1.0 if i == j else 0.0) - acc
    if not (math.sqrt(norm) < 0.5):
        # the regressor noise is too large for a first-order correction: keep the estimate but
        # carry the bias it predicts, (P S) theta, into the covariance so the SE stays honest
        C = cov.copy()
        for i in range(n):
            b = 0.0
            for k in range(n):
                acc = 0.0
                for j in range(n):
                    acc += P[i, j] * S[j, k]
                b += acc * theta[k]
            C[i, i] += b * b
        return theta, C
    Mi = inv_small(M)
    th = np.zeros(n)
    T = np.zeros((n, n))
    C = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            th[i] += Mi[i, k] * theta[k]
            for j in range(n):
                T[i, j] += Mi[i, k] * cov[k, j]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += T[i, k] * Mi[j, k]
            C[i, j] = acc
    return th, C


@njit(cache=True, error_model="numpy")
def valve_physical(th: np.ndarray, h: float) -> np.ndarray:
    """[2 zeta omega, omega^2, K_sv omega^2] from ARX [a1, a2, b0, b1, b2] (x5 scaled by X5_NOM)."""
    out = np.empty(3)
    _valve_physical(th, h, out)
    return out


@njit(cache=True, error_model="numpy")
def _valve_physical(th: np.ndarray, h: float, out: np.ndarray) -> np.ndarray:
    out[:] = np.nan
    a1, a2 = th[0], th[1]
    den = 1.0 + a1 + a2
    disc = a1 * a1 - 4.0 * a2
    if disc < 0.0:
        if a2 <= 0.0:
            return out
        r = math.sqrt(a2)
        c = -a1 / (2.0 * r)
        if abs(c) > 1.0:
            return out
        sr = math.log(r) / h
        wd = math.acos(c) / h
        w2 = sr * sr + wd * wd
        tzw = -2.0 * sr
    else:
        sq = math.sqrt(disc)
        za = (-a1 + sq) / 2.0
        zb = (-a1 - sq) / 2.0
        if za <= 0.0 or zb <= 0.0:
            return out
        sa = math.log(za) / h
        sb = math.log(zb) / h
        w2 = sa * sb
        tzw = -(sa + sb)
    if den == 0.0:
        return out
    k = X5_NOM * (th[2] + th[3] + th[4]) / den
    out[0] = tzw
    out[1] = w2
    out[2] = k * w2
    return out


@njit(cache=True, error_model="numpy")
def _valve_jacobian(th: np.ndarray, h: float, phys: np.ndarray, J: np.ndarray) -> None:
    """d[2 zeta omega, omega^2, K_sv omega^2] / d[a1, a2, b0, b1, b2] (3, 5) at ``th`` (phys =
    valve_physical(th, h)), analytically: 2 zeta omega = -ln(a2) / h in both pole cases; omega^2 =
    (ln^2 r + acos^2 c) / h^2 with r = sqrt(a2), c = -a1 / (2 r) for complex poles, ln z_a ln z_b / h^2
    for real ones: central differences would take ten evaluations with logs and acos, a third of
    the valve's read-out, and a test holds the two equal. NaN where the poles are repeated or on the
    unit circle's edge (c = +-1), where neither is defined."""
    J[:, :] = np.nan
    a1, a2 = th[0], th[1]
    den = 1.0 + a1 + a2
    k = X5_NOM * (th[2] + th[3] + th[4]) / den
    w2 = phys[1]
    disc = a1 * a1 - 4.0 * a2
    if disc < 0.0:
        r = math.sqrt(a2)
        c = -a1 / (2.0 * r)
        q = 1.0 - c * c
        if not q > 0.0:
            return
        sr = math.log(r) / h
        wd = math.acos(c) / h
        dwd_dc = -1.0 / (h * math.sqrt(q))
        dw2_da1 = 2.0 * wd * dwd_dc * (-1.0 / (2.0 * r))
        dw2_da2 = 2.0 * sr / (2.0 * a2 * h) + 2.0 * wd * dwd_dc * a1 / (4.0 * a2 * r)
    else:
        sq = math.sqrt(disc)
        if not sq > 0.0:
            return
        za = (-a1 + sq) / 2.0
        zb = (-a1 - sq) / 2.0
        sa = math.log(za) / h
        sb = math.log(zb) / h
        dsa_da1 = (-1.0 + a1 / sq) / 2.0 / (za * h)
        dsb_da1 = (-1.0 - a1 / sq) / 2.0 / (zb * h)
        dsa_da2 = -1.0 / sq / (za * h)
        dsb_da2 = 1.0 / sq / (zb * h)
        dw2_da1 = dsa_da1 * sb + sa * dsb_da1
        dw2_da2 = dsa_da2 * sb + sa * dsb_da2
    J[0, 0] = 0.0
    J[0, 1] = -1.0 / (a2 * h)
    J[1, 0] = dw2_da1
    J[1, 1] = dw2_da2
    J[0, 2] = J[0, 3] = J[0, 4] = 0.0
    J[1, 2] = J[1, 3] = J[1, 4] = 0.0
    dk_da = -k / den
    J[2, 0] = dk_da * w2 + k * dw2_da1
    J[2, 1] = dk_da * w2 + k * dw2_da2
    J[2, 2] = J[2, 3] = J[2, 4] = X5_NOM / den * w2


@njit(cache=True, error_model="numpy")
def _valve_se(var: float) -> float:
    """SE from a quadratic form of the valve IV's symmetrised P: the IV's P is not a covariance
    and, symmetrised, can be indefinite (records that start mid-run with steps in ug give
    eigenvalues down to -576). A form <= 0 then says nothing: unknown (inf), not 0, which would
    claim an exact estimate (omega^2 +241 % off with SE 0 on one mid-run random rig)."""
    return math.sqrt(var) if var > 0.0 else np.inf


@njit(cache=True, error_model="numpy")
def _static_gain(st: np.ndarray) -> tuple[float, float]:
    """K_sv [m/V] and its SE from the static-gain rows (monitor.equation_rows.static_gain_rows);
    NaN / inf before they have any."""
    if not st[O_ROWS_K] > 3:
        return np.nan, np.inf
    s2, kap = _sigma2_kappa(st, (5,), 3)
    k = st[O_TH_K] * THETA_NOM_K[0]
    if not math.isfinite(s2):
        return k, np.inf
    return k, _valve_se(st[O_P_K] * s2 * kap) * THETA_NOM_K[0]


@njit(cache=True, error_model="numpy")
def _force_noise(st, g_f, n):
    """(n, n) accumulated covariance of the x1 noise in the force rows' regressors (scaled units):
    white noise through the SVF reaches s^2F[x1], sF[x1] and F[x1] (m, B + f_v, K_t), not sign(x2);
    with the observer's columns (n = N_OBS_PARAMS) also sH[Lc] (psi4), Lc ~ KL x1. g_f is
    ``monitor.force_observer.force_noise_gram``: [F, sF, s^2F, sH]."""
    # each regressor's filter output in g_f: m s^2F, B sF, K F, psi4 sH (f_c's sign and the rest: none)
    S = np.zeros((n, n))
    var1 = st[O_NOISE] / D4_VARIANCE_GAIN * st[O_BC]
    cols = (0, 1, 3, 7)
    gi = (2, 1, 0, 3)
    f = np.empty(4)
    for a in range(3):
        f[a] = THETA_NOM_F[cols[a]] / Y_NOM_F
    f[3] = PSI_NOM[3] / Y_NOM_F * st[O_OBS_KL]
    m = 4 if n > 7 else 3
    for a in range(m):
        for b in range(m):
            S[cols[a], cols[b]] = var1 * f[a] * f[b] * g_f[gi[a], gi[b]]
    return S


# The observer's estimate of B + f_v and f_c replaces the plain one only where its standard error
# is clearly the smaller: both SEs are estimates (the residuals' variance and long-run factor),
# and taking the smaller of two alike picks the one that happens to be underestimated. Measured
# (streaming, paper's input, 10 s): at realistic noise the plain B + f_v SE is 1.87-3.44 times
# the observer's (40 seeds); at stress the two are alike (1.52 and 1.66 in 2 of 20 seeds, the
# rest the plain one smaller), and taking the observer's at 1.5 put one seed's B + f_v 4 SE off.
# m and K_t stay the plain force balance's: the observer's m SE is 1.5-1.8 times smaller but
# does not cover its error (truth within +-3 SE in 26 of 30 seeds), and K_t gains nothing.
OBS_MARGIN = 1.75


@njit(cache=True, error_model="numpy")
def chamber_estimate(st: np.ndarray, model: IdentModel, th: np.ndarray, cov: np.ndarray) -> bool:
    """The chamber parameters 1/beta_e [1/Pa], theta [m^2.5/kg^0.5], C_ip, C_ep [m^3/(s Pa)] into
    th (4,) and their covariance into cov (4, 4) [products of those units], bias-compensated, from
    the state row ``st`` (``monitor.layout``). False if the residual variance is not known yet
    (cov is then the unscaled P)."""
    t = st[O_TH_C:O_TH_C + 4].copy()
    P = st[O_P_C:O_P_C + 16].reshape((4, 4)).copy()
    s2, kap = _sigma2_kappa(st, (1, 2), 4)
    fin = math.isfinite(s2)
    c = P * (s2 * kap) if fin else P.copy()
    if model.hyper[H_BC] > 0.0:
        sc0 = THETA_NOM_C[0] / Y_NOM_C
        S = np.zeros((4, 4))
        S[0, 0] = (st[O_NOISE + 1] * st[O_BC + 1] + st[O_NOISE + 2] * st[O_BC + 2]) / D4_VARIANCE_GAIN \
            * model.g_c[1, 1] * sc0 * sc0
        t, c = _compensate(t, c, P, S)
    for i in range(4):
        th[i] = t[i] * THETA_NOM_C[i]
        for j in range(4):
            cov[i, j] = c[i, j] * THETA_NOM_C[i] * THETA_NOM_C[j]
    return fin


@njit(cache=True, error_model="numpy")
def plain_force(st: np.ndarray, model: IdentModel):
    """The plain force balance's (m, B + f_v, f_c, K_t, F_0) and their covariance, scaled,
    bias-compensated; fin False while the residual variance is not known (cov is then inf)."""
    th = st[O_TH_F:O_TH_F + 5].copy()
    P = st[O_P_F:O_P_F + 25].reshape((5, 5)).copy()
    s2, kap = _sigma2_kappa(st, (0,), 5)
    fin = math.isfinite(s2)
    cov = P * (s2 * kap) if fin else P * np.inf
    if model.hyper[H_BC] > 0.0:
        S = _force_noise(st, model.g_f, 5)
        if fin:
            th, cov = _compensate(th, cov, P, S)
        else:
            th, cov = _compensate(th, P, P, S)
            cov = cov * np.inf
    return th, cov, fin


@njit(cache=True, error_model="numpy")
def observer_refresh(st: np.ndarray, model: IdentModel) -> None:
    """Solve the force balance with observed pressures (monitor.force_observer) with the chamber
    estimate as the prior on psi, and keep its B + f_v and f_c and their variances in the state
    (OBS_SOL, scaled; all 0 when there is no solution: the state stays finite).

    The per-sample kernel calls it every OBS_REFRESH rows, not the read-out at every evaluation:
    the solve costs ~1.2 us, 120 ns a sample when done every 10 samples, ~30 ns every 32 rows,
    and B + f_v moves slowly.
    """
    for q in range(4):
        st[O_OBS_SOL + q] = 0.0
    if not (st[O_ROWS + 1] > 4 and st[O_ROWS_O] > N_OBS_PARAMS and both_signs(st)):
        return
    cp = np.empty(4)
    ccov = np.empty((4, 4))
    if not chamber_estimate(st, model, cp, ccov):
        return
    # the prior: psi from the chamber estimate, F_0 from the plain force balance's
    mu = np.zeros(N_PRIOR)
    c = np.zeros((N_PRIOR, N_PRIOR))
    if not chamber_prior(cp, ccov, mu[:4], c[:4, :4]):
        return
    thf, covf, fin = plain_force(st, model)
    if not (fin and covf[4, 4] > 0.0):
        return
    mu[4] = thf[4]
    c[4, 4] = covf[4, 4]
    _, kap = _sigma2_kappa(st, (4,), 4)
    S = _force_noise(st, model.g_f, N_OBS_PARAMS) if model.hyper[H_BC] > 0.0 else np.zeros((N_OBS_PARAMS, N_OBS_PARAMS))
    th = np.empty(N_OBS_PARAMS)
    var = np.empty(4)
    if not solve_with_prior(st, S, st[O_BC], kap, mu, c, th, var):
        return
    for q in range(2):
        i = REPORTED[q]
        if math.isfinite(th[i]) and var[i] > 0.0:
            st[O_OBS_SOL + q] = th[i]
            st[O_OBS_SOL + 2 + q] = var[i]


@njit(cache=True, error_model="numpy")
def _observed_force(st, params, se):
    """B + f_v and f_c from the force balance with observed pressures (its solution kept in the
    state by ``observer_refresh``), where its standard error is clearly the smaller (OBS_MARGIN)."""
    for q in range(2):
        i = REPORTED[q]
        v = st[O_OBS_SOL + 2 + q]
        if not (v > 0.0 and math.isfinite(v)):
            continue
        s_i = math.sqrt(v) * THETA_NOM_F[i]
        if s_i * OBS_MARGIN < se[i]:
            params[i] = st[O_OBS_SOL + q] * THETA_NOM_F[i]
            se[i] = s_i


@njit(cache=True, error_model="numpy")
def estimates(st: np.ndarray, model: IdentModel, params: np.ndarray, se: np.ndarray) -> None:
    """Read the state row ``st`` (``monitor.layout``) out into params (N_PARAMS,) in PARAM_NAMES
    order [SI, the units of the module docstring] and their standard errors se (N_PARAMS,) [same
    units]; NaN / inf where unknown."""
    hyper = model.hyper
    params[:] = np.nan
    se[:] = np.inf
    # force balance
    if st[O_ROWS] > 4:
        th, cov, fin = plain_force(st, model)
        for i in range(4):
            params[i] = th[i] * THETA_NOM_F[i]
            se[i] = math.sqrt(max(cov[i, i], 0.0)) * THETA_NOM_F[i] if fin else np.inf
    # chambers
    if st[O_ROWS + 1] > 4:
        th = np.empty(4)
        cov = np.empty((4, 4))
        fin = chamber_estimate(st, model, th, cov)
        for i in range(4):
            params[4 + i] = th[i]
            se[4 + i] = math.sqrt(max(cov[i, i], 0.0)) if fin else np.inf
    if hyper[H_OBS] > 0.0:
        _observed_force(st, params, se)
    # valve: its static gain from its own rows, its dynamics from the ARX with IV
    params[11], se[11] = _static_gain(st)
    if st[O_ROWS + 2] > 6:
        th = st[O_TH_V:O_TH_V + 5].copy()
        P = st[O_P_V:O_P_V + 25].reshape((5, 5))
        phys = valve_physical(th, hyper[H_H])
        s2, kap = _sigma2_kappa(st, (3,), 5)
        for i in range(3):
            params[8 + i] = phys[i]
        if math.isfinite(s2) and math.isfinite(phys[0]):
            J = np.zeros((3, 5))
            _valve_jacobian(th, hyper[H_H], phys, J)
            f = s2 * kap
            for i in range(3):
                acc = 0.0
                for a in range(5):
                    for b in range(5):
                        acc += J[i, a] * 0.5 * (P[a, b] + P[b, a]) * J[i, b]
                se[8 + i] = _valve_se(acc * f)
