"""Observer pressures -> batch force regression (recipe replica) with cross-term bias compensation
and SE variants. Usage: python batch_obs.py [seeds] [seed0]"""
import sys as _s
from variants import *
from batch import force_rows, fit

HAC = (8, 50, 100, 200)


def run_variant(runs, cps, sig, mode, lag, guard, cross, a=80.0, qmod=30.0, hp=0.0):
    est, ses = [], {k: [] for k in ["recipe"] + [f"hac{L}" for L in HAC]}
    for r, cp in zip(runs, cps):
        s = r.samples
        if mode == "meas":
            p1, p2 = s[:, 2], s[:, 3]
        else:
            p1, p2 = observe(s, cp, RC, cfg.h, sig, qmod, mode, lag)
        q = cfg.A1 * p1 - cfg.A2 * p2 - cfg.F_L
        beta = 1.0 / cp[0]
        x1bar = np.mean(s[:, 1])
        kh = beta * (cfg.A1 ** 2 / (cfg.V10 + cfg.A1 * x1bar) + cfg.A2 ** 2 / (cfg.V20 - cfg.A2 * x1bar))
        phi, y, idx, var1, m = force_rows(s[:, 1], q, cfg.h, a=a, guard=guard, hp=hp)
        th, se, e = fit(phi, y, var1, m, kh=kh if (cross and mode != "meas") else 0.0, hac_lags=HAC)
        est.append(th)
        for k in ses:
            ses[k].append(se[k])
    return np.array(est), {k: np.array(v) for k, v in ses.items()}


def line(label, est, ses):
    parts = []
    for i, nmv in enumerate(("m", "B_fv", "f_c", "K_t")):
        t = TRUE[nmv]
        rel = (est[:, i] - t) / t
        cov = "/".join(str(int(np.sum(np.abs(est[:, i] - t) <= 3 * ses[k][:, i]))) for k in ses)
        if nmv == "B_fv":
            parts.append(f"B_fv MAE {100*np.mean(np.abs(rel)):5.2f}% bias {100*np.mean(rel):+5.2f}% "
                         f"sd {100*np.std(rel, ddof=1) if len(rel) > 1 else 0:5.2f}% "
                         f"medSE(rec/hac{HAC}) " + "/".join(f"{100*np.median(ses[k][:, i])/t:.2f}" for k in ses)
                         + f" cov {cov}")
        else:
            parts.append(f"{nmv} {100*np.mean(np.abs(rel)):.2f}% cov {cov}")
    print(f"{label:36s} " + " | ".join(parts), flush=True)


if __name__ == "__main__":
    # (parsed here, not at import: joint.py and causal.py import this module with their own arguments)
    seeds = int(_s.argv[1]) if len(_s.argv) > 1 else 10
    seed0 = int(_s.argv[2]) if len(_s.argv) > 2 else 0
    for spec in ["none", "realistic", "stress"]:
        n = 1 if spec == "none" else seeds
        runs = runs_for(spec, seeds=n, seed0=seed0)
        nm = make_noise(spec); sig = np.maximum(nm.rms, [1e-7, 10.0, 10.0, 1e-9])
        base = streaming(runs)
        est_cp = [[base[k][0][i] for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")] for i in range(n)]
        for guard in (0.1, 0.0):
            line(f"{spec} meas g{guard}", *run_variant(runs, est_cp, sig, "meas", 0, guard, False))
            for cpn, cps in (("true", [CP_TRUE] * n), ("ident", est_cp)):
                for mode, lag in (("filter", 0), ("lag", 200), ("rts", 0)):
                    for cross in (True,):
                        line(f"{spec} {cpn} {mode}{lag or ''} g{guard} x{int(cross)}",
                             *run_variant(runs, cps, sig, mode, lag, guard, cross))
