"""The noise tables of docs/noise.md: paper's identification input, 10 seeds per noise model.

Mean absolute relative error of our recipe and of the paper's literal one, and how often the
truth lies inside our +-3 standard errors. Run: python benchmarks/noise_table.py [--seconds T]
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse

import numpy as np

from monitor.paper_recipe import identify_paper
from monitor.pipeline import Fleet
from plant_sim.noise import noise_model
from hydromon.contract import RigConfig
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate_fleet

SHOWN = ("B_fv", "f_c", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "K_sv_omega_sv2", "K_sv")


def table(noise: str, seconds: float, seeds: int = 10):
    runs = simulate_fleet(RigConfig(), [PlantParams()] * seeds, [PaperIdentification()] * seeds, seconds,
                          noise=noise_model(noise), seeds=list(range(seeds)))
    fleet = Fleet()
    for i in range(seeds):
        fleet.add_rig(f"s{i}")
    for i, r in enumerate(runs):
        fleet.update(np.full(len(r.samples), i), r.samples)
    true = runs[0].params.identified()
    out = {}
    for name in SHOWN:
        ours = np.array([fleet.estimate(i).params[name] for i in range(seeds)])
        se = np.array([fleet.estimate(i).std_errors[name] for i in range(seeds)])
        paper = np.array([identify_paper(r.samples)[name] for r in runs])
        t = true[name]
        out[name] = (np.mean(np.abs(ours - t)) / t, np.mean(np.abs(paper - t)) / t,
                     int(np.sum(np.abs(ours - t) <= 3 * se)))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--seeds", type=int, default=10)
    a = ap.parse_args()
    print(f"| noise | " + " | ".join(SHOWN) + " |")
    print("|---" * (len(SHOWN) + 1) + "|")
    for noise in ("none", "realistic", "stress", "pct:1"):
        t = table(noise, a.seconds, 1 if noise == "none" else a.seeds)
        cells = []
        for name in SHOWN:
            ours, paper, cov = t[name]
            n = 1 if noise == "none" else a.seeds
            mine = "no rows" if np.isnan(ours) else f"{100 * ours:.2f} %"  # no estimate at all
            cells.append(f"{mine} / {100 * paper:.1f} % ({cov}/{n})")
        print(f"| {noise} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
