"""The live monitor's memory: how fast it follows a rig that degrades, and what it costs.

Each graded parameter (K_sv, f_c, B_fv, C_ip, C_ep) is stepped by one grade, at every grade
step (from the middle of one band of the default ranges to the middle of the next; the
leakages have one step, healthy to 3x their fault threshold), on a rig that has run healthy
for ``--before`` seconds (the paper's variable-condition input, realistic sensor noise, the
plant changed from one sample to the next while it runs). For each memory the table gives
how long after the step the rig is graded the new grade for good (to the end of the run),
the worst over the parameter's steps and the seeds.

Beside it, what the memory costs on rigs that do not change (``STEADY``: every parameter in
the middle of one grade's band, or just below an edge between two grades), evaluated from
``--settle`` seconds on: the share of evaluations at the true grade, how often a rig's grade
changed per hour (each change is a false alarm or its end), the share of graded parameters
that could be placed (what the confidence counts), and each parameter's rms error where it is
identifiable (a finite standard error; K_sv, f_c, B_fv in % of the truth, the leakages in % of
their fault threshold).

Run: python benchmarks/memory_tradeoff.py [--seeds 1 2 3] [--memories 60 120 300 600 none]
(about 2.5 minutes per seed on one core; docs/method.md has the table and the default it chose).
"""

from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import math
import time

import numpy as np

from monitor.grading import Ranges, grade_of_values
from monitor.ident_options import IdentOptions
from monitor.pipeline import Fleet
from plant_sim.degradation import degrade
from plant_sim.live import PlantFleet
from plant_sim.noise import noise_model
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperVariable
from hydromon.contract import GRADES, PARAM_NAMES, RigConfig

RATE = 100.0
BLOCK = 1000  # samples per rig per simulation step
GRADED = ("K_sv", "f_c", "B_fv", "C_ip", "C_ep")
HEALTHY = PlantParams()
F_V = HEALTHY.f_v
# the middle of each grade's band of the default ranges (health .. fault)
CENTRES = {
    "K_sv": (2.5e-4, 1.95e-4, 1.55e-4, 1.2e-4, 0.75e-4),  # [m/V], falling: edges 2.2, 1.7, 1.4, 1.0 e-4
    "f_c": (5.0, 15.0, 32.5, 60.0, 100.0),  # [N], rising: edges 10, 20, 45, 75
    "B_fv": (6025.0, 6112.5, 6200.0, 6325.0, 6500.0),  # [N s/m], rising: edges 6075, 6150, 6250, 6400
}
LEAKS = {"C_ip": (3e-11, 3e-10), "C_ep": (0.0, 3e-10)}  # [m^3/(s Pa)], fault threshold 1e-10
THRESHOLD = 1e-10


def _plant(name: str, value: float) -> PlantParams:
    field = {"B_fv": "B"}.get(name, name)
    if name == "B_fv":
        value -= F_V
    return HEALTHY.model_copy(update={field: value})


def scenarios() -> list[tuple[str, PlantParams, PlantParams]]:
    """(label, plant before, plant after) of every one-grade step of every graded parameter."""
    out = []
    for name, centres in CENTRES.items():
        for g in range(4):
            label = f"{name} {GRADES[g]} -> {GRADES[g + 1]}"
            out.append((label, _plant(name, centres[g]), _plant(name, centres[g + 1])))
    for name, (before, after) in LEAKS.items():
        out.append((f"{name} health -> fault", _plant(name, before), _plant(name, after)))
    return out


STEADY = (0.1, 0.3, 0.5, 0.7, 0.9, 0.18, 0.38, 0.58, 0.78)
"""Severities of the rigs that do not change: the middle of each grade's band, and 10 % of a band
below each edge between two grades (where a noisy estimate may cross the edge and back)."""


