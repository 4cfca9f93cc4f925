"""Cramer-Rao bounds of the identification problem: how well can *any* unbiased estimator do?

The rig is simulated noise-free on the paper's identification input; the sensitivity of every
measured channel (x1, x3, x4, x5) to every physical parameter is taken by central
differences of the simulator; with white Gaussian sensor noise of the given rms per channel
the Fisher information is F = sum_t J(t)' S^-1 J(t) and the bound on the standard error of
parameter i is sqrt((F^-1)_ii). This is the output-error bound: it uses everything the
model says about every channel (the chamber dynamics included), so no recipe can beat it
without information beyond the record. The expected mean absolute error of an unbiased,
normally distributed estimate is sqrt(2/pi) = 0.80 times its standard error.

Run: python benchmarks/crlb.py [--seconds 10 60] [--noise realistic]
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import math

import numpy as np

from plant_sim.noise import noise_model
from hydromon.contract import RigConfig
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate

# perturbed field of PlantParams -> the identified parameter it moves (same relative change)
FIELDS = {"m": "m", "B": "B_fv", "f_c": "f_c", "K_t": "K_t", "beta_e": "inv_beta_e", "C_d": "CdW_sqrt_rho",
          "C_ip": "C_ip", "omega_sv": "omega_sv", "zeta_sv": "zeta_sv", "K_sv": "K_sv"}
REL_STEP = 1e-4


def bounds(seconds: float, noise: str = "realistic") -> dict[str, float]:
    """Relative standard-error bound [-] of each parameter for a ``seconds`` long record."""
    cfg = RigConfig()
    sigma = noise_model(noise, cfg).rms  # x1, x3, x4, x5 [m, Pa, Pa, m]
    base = PlantParams()
    cols = []
    for field in FIELDS:
        v = getattr(base, field)
        out = []
        for sgn in (1.0, -1.0):
            p = base.model_copy(update={field: v * (1.0 + sgn * REL_STEP)})
            out.append(simulate(PaperIdentification(), seconds, params=p, config=cfg).samples[:, 1:])
        # d y / d ln(theta): a relative parameter change
        cols.append(((out[0] - out[1]) / (2.0 * REL_STEP) / sigma).ravel())
    J = np.column_stack(cols)
    cov = np.linalg.inv(J.T @ J)
    rel = np.sqrt(np.diag(cov))
    # 1/beta_e and beta_e, C_d and C_d W/sqrt(rho): equal relative errors to first order
    return dict(zip(FIELDS.values(), rel.tolist()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, nargs="+", default=[10.0, 60.0])
    ap.add_argument("--noise", default="realistic")
    args = ap.parse_args()
    res = {s: bounds(s, args.noise) for s in args.seconds}
    names = list(FIELDS.values())
    print(f"Cramer-Rao bound, {args.noise} noise, paper identification input: relative standard error "
          f"(expected mean |error| = 0.80 x)")
    print("| parameter | " + " | ".join(f"{s:g} s" for s in args.seconds) + " |")
    print("|---|" + "---|" * len(args.seconds))
    for n in names:
        print(f"| {n} | " + " | ".join(f"{100 * res[s][n]:.3f} %" for s in args.seconds) + " |")
    if not all(math.isfinite(res[s][n]) for s in args.seconds for n in names):
        raise SystemExit("a bound is not finite: the parameters are not identifiable from this record")


if __name__ == "__main__":
    main()
