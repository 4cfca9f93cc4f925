"""CRLB of the whole model (as benchmarks/crlb.py) but discarding the first `skip` seconds of the record
(the start from rest with the ug step at t = 0), and with x5 treated as a noisy *input* variant not done.
Also the force-balance-only bound is not recomputed here."""
from common import *
from plant_sim.simulate import simulate
FIELDS = {"m": "m", "B": "B_fv", "f_c": "f_c", "K_t": "K_t", "beta_e": "inv_beta_e", "C_d": "CdW_sqrt_rho",
          "C_ip": "C_ip", "omega_sv": "omega_sv", "zeta_sv": "zeta_sv", "K_sv": "K_sv"}
cfg = RigConfig(); base = PlantParams(); sigma = noise_model("realistic", cfg).rms
outs = {}
for field in FIELDS:
    v = getattr(base, field); o = []
    for sgn in (1.0, -1.0):
        p = base.model_copy(update={field: v * (1.0 + sgn * 1e-4)})
        o.append(simulate(PaperIdentification(), 10.0, params=p, config=cfg).samples[:, 1:])
    outs[field] = (o[0] - o[1]) / 2e-4 / sigma
for skip in (0.0, 0.1, 0.5, 1.0):
    k = int(round(skip / cfg.h))
    J = np.column_stack([outs[f][k:].ravel() for f in FIELDS])
    rel = np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    print(f"skip {skip:.1f} s: " + "  ".join(f"{FIELDS[f]} {100*r:.3f}%" for f, r in zip(FIELDS, rel)))