def run_seed(seed: int, memories: list[float | None], before: float, after: float, settle: float):
    """Simulate every scenario and steady rig with noise seed ``seed`` and grade them with each
    memory. Returns per memory: follow times [s] by scenario label (inf: not followed by the end),
    and the steady rigs' statistics."""
    steps = scenarios()
    plants = [b for _, b, _ in steps] + [degrade(s) for s in STEADY]
    truth_steady = [grade_of_values(p.identified()) for p in plants[len(steps):]]
    n = len(plants)
    ss = np.random.SeedSequence(seed).generate_state(n)
    plant = PlantFleet(RigConfig(), plants, [PaperVariable()] * n, noise=noise_model("realistic"),
                       seeds=[int(s) for s in ss])
    fleets = {}
    for m in memories:
        options = IdentOptions() if m is None else IdentOptions(lam=math.exp(-1.0 / (m * RATE)))
        f = Fleet(options, Ranges.default(), sample_rate=RATE, capacity=n)
        for i in range(n):
            f.add_rig(f"r{i}")
        fleets[m] = f
    total = int(round((before + after) * RATE))
    k_step = int(round(before * RATE))
    rig_of_row = np.repeat(np.arange(n), BLOCK)
    log = {m: {"rig": [], "count": [], "level": [], "params": [], "se": [], "grades": []} for m in memories}
    idx = [PARAM_NAMES.index(p) for p in GRADED]
    k = 0
    while k < total:
        if k == k_step:
            for i, (_, _, later) in enumerate(steps):
                plant.set_rig(i, params=later)
        kk = min(BLOCK, total - k, k_step - k if k < k_step else total)
        block = plant.step(kk)
        rows = rig_of_row if kk == BLOCK else np.repeat(np.arange(n), kk)
        flat = block.samples.reshape(-1, 5)
        for m, f in fleets.items():
            ev = f.update(rows, flat)
            names = f.graded(0)  # every rig has the default constants: the same graded parameters
            gi = [names.index(p) for p in GRADED]
            lg = log[m]
            lg["rig"].append(ev.rig.astype(np.int16))
            lg["count"].append(ev.counts.astype(np.int32))
            lg["level"].append(ev.level.astype(np.int8))
            lg["params"].append(ev.params[:, idx].astype(np.float64))
            lg["se"].append(ev.std_errors[:, idx].astype(np.float64))
            lg["grades"].append(ev.grades[:, gi].astype(np.int8))
        k += kk
    out = {}
    for m in memories:
        lg = {key: np.concatenate(v) for key, v in log[m].items()}
        follow = {}
        for i, (label, _, later) in enumerate(steps):
            sel = lg["rig"] == i
            t = lg["count"][sel] / RATE - before
            level = lg["level"][sel]
            new = grade_of_values(later.identified())
            wrong = t[(t > 0) & (level != new)]
            follow[label] = (0.0 if len(wrong) == 0 else float(wrong.max())) if level[-1] == new else math.inf
        right = placed = evals = changes = 0
        err = {p: [] for p in GRADED}
        for j, truth in enumerate(truth_steady):
            i = len(steps) + j
            sel = (lg["rig"] == i) & (lg["count"] / RATE >= settle)
            right += int((lg["level"][sel] == truth).sum())
            changes += int((np.diff(lg["level"][sel]) != 0).sum())
            placed += int((lg["grades"][sel] >= 0).sum())
            evals += int(sel.sum())
            true = plants[i].identified()
            for c, p in enumerate(GRADED):
                scale = THRESHOLD if p in LEAKS else true[p]
                ok = sel & np.isfinite(lg["se"][:, c])
                err[p].append((lg["params"][ok, c] - true[p]) / scale)
        rms = {p: 100.0 * float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for p, v in err.items()}
        hours = evals * f.eval_every / RATE / 3600.0
        out[m] = {"follow": follow, "right": right / evals, "placed": placed / (evals * len(GRADED)), "rms": rms,
                  "changes": changes / hours}
    return out


def _name(m) -> str:
    return "none (growing)" if m is None else f"{m:g} s"


def _secs(v: float) -> str:
    return "not followed" if math.isinf(v) else f"{v:.0f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--memories", nargs="+", default=["60", "120", "300", "600", "none"])
    ap.add_argument("--before", type=float, default=600.0, help="healthy history before the step [s] (default 600)")
    ap.add_argument("--after", type=float, default=900.0, help="run after the step [s] (default 900)")
    ap.add_argument("--settle", type=float, default=300.0,
                    help="the steady rigs' statistics are taken from this time on [s] (default 300)")
    ap.add_argument("--detail", action="store_true", help="also print each step's follow time per seed")
    args = ap.parse_args()
    memories = [None if m in ("none", "inf") else float(m) for m in args.memories]
    results = {}
    for seed in args.seeds:
        t0 = time.monotonic()
        results[seed] = run_seed(seed, memories, args.before, args.after, args.settle)
        print(f"seed {seed}: {time.monotonic() - t0:.0f} s", flush=True)
    labels = [label for label, _, _ in scenarios()]
    params = [*CENTRES, *LEAKS]
    print(f"\nfollowed for good [s after the step] (worst over the parameter's one-grade steps and seeds "
          f"{', '.join(map(str, args.seeds))}); healthy history {args.before:g} s, realistic noise:\n")
    print("| memory | " + " | ".join(params) + " | graded right | grade changes | placed | " +
          " | ".join(f"rms {p}" for p in GRADED) + " |")
    print("|" + " --- |" * (len(params) + 4 + len(GRADED)))
    for m in memories:
        worst = [max(results[s][m]["follow"][lb] for s in args.seeds for lb in labels if lb.split()[0] == p)
                 for p in params]
        right = np.mean([results[s][m]["right"] for s in args.seeds])
        placed = np.mean([results[s][m]["placed"] for s in args.seeds])
        changes = np.mean([results[s][m]["changes"] for s in args.seeds])
        rms = [np.sqrt(np.mean([results[s][m]["rms"][p] ** 2 for s in args.seeds])) for p in GRADED]
        print(f"| {_name(m)} | " + " | ".join(_secs(w) for w in worst)
              + f" | {100 * right:.1f} % | {changes:.1f}/h | {100 * placed:.0f} % | "
              + " | ".join(f"{r:.2g} %" for r in rms) + " |")
    if args.detail:
        print("\nfollow time [s] per step, seeds " + ", ".join(map(str, args.seeds)) + ":\n")
        print("| step | " + " | ".join(_name(m) for m in memories) + " |")
        print("|" + " --- |" * (len(memories) + 1))
        for lb in labels:
            print(f"| {lb} | " + " | ".join(" / ".join(_secs(results[s][m]["follow"][lb]) for s in args.seeds)
                                           for m in memories) + " |")


if __name__ == "__main__":
    main()
