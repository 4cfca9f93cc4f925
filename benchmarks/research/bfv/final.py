"""All report numbers in one run (against the installed hydromon; run from this directory).

Methods (B_fv, 10 s, paper identification input):
  stream   : the streaming identifier as is (monitor.pipeline.Fleet)
  batch    : batch replica of its force regression on measured pressures (fairness check)
  obs      : pressure observer (EKF on chamber eqs, identified chamber params, fixed-lag 200) -> same regression
  joint    : obs + chamber-parameter-error regressors with the chamber identification's covariance as prior
  joint-v  : joint, observer driven by the valve-model x5 (from ug, x1) instead of measured x5
  pem4     : whole-model prediction error, EKF (x1, x2, p1, p2), measured x5 as input
  pem6     : whole-model prediction error, EKF (x1, x2, p1, p2, x5, x6), ug as input
Usage: python final.py [seed0 seeds spec ...]
"""
import sys as _s, time
from joint import *
from pem import pem_fit
from pem6 import pem6_fit

N8 = ("m", "B_fv", "f_c", "K_t", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")
N11 = N8 + ("two_zeta_omega", "omega_sv2", "K_sv_omega_sv2")
RC6 = [cfg.A1, cfg.A2, cfg.V10, cfg.V20, cfg.p_s, cfg.F_L]
RC8 = RC6 + [cfg.K_p, cfg.K_f]


def row(label, E, S):
    out = []
    for j, k in enumerate(("m", "B_fv", "f_c")):
        t = TRUE[k]; rel = (E[:, j] - t) / t
        c3 = int(np.sum(np.abs(E[:, j] - t) <= 3 * S[:, j])); c2 = int(np.sum(np.abs(E[:, j] - t) <= 2 * S[:, j]))
        if k == "B_fv":
            out.append(f"B_fv MAE {100*np.mean(np.abs(rel)):5.2f}% bias {100*np.mean(rel):+5.2f}% "
                       f"sd {100*(np.std(rel, ddof=1) if len(rel) > 1 else 0):5.2f}% medSE {100*np.median(S[:, j])/t:5.2f}% "
                       f"in3SE {c3}/{len(rel)} in2SE {c2}/{len(rel)}")
        else:
            out.append(f"{k} {100*np.mean(np.abs(rel)):6.2f}% ({c3})")
    print(f"  {label:22s} " + " | ".join(out), flush=True)


def evaluate(spec, seed0, seeds, guards=(0.1,)):
    n = 1 if spec == "none" else seeds
    runs = runs_for(spec, seeds=n, seed0=seed0)
    sig = make_noise("realistic").rms if spec == "none" else make_noise(spec).rms
    print(f"== {spec}, seeds {seed0}..{seed0+n-1}", flush=True)
    st = streaming(runs)
    row("stream", np.column_stack([st[k][0] for k in ("m", "B_fv", "f_c")]), np.column_stack([st[k][1] for k in ("m", "B_fv", "f_c")]))
    ch = chamber_estimates(runs)
    vm = valve_models(runs)
    for guard in guards:
        res = {k: ([], []) for k in ("batch", "obs", "joint", "joint-v")}
        for r, (cp0, ccov), (x5m, rel) in zip(runs, ch, vm):
            s = r.samples
            q = cfg.A1 * s[:, 2] - cfg.A2 * s[:, 3] - cfg.F_L
            phi, y, idx, var1, m = force_rows(s[:, 1], q, cfg.h, guard=guard)
            th, se, e = fit(phi, y, var1, m)
            res["batch"][0].append(th[:3]); res["batch"][1].append(se["recipe"][:3])
            jr, (th0, ses0) = joint_fit(s, list(cp0), ccov, sig, guard=guard)
            res["obs"][0].append(th0[:3]); res["obs"][1].append(ses0["recipe"][:3])
            res["joint"][0].append(jr["k8"][0][:3]); res["joint"][1].append(jr["k8"][1][:3])
            s2 = s.copy(); s2[:, 4] = x5m
            cc = ccov.copy(); cc[1, 1] += (cp0[1] * rel) ** 2
            sg = sig.copy(); sg[3] = 0.05e-6
            jv, _ = joint_fit(s2, list(cp0), cc, sg, guard=guard)
            res["joint-v"][0].append(jv["k8"][0][:3]); res["joint-v"][1].append(jv["k8"][1][:3])
        for k, (E, S) in res.items():
            row(f"{k} (guard {guard})", np.array(E), np.array(S))
    # whole-model PEM, started from the streaming estimates
    fleet = Fleet()
    for i in range(n):
        fleet.add_rig(f"s{i}")
    for i, r in enumerate(runs):
        fleet.update(np.full(len(r.samples), i), r.samples)
    P4, P6 = ([], []), ([], [])
    for i, r in enumerate(runs):
        est = fleet.estimate(i).params
        th0 = np.array([est[k] for k in N11])
        if not np.all(np.isfinite(th0)):
            th0 = np.array([TRUE[k] for k in N11])
        th, se, _, _ = pem_fit(r.samples, th0[:8], RC6, cfg.h, sig)
        P4[0].append(th[:3]); P4[1].append(se[:3])
        th, se, _, _ = pem6_fit(r.samples, th0, RC8, cfg.h, sig)
        P6[0].append(th[:3]); P6[1].append(se[:3])
    row("pem4", np.array(P4[0]), np.array(P4[1]))
    row("pem6", np.array(P6[0]), np.array(P6[1]))


if __name__ == "__main__":
    a = _s.argv[1:]
    if a:
        seed0, seeds = int(a[0]), int(a[1])
        for spec in a[2:]:
            evaluate(spec, seed0, seeds)
    else:
        evaluate("none", 0, 1)
        evaluate("realistic", 0, 10)
        evaluate("stress", 0, 10)
        evaluate("realistic", 10, 30)
