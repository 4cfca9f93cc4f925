"""Step 2: observed pressures fed into the SAME streaming identifier (force parameters read out).

Usage: python variants.py [seeds]
"""
import sys as _s
from common import *
from observer import observe
from dataclasses import replace

cfg = RigConfig(); pp = PlantParams()
CP_TRUE = [1 / pp.beta_e, pp.CdW_sqrt_rho, pp.C_ip, pp.C_ep]
RC = [cfg.A1, cfg.A2, cfg.V10, cfg.V20, cfg.p_s]
TRUE = pp.identified()


def sg_smooth(x, half, order=2):
    """Centred Savitzky-Golay smoothing (value), edges left raw."""
    from scipy.signal import savgol_filter
    return savgol_filter(x, 2 * half + 1, order, mode="interp")


def observed_runs(runs, cp_list, sig, qmod, mode, lag=100, x1s=0):
    out = []
    for r, cp in zip(runs, cp_list):
        x1o = sg_smooth(r.samples[:, 1], x1s, 3) if x1s else None
        p1, p2 = observe(r.samples, cp, RC, cfg.h, sig, qmod, mode, lag, x1o)
        m = r.measured.copy(); m[:, 1] = p1; m[:, 2] = p2
        out.append(replace(r, measured=m))
    return out


def report(label, st):
    s = summary(*st["B_fv"], TRUE["B_fv"])
    extra = "  ".join(f"{nm} {100*summary(*st[nm], TRUE[nm])['mae']:.2f}%({summary(*st[nm], TRUE[nm])['cov']})"
                      for nm in ("m", "f_c", "K_t"))
    print(f"{label:48s} B_fv {fmt(s)} | {extra}", flush=True)


if __name__ == "__main__":
    seeds = int(_s.argv[1]) if len(_s.argv) > 1 else 10
    for spec in ["none", "realistic", "stress"]:
        n = 1 if spec == "none" else seeds
        runs = runs_for(spec, seeds=n)
        nm = make_noise(spec)
        sig = np.maximum(nm.rms, [1e-7, 10.0, 10.0, 1e-9])
        base = streaming(runs)
        report(f"{spec} measured p (baseline)", base)
        est_cp = [[base[k][0][i] for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")] for i in range(n)]
        for cpname, cps in (("true cp", [CP_TRUE] * n), ("ident cp", est_cp)):
            for mode, lag in (("filter", 0), ("lag", 50), ("lag", 200), ("rts", 0)):
                for qmod in (30.0,):
                    for x1s in (0, 10):
                        obs = observed_runs(runs, cps, sig, qmod, mode, lag, x1s)
                        report(f"{spec} {cpname} {mode}{lag if mode=='lag' else ''} q{qmod:.0f} x1s{x1s}", streaming(obs))
