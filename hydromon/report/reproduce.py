"""The paper's Tables 2, 3 and 4, ours beside the paper's (``hydromon reproduce``).

* **Table 2** (identification, section 3.3): the paper's plant (Table 1, f_v = 25) under
  its identification input 2 + sin(2 pi t) for 10 s; true value, the paper's estimate,
  ours (``monitor.pipeline``) and its relative error, and the paper's literal recipe
  (``monitor.paper_recipe``). With a noise model and ``seeds`` > 1, also the mean absolute
  relative error over the seeds for both recipes (``ours`` is seed 0). With ``refine``, also
  the whole-record prediction-error fit (``monitor.refine``, as ``evaluate --refine``) of the
  force and chamber parameters: its estimate, error, and over the seeds its mean absolute
  error and how often the truth is inside its +-3 standard errors.
* **Table 3** (health ranges): the paper's ranges beside a quick calibration
  (``monitor.calibrate``, default 40 runs under the same noise model).
* **Table 4** (variable condition, section 4.2): the five groups' plants
  (``plant_sim.degradation.table4_group``: the paper's estimates taken as the truth) under
  the variable input for 10 s; the paper's estimates and grade beside ours.

``reproduce`` computes a :class:`Reproduction`; ``to_json``, ``render`` and ``plot`` present it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hydromon.contract import PARAM_NAMES
from monitor.calibrate import calibrate, simulate_runs
from monitor.grading import Ranges
from monitor.paper_recipe import identify_paper
from monitor.pipeline import Pipeline
from monitor.refine import REFINED, refine
from plant_sim.degradation import TABLE4_PAPER_GRADES, table4_group
from plant_sim.noise import noise_model
from hydromon.contract import RigConfig
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperIdentification, PaperVariable
from plant_sim.simulate import simulate

__all__ = ["PAPER_TABLE2", "TABLE4_NAMES", "Reproduction", "reproduce", "to_json", "render", "plot"]

DURATION = 10.0  # [s], the paper's T
PAPER_TABLE2 = {
    "m": 120.04, "B_fv": 6027.50, "f_c": 4.95, "K_t": 0.99e6, "inv_beta_e": 1.42e-9,
    "CdW_sqrt_rho": 6.068e-4, "C_ip": 2.99e-11, "C_ep": 2.75e-13, "two_zeta_omega": 99.85,
    "omega_sv2": 10014.0, "K_sv_omega_sv2": 2.5012,
}
TABLE4_NAMES = ("K_sv_omega_sv2", "CdW_sqrt_rho", "f_c", "B_fv", "C_ip", "C_ep")
# the paper's figures 10-12: parameters of each equation
EQUATIONS = {
    "fig10_force": ("m", "B_fv", "f_c", "K_t"),
    "fig11_chambers": ("inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep"),
    "fig12_valve": ("two_zeta_omega", "omega_sv2", "K_sv_omega_sv2"),
}


def _rel(est: float, true: float):
    return (est - true) / true if true != 0 else None


@dataclass(frozen=True)
class History:
    """Estimates over time of the Table 2 run (seed 0), for plots like Figs 10-12.

    t_ours [s] and ours (n, 12): our pipeline's evaluations; t_paper [s] and paper (N, 12):
    the paper's recipe after each sample (NaN during its warm-up); true: the truth."""

    t_ours: np.ndarray
    ours: np.ndarray
    t_paper: np.ndarray
    paper: np.ndarray
    true: dict


@dataclass(frozen=True)
class Reproduction:
    """Computed tables (lists of plain dicts, JSON-ready) and the Table 2 estimate history."""

    table2: list
    table3: list
    table4: list
    noise: str
    seeds: int
    table3_source: str
    history: History | None = field(default=None, repr=False)
    refined: bool = False


