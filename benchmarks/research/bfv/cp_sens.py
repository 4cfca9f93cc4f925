"""Sensitivity of the observer-based B_fv to chamber-parameter errors (noise-free data, realistic sig)."""
from batch_obs import *
runs_none = runs_for("none", seeds=1)
sig = make_noise("realistic").rms
bn = streaming(runs_none)
cp_id = [bn[k][0][0] for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")]
print("identified cp (noise-free):", cp_id, " true:", CP_TRUE)
print("rel errors:", [(a - b) / b if b else a for a, b in zip(cp_id, CP_TRUE)])
def go(label, cp):
    est, ses = run_variant(runs_none, [cp], sig, "lag", 200, 0.1, True)
    print(f"{label:28s} B {100*(est[0,1]/TRUE['B_fv']-1):+.3f}%  m {100*(est[0,0]/TRUE['m']-1):+.2f}%  fc {100*(est[0,2]/TRUE['f_c']-1):+.1f}%  Kt {100*(est[0,3]/TRUE['K_t']-1):+.4f}%")
go("true", CP_TRUE)
go("identified", cp_id)
for i, nm in enumerate(("inv_beta", "theta", "C_ip")):
    for d in (1e-3, -1e-3):
        cp = list(CP_TRUE); cp[i] *= 1 + d
        go(f"{nm} {d:+.1e}", cp)
for cep in (1e-13, 1e-12, cp_id[3]):
    cp = list(CP_TRUE); cp[3] = cep
    go(f"C_ep {cep:.1e}", cp)
