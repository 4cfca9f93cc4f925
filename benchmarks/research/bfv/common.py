"""Shared helpers: simulate runs, run the streaming identifier, summarise errors."""
import sys
import os  # noqa: F401
import numpy as np
from monitor.pipeline import Fleet
from monitor.ident_options import IdentOptions
from plant_sim.noise import noise_model, NoiseModel
from plant_sim.params import PlantParams, RigConfig
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate_fleet

NAMES = ("m", "B_fv", "f_c", "K_t", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep")


def make_noise(spec):
    if isinstance(spec, NoiseModel):
        return spec
    if spec.startswith("only:"):
        chans = spec[5:].split("+")
        base = noise_model("realistic")
        kw = {c: getattr(base, c) for c in chans}
        return NoiseModel(name=spec, **kw)
    if spec.startswith("stressonly:"):
        chans = spec[11:].split("+")
        base = noise_model("stress")
        kw = {c: getattr(base, c) for c in chans}
        return NoiseModel(name=spec, **kw)
    return noise_model(spec)


def runs_for(noise, seconds=10.0, seeds=10, seed0=0):
    return simulate_fleet(RigConfig(), [PlantParams()] * seeds, [PaperIdentification()] * seeds, seconds,
                          noise=make_noise(noise), seeds=list(range(seed0, seed0 + seeds)))


def streaming(runs, options=None):
    """Streaming identifier estimates and SEs: dict name -> (est array, se array)."""
    fleet = Fleet(options) if options is not None else Fleet()
    for i in range(len(runs)):
        fleet.add_rig(f"s{i}")
    for i, r in enumerate(runs):
        fleet.update(np.full(len(r.samples), i), r.samples)
    out = {}
    for name in NAMES:
        est = np.array([fleet.estimate(i).params[name] for i in range(len(runs))])
        se = np.array([fleet.estimate(i).std_errors[name] for i in range(len(runs))])
        out[name] = (est, se)
    return out


def summary(est, se, true):
    rel = (est - true) / true
    cov = int(np.sum(np.abs(est - true) <= 3 * se)) if se is not None else -1
    return dict(mae=np.mean(np.abs(rel)), bias=np.mean(rel), sd=np.std(rel, ddof=1) if len(rel) > 1 else 0.0,
                cov=cov, n=len(rel), medse=np.median(se / true) if se is not None else np.nan)


def fmt(s):
    return (f"MAE {100*s['mae']:6.2f} %  bias {100*s['bias']:+6.2f} %  sd {100*s['sd']:5.2f} %  "
            f"medSE {100*s['medse']:5.2f} %  cov {s['cov']}/{s['n']}")


def chamber_estimates(runs, options=None):
    """Per run: chamber parameters [1/beta, theta, C_ip, C_ep] and their full 4x4 covariance,
    exactly as monitor.estimates computes the diagonal (sigma^2 kappa P, bias-compensated)."""
    import math
    from monitor.estimates import _sigma2_kappa, _compensate
    from monitor.identify import THETA_NOM_C, Y_NOM_C
    from monitor.layout import O_TH_C, O_P_C, O_NOISE, O_BC
    fleet = Fleet(options) if options is not None else Fleet()
    for i in range(len(runs)):
        fleet.add_rig(f"s{i}")
    for i, r in enumerate(runs):
        fleet.update(np.full(len(r.samples), i), r.samples)
    g_c = fleet._k.g_c
    out = []
    for i in range(len(runs)):
        st = fleet.states[i]
        th = st[O_TH_C:O_TH_C + 4].copy()
        P = st[O_P_C:O_P_C + 16].reshape((4, 4)).copy()
        s2, kap = _sigma2_kappa(st, (1, 2), 4)
        cov = P * (s2 * kap)
        sc0 = THETA_NOM_C[0] / Y_NOM_C
        S = np.zeros((4, 4))
        S[0, 0] = (st[O_NOISE + 1] * st[O_BC + 1] + st[O_NOISE + 2] * st[O_BC + 2]) / 70.0 * g_c[1, 1] * sc0 * sc0
        th, cov = _compensate(th, cov, P, S)
        D = np.diag(THETA_NOM_C)
        out.append((th * THETA_NOM_C, D @ cov @ D))
    return out


def valve_models(runs, options=None):
    """Per run: x5 simulated by the identified valve ARX from du = K_p (ug - K_f x1) alone (the IV
    auxiliary model), and the relative SE of its DC gain (delta method on the ARX covariance)."""
    from monitor.estimates import _sigma2_kappa
    from monitor.identify import X5_NOM
    from monitor.layout import O_TH_V, O_P_V
    cfg = RigConfig()
    fleet = Fleet(options) if options is not None else Fleet()
    for i in range(len(runs)):
        fleet.add_rig(f"s{i}")
    for i, r in enumerate(runs):
        fleet.update(np.full(len(r.samples), i), r.samples)
    out = []
    for i, r in enumerate(runs):
        st = fleet.states[i]
        th = st[O_TH_V:O_TH_V + 5].copy()
        P = st[O_P_V:O_P_V + 25].reshape((5, 5))
        s2, kap = _sigma2_kappa(st, (3,), 5)
        a1, a2, b0, b1, b2 = th
        s = r.samples
        du = cfg.K_p * (s[:, 0] - cfg.K_f * s[:, 1])
        x5 = np.empty(len(du))
        x5[0] = s[0, 4]; x5[1] = s[1, 4]
        y1, y2 = x5[1] / X5_NOM, x5[0] / X5_NOM
        for k in range(2, len(du)):
            y = -a1 * y1 - a2 * y2 + b0 * du[k] + b1 * du[k - 1] + b2 * du[k - 2]
            x5[k] = y * X5_NOM
            y2, y1 = y1, y
        # DC gain g = (b0+b1+b2)/(1+a1+a2): relative SE by the delta method
        den = 1 + a1 + a2; num = b0 + b1 + b2
        J = np.array([-num / den ** 2, -num / den ** 2, 1 / den, 1 / den, 1 / den]) / (num / den)
        rel = float(np.sqrt(max(J @ (0.5 * (P + P.T)) @ J * s2 * kap, 0.0)))
        out.append((x5, rel))
    return out
