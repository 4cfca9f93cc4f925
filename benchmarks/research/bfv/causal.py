"""Session 4: the pressure observer (obs) and the joint fit with a causal filter or a short fixed lag.

Same methods as final.py (obs: observer pressures -> the batch force regression, recipe SE;
joint: + chamber-parameter sensitivities with the chamber estimate as prior, k8 SE), with the
observer's output taken from
  filter  : the EKF's filtered state (uses x1, x5 one sample ahead: the 4th-order stencil)
  strict  : the EKF with the plain trapezoid step (order4=False): samples up to k only
  lagL    : fixed-lag smoother, the state at k from samples up to k + L
The force rows already refer to the instant SG_HALF = 3 samples before the newest (the centred
velocity window), so a lag up to 3 adds no delay to the rows; lag L adds max(L - 3, 0) samples.

Usage (from this directory, PYTHONPATH=<repo>:.):
  python causal.py repro                    # final_foh.txt's realistic 0-9 obs/joint (FOH SVF, lag 200)
  python causal.py SPEC SEED0 SEEDS [CFG ...]   # CFG: filter strict lag5 lag10 ... (default: all below)
CFG may end in :earlyT (the observer at the streaming chamber estimate after the first T s, the
chamber estimate at the end as the prior's mean) or :offD (the observer at the estimate moved D %),
or : (none); a further :jr takes the joint row's residual variance from its own residuals.
Each joint CFG is followed by "minSE": per rig the stream or the joint row, whichever SE is smaller.
"""
import sys as _s
import time
from joint import *

DEFAULT = ("filter", "strict", "lag3", "lag5", "lag10", "lag20", "lag50", "lag200")


def parse(cfg):
    cfg = cfg.split(":")[0]
    if cfg == "filter":
        return "filter", 0, True
    if cfg == "strict":
        return "filter", 0, False
    if cfg.startswith("lag"):
        return "lag", int(cfg[3:]), True
    raise ValueError(cfg)


def row(label, E, S):
    """E, S: (n, 3) estimates and SEs of m, B_fv, f_c."""
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
    print(f"  {label:24s} " + " | ".join(out), flush=True)


class EarlyRun:
    def __init__(self, samples):
        self.samples = samples


def evaluate(spec, seed0, seeds, cfgs=DEFAULT, svf="cubic", stream=True):
    n = 1 if spec == "none" else seeds
    runs = runs_for(spec, seeds=n, seed0=seed0)
    sig = make_noise("realistic").rms if spec == "none" else make_noise(spec).rms
    print(f"== {spec}, seeds {seed0}..{seed0+n-1}, force SVF {svf}", flush=True)
    if stream:
        st = streaming(runs)
        row("stream", np.column_stack([st[k][0] for k in ("m", "B_fv", "f_c")]),
            np.column_stack([st[k][1] for k in ("m", "B_fv", "f_c")]))
        E, S = [], []
        for r in runs:
            s = r.samples
            q = cfg.A1 * s[:, 2] - cfg.A2 * s[:, 3] - cfg.F_L
            phi, y, idx, var1, m = force_rows(s[:, 1], q, cfg.h, guard=0.1, svf=svf)
            th, se, e = fit(phi, y, var1, m)
            E.append(th[:3]); S.append(se["recipe"][:3])
        row("batch (measured p)", np.array(E), np.array(S))
    ch = chamber_estimates(runs)
    early = {}
    for c in cfgs:
        mode, lag, o4 = parse(c)
        parts = c.split(":")
        nom = parts[1] if len(parts) > 1 else ""
        jres = "jr" in parts[2:]
        t0 = time.time()
        res = {k: ([], []) for k in ("obs", "joint")}
        for i, (r, (cp0, ccov)) in enumerate(zip(runs, ch)):
            cp_nom = None
            if nom.startswith("early"):
                # the observer frozen at the streaming chamber estimate after the first T s
                T = float(nom[5:])
                if T not in early:
                    early[T] = chamber_estimates([EarlyRun(q.samples[:int(round(T / cfg.h))]) for q in runs])
                cp_nom = list(early[T][i][0])
            elif nom.startswith("off"):
                # the observer at the estimate moved by +-d % (1/beta +, theta -, C_ip +; C_ep as is)
                d = float(nom[3:]) / 100.0
                cp_nom = [cp0[0] * (1 + d), cp0[1] * (1 - d), cp0[2] * (1 + d), cp0[3]]
            jr, (th0, ses0) = joint_fit(r.samples, list(cp0), ccov, sig, mode=mode, lag=lag, guard=0.1,
                                        svf=svf, order4=o4, cp_nom=cp_nom, joint_resid=jres)
            res["obs"][0].append(th0[:3]); res["obs"][1].append(ses0["recipe"][:3])
            res["joint"][0].append(jr["k8"][0][:3]); res["joint"][1].append(jr["k8"][1][:3])
        for k, (E, S) in res.items():
            row(f"{k} {c}", np.array(E), np.array(S))
        if stream:
            # per rig, whichever of stream and joint claims the smaller B_fv SE (the rest follow it)
            E, S = np.array(res["joint"][0]), np.array(res["joint"][1])
            Es = np.column_stack([st[k][0] for k in ("m", "B_fv", "f_c")])
            Ss = np.column_stack([st[k][1] for k in ("m", "B_fv", "f_c")])
            pick = S[:, 1] < Ss[:, 1]
            row(f"minSE {c} ({int(pick.sum())}j)", np.where(pick[:, None], E, Es), np.where(pick[:, None], S, Ss))
        print(f"    ({time.time() - t0:.1f} s)", flush=True)


if __name__ == "__main__":
    a = _s.argv[1:]
    if a and a[0] == "repro":
        evaluate("realistic", 0, 10, ("lag200",), svf="foh")
    else:
        evaluate(a[0], int(a[1]), int(a[2]), tuple(a[3:]) or DEFAULT)