def _table2(noise: str, seeds: int, config: RigConfig, refined: bool = False):
    true = PlantParams().identified()
    nm = noise_model(noise, config)
    ours_runs, paper_runs, refined_runs, hist = [], [], [], None
    for seed in range(seeds):
        run = simulate(PaperIdentification(), DURATION, config=config, noise=nm, seed=seed)
        events, a = Pipeline(config=config).run(run.samples)
        pr = identify_paper(run.samples, config, full=True)
        ours_runs.append(a.params)
        paper_runs.append(pr.params)
        if refined:
            refined_runs.append(refine(run.samples, config, a.params))
        if seed == 0:
            hist = History(t_ours=events.counts * config.h, ours=events.params.copy(),
                           t_paper=np.arange(1, len(run.samples) + 1) * config.h, paper=pr.history,
                           true=true)
            se = a.std_errors
    rows = []
    for k in PAPER_TABLE2:  # the paper's rows (K_sv, the static gain, is ours only)
        o, p = ours_runs[0][k], paper_runs[0][k]
        row = {"name": k, "true": true[k], "paper": PAPER_TABLE2[k], "ours": o, "rel_err": _rel(o, true[k]),
               "ours_std_error": se[k] if math.isfinite(se[k]) else None,
               "paper_rel_err": _rel(PAPER_TABLE2[k], true[k]),
               "paper_recipe": p, "paper_recipe_rel_err": _rel(p, true[k])}
        if true[k] != 0:
            row["mean_abs_rel_err"] = float(np.mean([abs(r[k] - true[k]) / true[k] for r in ours_runs]))
            row["paper_recipe_mean_abs_rel_err"] = float(np.mean([abs(r[k] - true[k]) / true[k]
                                                                  for r in paper_runs]))
        else:
            row["mean_abs_err"] = float(np.mean([abs(r[k]) for r in ours_runs]))
            row["paper_recipe_mean_abs_err"] = float(np.mean([abs(r[k]) for r in paper_runs]))
        if refined and k in REFINED:
            est = np.array([r.params[k] for r in refined_runs])
            r_se = np.array([r.std_errors[k] for r in refined_runs])
            row["refined"], row["refined_std_error"] = float(est[0]), float(r_se[0])
            row["refined_rel_err"] = _rel(est[0], true[k])
            err = np.abs(est - true[k])
            if true[k] != 0:
                row["refined_mean_abs_rel_err"] = float(np.mean(err) / true[k])
            else:
                row["refined_mean_abs_err"] = float(np.mean(err))
            ok = np.array([r.ok for r in refined_runs])
            # a failed fit has no standard error (inf): it covers nothing, it is counted apart
            row["refined_within_3se"] = int(np.sum((err <= 3 * r_se) & ok))
            row["refined_ok"] = int(ok.sum())
        rows.append(row)
    return rows, hist


def _range_dict(r) -> dict | None:
    return None if r is None else r.model_dump(exclude_none=True)


def _table3(noise: str, runs: int, config: RigConfig):
    paper = Ranges.paper()
    dropped = {}
    if runs > 0:
        cal = calibrate(simulate_runs(runs, noise=noise, config=config), strict=False, rig=config)
        ours, dropped = cal.ranges, cal.dropped
        source = f"calibration ({runs} runs, noise {noise}; monitor.calibrate)"
    else:
        ours = Ranges.default()
        source = "our default ranges (the paper's Table 3, the valve on K_sv; no calibration run)"
    names = list(paper.params) + [k for k in ours.params if k not in paper.params]
    rows = []
    for k in names:
        row = {"name": k, "paper": _range_dict(paper.params.get(k)), "ours": _range_dict(ours.params.get(k))}
        if k in dropped:
            row["note"] = dropped[k]
        rows.append(row)
    return rows, source


