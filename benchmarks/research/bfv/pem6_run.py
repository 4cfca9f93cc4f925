"""PEM with valve states. Usage: python pem6_run.py noise seeds seed0 [start]"""
import sys as _s, time
from common import *
from pem6 import pem6_fit
cfg = RigConfig(); pp = PlantParams(); TRUE = pp.identified()
RC8 = [cfg.A1, cfg.A2, cfg.V10, cfg.V20, cfg.p_s, cfg.F_L, cfg.K_p, cfg.K_f]
N11 = ("m", "B_fv", "f_c", "K_t", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep", "two_zeta_omega", "omega_sv2", "K_sv_omega_sv2")
spec = _s.argv[1] if len(_s.argv) > 1 else "realistic"
seeds = int(_s.argv[2]) if len(_s.argv) > 2 else 10
seed0 = int(_s.argv[3]) if len(_s.argv) > 3 else 0
start = _s.argv[4] if len(_s.argv) > 4 else "stream"
Q = tuple(float(v) for v in _s.argv[5].split(",")) if len(_s.argv) > 5 else (0.0, 1e-5, 10.0, 10.0, 1e-9, 1e-6)
runs = runs_for(spec, seeds=seeds, seed0=seed0)
sig = make_noise(spec).rms if spec != "none" else make_noise("realistic").rms
fleet = Fleet()
for i in range(len(runs)):
    fleet.add_rig(f"s{i}")
for i, r in enumerate(runs):
    fleet.update(np.full(len(r.samples), i), r.samples)
E, S = [], []
for i, r in enumerate(runs):
    t0 = time.time()
    est = fleet.estimate(i).params
    th0 = np.array([TRUE[k] for k in N11]) if start == "true" else np.array([est[k] for k in N11])
    if not np.all(np.isfinite(th0)):
        th0 = np.array([TRUE[k] for k in N11])
    th, se, res, s2 = pem6_fit(r.samples, th0, RC8, cfg.h, sig, q=Q)
    E.append(th); S.append(se)
    rel = {k: 100 * (th[j] / TRUE[k] - 1) for j, k in enumerate(N11) if TRUE[k] != 0}
    print(f"seed {r.seed}: B {rel['B_fv']:+.3f}% (SE {100*se[1]/TRUE['B_fv']:.3f}%) m {rel['m']:+.2f}% fc {rel['f_c']:+.1f}% "
          f"1/b {rel['inv_beta_e']:+.3f}% th {rel['CdW_sqrt_rho']:+.3f}% Cip {rel['C_ip']:+.3f}% w2 {rel['omega_sv2']:+.3f}% "
          f"Kw2 {rel['K_sv_omega_sv2']:+.3f}% s2 {s2:.3f} nfev {res.nfev} {time.time()-t0:.1f}s", flush=True)
E = np.array(E); S = np.array(S)
st = {k: (np.array([fleet.estimate(i).params[k] for i in range(len(runs))]),
          np.array([fleet.estimate(i).std_errors[k] for i in range(len(runs))])) for k in N11}
for j, k in enumerate(N11):
    if TRUE[k] == 0:
        continue
    print(f"{spec} PEM6 {k:15s} {fmt(summary(E[:, j], S[:, j], TRUE[k]))}    | streaming {fmt(summary(*st[k], TRUE[k]))}")
