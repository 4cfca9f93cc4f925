"""Joint force regression: observer pressures + chamber-parameter-error regressors with the chamber
identification's covariance as prior (first-order whole-model estimate). Honest SE includes cp uncertainty.

Usage: python joint.py [seeds] [seed0] [noise ...]"""
import sys as _s
from batch_obs import *
from batch import force_rows, fit, noise_est, NOM
from batch import noise_gram

STEPS = np.array([1e-3, 1e-3, 1e-3])  # relative steps for 1/beta, theta, C_ip
CEP_STEP = 1e-14


def rows_for(s, cp, sig, mode, lag, guard, qmod=30.0, a=80.0, svf="cubic", order4=True):
    p1, p2 = observe(s, cp, RC, cfg.h, sig, qmod, mode, lag, order4=order4)
    q = cfg.A1 * p1 - cfg.A2 * p2 - cfg.F_L
    return force_rows(s[:, 1], q, cfg.h, a=a, guard=guard, svf=svf)


def joint_fit(s, cp0, ccov, sig, mode="lag", lag=200, guard=0.1, use_cep=True, prior_scale=1.0, a=80.0, qmod=30.0,
              svf="cubic", order4=True, cp_nom=None, joint_resid=False):
    """cp_nom: run the observer (and its sensitivities) at these chamber parameters instead of the
    estimate cp0; the prior on delta = cp_true - cp_nom is then centred at cp0 - cp_nom (a streaming
    monitor would freeze cp_nom early and read the current chamber estimate as the prior).
    joint_resid: the residual variance and kappa (k8 row only) from the joint fit's own residuals
    (one re-solve) instead of the observer-only fit's, which carry the cp_nom misfit."""
    cp0 = list(cp0)
    lin = list(cp0) if cp_nom is None else list(cp_nom)
    phi, y, idx, var1, m = rows_for(s, lin, sig, mode, lag, guard, qmod, a, svf, order4)
    cols = []
    steps = []
    for i in range(4 if use_cep else 3):
        cp = list(lin)
        d = CEP_STEP if i == 3 else STEPS[i] * lin[i]
        cp[i] = lin[i] + d
        _, yi, idx_i, _, _ = rows_for(s, cp, sig, mode, lag, guard, qmod, a, svf, order4)
        assert np.array_equal(idx_i, idx)
        cols.append((yi - y) / d)   # dy/dcp_i
        steps.append(d)
    Z = np.column_stack(cols)  # y(cp_true) ~ y(cp0) + Z delta  =>  y(cp0) = phi th - Z delta
    # plain fit first (for residual variance / kappa and the x1-noise bias compensation)
    th0, ses0, e0 = fit(phi, y, var1, m, kh=0.0, hac_lags=(100,))
    kap_e = e0
    n = len(y)
    s2 = e0 @ e0 / (n - 4)
    L = 100
    kap = 1.0
    for j in range(1, L + 1):
        kap += 2.0 * (1.0 - j / (L + 1.0)) * (e0[j:] @ e0[:-j]) / (e0 @ e0)
    kap = max(kap, 0.25)
    k8 = 1.0
    for j in range(1, 9):
        k8 += 2.0 * (1.0 - j / 9.0) * (e0[j:] @ e0[:-j]) / (e0 @ e0)
    # joint normal equations in scaled units
    sc = np.concatenate([NOM, np.array(steps) * 1e3])
    X = np.column_stack([phi, -Z]) * sc
    nd = Z.shape[1]
    Cp = ccov[:nd, :nd] * prior_scale
    Dinv = np.diag(1.0 / sc[4:])
    Pri = np.linalg.inv(Dinv @ Cp @ Dinv)  # prior precision of scaled delta
    # bias compensation of the x1 regressors (same S as the recipe)
    g = noise_gram(m)
    out = (2, 1, -1, 0)
    S = np.zeros((4 + nd, 4 + nd))
    for i in range(4):
        for j in range(4):
            if out[i] >= 0 and out[j] >= 0:
                S[i, j] = var1 * n * sc[i] * sc[j] * g[out[i], out[j]]
    res = {}
    for kname, kk in (("k8", k8), ("k100", kap)):
        w = 1.0 / (s2 * kk)
        A = X.T @ X * w
        A[4:, 4:] += Pri
        b = X.T @ y * w
        b[4:] += Pri @ ((np.asarray(cp0[:nd]) - np.asarray(lin[:nd])) / sc[4:])
        Acomp = A - S * w
        th = np.linalg.solve(Acomp, b)
        cov = np.linalg.inv(Acomp) @ A @ np.linalg.inv(Acomp)
        if joint_resid and kname == "k8":
            e = y - X @ th
            s2j = e @ e / (n - 4)
            kj = 1.0
            for j in range(1, 9):
                kj += 2.0 * (1.0 - j / 9.0) * (e[j:] @ e[:-j]) / (e @ e)
            kj = min(max(kj, 0.25), 17.0)
            w = 1.0 / (s2j * kj)
            A = X.T @ X * w
            A[4:, 4:] += Pri
            b = X.T @ y * w
            b[4:] += Pri @ ((np.asarray(cp0[:nd]) - np.asarray(lin[:nd])) / sc[4:])
            Acomp = A - S * w
            th = np.linalg.solve(Acomp, b)
            cov = np.linalg.inv(Acomp) @ A @ np.linalg.inv(Acomp)
        res[kname] = (th[:4] * NOM, np.sqrt(np.diag(cov))[:4] * NOM, th[4:] * sc[4:])
    return res, (th0, ses0)


if __name__ == "__main__":
    seeds = int(_s.argv[1]) if len(_s.argv) > 1 else 10
    seed0 = int(_s.argv[2]) if len(_s.argv) > 2 else 0
    specs = _s.argv[3:] or ["none", "realistic", "stress"]
    for spec in specs:
        nrun = 1 if spec == "none" else seeds
        runs = runs_for(spec, seeds=nrun, seed0=seed0)
        sig = make_noise("realistic").rms if spec == "none" else make_noise(spec).rms
        ch = chamber_estimates(runs)
        for guard in (0.1, 0.0):
            for use_cep in (True,):
                R = {"k8": [], "k100": []}
                plain = []
                for r, (cp0, ccov) in zip(runs, ch):
                    res, (th0, ses0) = joint_fit(r.samples, list(cp0), ccov, sig, guard=guard, use_cep=use_cep)
                    for k in R:
                        R[k].append(res[k])
                    plain.append((th0, ses0["recipe"], ses0["hac100"]))
                th0 = np.array([p[0] for p in plain])
                line(f"{spec} g{guard} observer-only", th0, {"recipe": np.array([p[1] for p in plain]), "hac100": np.array([p[2] for p in plain])})
                for k in R:
                    est = np.array([x[0] for x in R[k]]); se = np.array([x[1] for x in R[k]])
                    line(f"{spec} g{guard} joint cep{int(use_cep)} {k}", est, {k: se})
                dl = np.array([x[2] for x in R["k100"]])
                print("   delta cp estimates (rel for 1/b, th, Cip; abs C_ep) seed0..2:",
                      np.round(dl[:3, :3] / np.array([c[0][:3] for c in ch[:3]]), 5), dl[:3, 3:].ravel())