def _table4(noise: str, config: RigConfig):
    nm = noise_model(noise, config)
    rows = []
    for g in range(1, 6):
        plant = table4_group(g)
        run = simulate(PaperVariable(), DURATION, params=plant, config=config, noise=nm, seed=g)
        a = Pipeline(config=config).run(run.samples)[1]
        paper = plant.identified()
        rows.append({
            "group": g, "paper_grade": TABLE4_PAPER_GRADES[g], "grade": a.grade, "level": a.level,
            "confidence": a.confidence, "converged": a.converged,
            "params": {k: a.params[k] for k in PARAM_NAMES},
            "paper_params": {k: paper[k] for k in TABLE4_NAMES},
        })
    return rows


def reproduce(noise: str = "none", seeds: int = 1, calibration_runs: int = 40,
              config: RigConfig | None = None, refined: bool = False) -> Reproduction:
    """Compute Tables 2, 3, 4 (module docstring). Deterministic: seeds 0..seeds-1 for Table 2,
    seed g for Table 4 group g, seed i for calibration run i. ``calibration_runs`` = 0
    compares Table 3 with our default ranges instead of calibrating. ``refined`` adds the
    whole-record fit to Table 2 (about 1 s of CPU per seed)."""
    if seeds < 1:
        raise ValueError(f"--seeds {seeds}: need at least 1")
    if calibration_runs < 0 or 0 < calibration_runs < 10:
        raise ValueError(f"--calibration-runs {calibration_runs}: 0 (our default ranges) or at least 10 "
                         "(two runs per label)")
    config = config or RigConfig()
    noise_model(noise, config)  # validate early
    t2, hist = _table2(noise, seeds, config, refined)
    t3, source = _table3(noise, calibration_runs, config)
    t4 = _table4(noise, config)
    return Reproduction(t2, t3, t4, noise, seeds, source, hist, refined)


# ----------------------------------------------------------------------------- presentation
def _clean(x):
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def to_json(rep: Reproduction) -> dict:
    """The ``reproduce --json`` document: ``{"table2": [...], "table3": [...], "table4": [...], ...}``."""
    return _clean({"table2": rep.table2, "table3": rep.table3, "table4": rep.table4, "noise": rep.noise,
                   "seeds": rep.seeds, "table3_source": rep.table3_source})


def _pct(x):
    return "-" if x is None else f"{100 * x:+.3f} %"


def _fmt_range(r):
    if r is None:
        return "-"
    if "fault_threshold" in r:
        return f"fault past {r['fault_threshold']:.3g}"
    return "  ".join(f"{e:.4g}" for e in r["edges"])


def render(rep: Reproduction, console=None) -> None:
    """Print the three tables (rich)."""
    from rich.console import Console
    from rich.table import Table

    if console is None:
        console = Console()
        if not console.is_terminal:
            console = Console(width=150)  # a pipe or file: do not squeeze the tables to 80 columns
    multi = rep.seeds > 1
    t = Table(title=f"Table 2: identification (paper's input, {DURATION:g} s, noise {rep.noise}"
                    + (f", {rep.seeds} seeds" if multi else "") + ")", header_style="bold")
    for c in ("parameter", "true", "paper", "ours", "ours err", "paper recipe", "recipe err"):
        t.add_column(c, justify="left" if c == "parameter" else "right")
    if multi:
        t.add_column("ours mean|err|", justify="right")
        t.add_column("recipe mean|err|", justify="right")
    if rep.refined:
        t.add_column("refined err", justify="right")
        if multi:
            t.add_column("refined mean|err| (in 3 SE)", justify="right")
    for r in rep.table2:
        cells = [r["name"], f"{r['true']:.5g}", f"{r['paper']:.5g}", f"{r['ours']:.5g}", _pct(r["rel_err"]),
                 f"{r['paper_recipe']:.5g}", _pct(r["paper_recipe_rel_err"])]
        if multi:
            if "mean_abs_rel_err" in r:
                cells += [f"{100 * r['mean_abs_rel_err']:.3f} %", f"{100 * r['paper_recipe_mean_abs_rel_err']:.3f} %"]
            else:
                cells += [f"{r['mean_abs_err']:.3g}", f"{r['paper_recipe_mean_abs_err']:.3g}"]
        if rep.refined:
            if "refined" not in r:
                cells += ["", ""] if multi else [""]
            else:
                cells.append(_pct(r["refined_rel_err"]) if r["true"] else f"{r['refined']:.3g}")
                if multi:
                    m = (f"{100 * r['refined_mean_abs_rel_err']:.3f} %" if "refined_mean_abs_rel_err" in r
                         else f"{r['refined_mean_abs_err']:.3g}")
                    failed = rep.seeds - r["refined_ok"]
                    cells.append(f"{m} ({r['refined_within_3se']}/{rep.seeds}"
                                 + (f", {failed} failed)" if failed else ")"))
        t.add_row(*cells)
    console.print(t)
    console.print("errors are relative to the true value; C_ep is 0, so its error is the value itself")
    if rep.refined:
        console.print("refined: the whole-record prediction-error fit (evaluate --refine), a batch step; "
                      "the live grade is the streaming estimate's (ours)")
    t = Table(title=f"Table 3: health ranges, edges health|sub-health|average|deterioration|fault; "
                    f"ours = {rep.table3_source}", header_style="bold")
    for c in ("parameter", "direction", "paper", "ours"):
        t.add_column(c, justify="left" if c in ("parameter", "direction") else "right")
    for r in rep.table3:
        d = (r["ours"] or r["paper"])["direction"]
        ours = _fmt_range(r["ours"]) if r["ours"] else "not separable" if "note" in r else "not graded"
        t.add_row(r["name"], d, _fmt_range(r["paper"]) if r["paper"] else "-", ours)
    console.print(t)
    for r in rep.table3:
        if "note" in r:
            console.print(f"  {r['note']}")
    t = Table(title=f"Table 4: variable condition ({DURATION:g} s, noise {rep.noise}); paper / ours",
              header_style="bold")
    t.add_column("group")
    for k in TABLE4_NAMES:
        t.add_column(k, justify="right")
    t.add_column("paper grade")
    t.add_column("our grade")
    t.add_column("conf.", justify="right")
    for r in rep.table4:
        cells = [str(r["group"])]
        for k in TABLE4_NAMES:
            cells.append(f"{r['paper_params'][k]:.4g}\n{r['params'][k]:.4g}")
        mark = "" if r["grade"] == r["paper_grade"] else " (differs)"
        cells += [r["paper_grade"], r["grade"] + mark, f"{r['confidence']:.2f}"]
        t.add_row(*cells)
    console.print(t)


def plot(rep: Reproduction, directory: str | Path) -> list[Path]:
    """PNGs like the paper's Figs 10-12: each equation's parameter estimates over time (Table 2
    run, seed 0), ours and the paper's recipe, with the true value. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if rep.history is None:
        raise ValueError("this reproduction has no history to plot")
    h = rep.history
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for fname, names in EQUATIONS.items():
        fig, axes = plt.subplots(len(names), 1, figsize=(7, 2.2 * len(names)), sharex=True)
        for ax, k in zip(np.atleast_1d(axes), names):
            j = PARAM_NAMES.index(k)
            ax.plot(h.t_paper, h.paper[:, j], color="tab:orange", lw=1, label="paper recipe (T-D + RLS)")
            ax.plot(h.t_ours, h.ours[:, j], color="tab:blue", lw=1.2, label="ours")
            ax.axhline(h.true[k], color="k", ls="--", lw=0.8, label="true")
            tv = h.true[k]
            span = max(abs(tv) * 0.2, 1e-13 if k == "C_ep" else 0.0)
            ax.set_ylim(tv - span, tv + span)
            ax.set_ylabel(k)
            ax.grid(alpha=0.3)
        axes[0].legend(loc="upper right", fontsize=7)
        axes[-1].set_xlabel("t [s]")
        fig.suptitle(f"{fname.split('_', 1)[1]}: estimates vs time (noise {rep.noise})")
        fig.tight_layout()
        path = out / f"{fname}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)
    return files
