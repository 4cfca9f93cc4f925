"""Health ranges from labelled runs (paper section 4.1).

The paper runs the rig many times under the identification input, labels each run by
four thresholds on the mean of x1 (the mean position falls as the health worsens: a worn
valve delivers less flow against the load and the leakages), identifies each run and reads
the parameter ranges of every label. We do the same on simulated rigs:

1. **Runs.** N rigs with severities spread evenly over [0, 1] (s_i = (i + 1/2) / N,
   ``plant_sim.degradation.degrade``), the paper's identification input 2 + sin(2 pi t)
   for 10 s, noise seeded ``seed + i``; ``simulate_runs`` (simulation + identification,
   deterministic, many rigs per compiled call).
2. **Thresholds.** The paper does not give its four x1 thresholds. We take them from the
   runs: threshold j is the mean of x1 at the severity band edge e_j = 0.2, 0.4, 0.6, 0.8,
   interpolated linearly between the runs on either side of the edge (x1's mean must fall
   strictly with severity across the edges, or ValueError). Measured noise-free (40 runs):
   37.9, 35.3, 33.0, 15.6 mm; the last is wide because the fault band's leakage stops the
   piston (x1 mean 29.5 mm at s = 0.79, 1.8 mm at s = 0.81).
3. **Labels.** label = number of thresholds the run's x1 mean is below (0 health .. 4 fault).
4. **Ranges.** For each graded parameter (those of the template ranges, default
   ``Ranges.default()``: Table 3 with the valve on K_sv) the converged runs of each label give [min, max]. The edge between
   labels j and j+1 is the midpoint of the gap between max_j and min_{j+1} (in the
   worsening direction, which is read off the data: the label-4 median against the
   label-0 median); where the two ranges overlap (noise), the midpoint of the two labels'
   medians. A two-level parameter of the template (C_ip, C_ep) gets one threshold: the
   midpoint between the largest value of labels 0-3 and the smallest of label 4. Edges
   must come out strictly monotone, else ValueError naming the parameter.

``calibrate`` (steps 2-4) is pure: runs in, :class:`Calibration` out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hydromon.contract import GRADES, PARAM_NAMES
from plant_sim.degradation import degrade
from hydromon.contract import RigConfig
from plant_sim.profiles import PaperIdentification

from .grading import ParamRange, Ranges
from .ident_options import IdentOptions

__all__ = ["BAND_EDGES", "RunResults", "Calibration", "x1_thresholds", "label_runs", "calibrate", "fit_ranges",
           "simulate_runs", "identify_fleet", "severities"]

BAND_EDGES = (0.2, 0.4, 0.6, 0.8)


@dataclass(frozen=True)
class RunResults:
    """Identified runs.

    Attributes
    ----------
    severity : (N,) float, degradation of each run's plant in [0, 1].
    x1_mean : (N,) float, mean measured piston position [m].
    params : (N, len(PARAM_NAMES)) float, identified parameters in PARAM_NAMES order [SI].
    converged : (N,) bool, the identifier converged.
    """

    severity: np.ndarray
    x1_mean: np.ndarray
    params: np.ndarray
    converged: np.ndarray

    def __post_init__(self):
        n = len(self.severity)
        if not (self.x1_mean.shape == (n,) and self.params.shape == (n, len(PARAM_NAMES))
                and self.converged.shape == (n,)):
            raise ValueError(f"RunResults: inconsistent shapes {self.severity.shape}, {self.x1_mean.shape}, "
                             f"{self.params.shape}, {self.converged.shape}")


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate`.

    Attributes
    ----------
    ranges : Ranges, the calibrated health ranges.
    thresholds : (4,) float, x1-mean thresholds between labels [m] (falling).
    labels : (N,) int, label 0..4 of every run.
    label_ranges : dict name -> (5, 2) array, [min, max] of each label's converged runs
        (NaN where a label has none) for every parameter of PARAM_NAMES.
    overlaps : dict name -> list of j where labels j and j+1 overlap (edge from medians).
    n_used : int, converged runs used.
    dropped : dict name -> reason, graded parameters left out of ``ranges`` (only with
        ``strict=False``) because their labels could not be told apart.
    """

    ranges: Ranges
    thresholds: np.ndarray
    labels: np.ndarray
    label_ranges: dict
    overlaps: dict = field(default_factory=dict)
    n_used: int = 0
    dropped: dict = field(default_factory=dict)


def severities(n: int) -> np.ndarray:
    """n severities spread evenly over [0, 1]: (i + 1/2) / n."""
    if n < 1:
        raise ValueError(f"need at least one run, got {n}")
    return (np.arange(n) + 0.5) / n


def x1_thresholds(severity: np.ndarray, x1_mean: np.ndarray, edges=BAND_EDGES) -> np.ndarray:
    """The x1-mean [m] at each severity band edge, interpolated between the runs around it."""
    severity = np.asarray(severity, dtype=float)
    x1_mean = np.asarray(x1_mean, dtype=float)
    order = np.argsort(severity)
    s, x = severity[order], x1_mean[order]
    out = []
    for e in edges:
        if not (s[0] < e < s[-1]):
            raise ValueError(f"severity edge {e} is not inside the runs' range [{s[0]}, {s[-1]}]; need more runs")
        k = int(np.searchsorted(s, e))  # s[k-1] < e <= s[k]
        w = (e - s[k - 1]) / (s[k] - s[k - 1])
        out.append((1.0 - w) * x[k - 1] + w * x[k])
    th = np.array(out)
    if not np.all(np.diff(th) < 0):
        raise ValueError(f"x1-mean thresholds {th.tolist()} [m] do not fall with severity: the runs cannot be "
                         "labelled by the mean of x1")
    return th


def label_runs(x1_mean: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """Label 0..4: the number of (falling) thresholds [m] a run's x1 mean [m] is below."""
    return (np.asarray(x1_mean, dtype=float)[:, None] < np.asarray(thresholds)[None, :]).sum(axis=1)


def _label_ranges(values: np.ndarray, labels: np.ndarray) -> np.ndarray:
    out = np.full((5, 2), np.nan)
    for j in range(5):
        v = values[labels == j]
        if v.size:
            out[j] = v.min(), v.max()
    return out


def fit_ranges(params: np.ndarray, labels: np.ndarray, template: Ranges, strict: bool = True,
               labels_present=range(5)) -> tuple[dict, dict, dict]:
    """Band edges of the template's parameters from identified values and their grade labels.

    params (N, len(PARAM_NAMES)) [SI]; labels (N,) in 0..4. Edge j (between grades j and j+1)
    is the midpoint of the gap between the two grades' values (in the worsening direction, read
    off the data: the worst present grade's median against the best's), or of their medians
    where they overlap; only edges whose two grades are in ``labels_present`` are fitted (the
    rest NaN). A two-level parameter gets one threshold between the grades below fault and fault.
    Returns ``(edges by name: (direction, 4 edges or threshold), overlaps, dropped)``; a
    parameter whose fitted edges are not monotone raises ValueError, or with ``strict`` False
    goes into ``dropped`` with the reason.
    """
    present = sorted(set(int(j) for j in labels_present))
    out, overlaps, dropped = {}, {}, {}
    for name, tpl in template.params.items():
        v = params[:, PARAM_NAMES.index(name)]
        med = {j: np.median(v[labels == j]) for j in present}
        s = 1.0 if med[present[-1]] > med[present[0]] else -1.0
        direction = "rising" if s > 0 else "falling"
        if tpl.fault_threshold is not None:
            if 4 not in present or not any(j < 4 for j in present):
                out[name] = (direction, None)
                continue
            healthy, fault = s * v[labels < 4], s * v[labels == 4]
            lo, hi = healthy.max(), fault.min()
            if hi < lo:
                overlaps[name] = [3]
                thr = 0.5 * (np.median(healthy) + np.median(fault))
            else:
                thr = 0.5 * (lo + hi)
            out[name] = (direction, float(s * thr))
            continue
        e = []
        for j in range(4):
            if j not in present or j + 1 not in present:
                e.append(np.nan)
                continue
            a, b = s * v[labels == j], s * v[labels == j + 1]
            if a.max() <= b.min():
                e.append(0.5 * (a.max() + b.min()))
            else:
                overlaps.setdefault(name, []).append(j)
                e.append(0.5 * (np.median(a) + np.median(b)))
        fitted = np.array(e)
        known = fitted[np.isfinite(fitted)]
        if not np.all(np.diff(known) > 0):
            msg = (f"{name}: calibrated edges {[round(float(s * x), 6) for x in fitted]} are not monotone "
                   "(the labels' values overlap too much); use more runs or less noise")
            if strict:
                raise ValueError(msg)
            dropped[name] = msg
            continue
        out[name] = (direction, tuple(float(s * x) for x in fitted))
    return out, overlaps, dropped


def calibrate(results: RunResults, template: Ranges | None = None, edges=BAND_EDGES,
              strict: bool = True, rig: RigConfig | None = None) -> Calibration:
    """Health ranges from identified runs (module docstring, steps 2-4). Pure.

    Parameters
    ----------
    results : RunResults
    template : Ranges
        Which parameters are graded and which are two-level (default: ``Ranges.default()``).
    edges : the four severity band edges that place the x1 thresholds.
    strict : bool
        True: a parameter whose edges come out non-monotone is a ValueError. False: it is
        left out of the ranges and listed in ``Calibration.dropped`` (e.g. B + f_v under
        realistic noise, whose bands are ~1 % wide, below a 10 s run's precision).
    rig : RigConfig
        The rig constants the runs were simulated with: the ranges are made for them (default
        the reference rig's).
    """
    template = template or Ranges.default()
    th = x1_thresholds(results.severity, results.x1_mean, edges)
    labels = label_runs(results.x1_mean, th)
    use = np.asarray(results.converged, dtype=bool) & np.all(np.isfinite(results.params), axis=1)
    if not use.any():
        raise ValueError("no run converged; nothing to calibrate from")
    lab = labels[use]
    missing = [j for j in range(5) if not np.any(lab == j)]
    if missing:
        raise ValueError(f"label(s) {missing} have no converged run; use more runs")
    pars = results.params[use]
    label_ranges = {k: _label_ranges(pars[:, i], lab) for i, k in enumerate(PARAM_NAMES)}
    fitted, overlaps, dropped = fit_ranges(pars, lab, template, strict)
    out = {name: ParamRange(direction=d, **({"fault_threshold": x} if isinstance(x, float) else {"edges": x}))
           for name, (d, x) in fitted.items()}
    src = (f"hydromon calibrate: {int(use.sum())} converged runs of {len(labels)}, severities evenly over [0, 1], "
           f"labelled by x1-mean thresholds {[round(float(x), 6) for x in th]} m (the x1 mean at severity "
           f"{list(edges)}); edges are midpoints between adjacent labels' [min, max] (medians where they overlap)")
    if dropped:
        src += f"; left out (labels not separable): {', '.join(dropped)}"
    if not out:
        raise ValueError("no graded parameter could be calibrated: " + "; ".join(dropped.values()))
    return Calibration(Ranges(params=out, source=src, rig=rig or RigConfig()), th, labels, label_ranges, overlaps,
                       int(use.sum()), dropped)


def identify_fleet(samples: np.ndarray, config: RigConfig | None = None,
                   options: IdentOptions | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Identify many runs together (one ``monitor.pipeline.Fleet``, samples interleaved in time).

    samples : (n_runs, N, 5) ug, x1, x3, x4, x5 [SI]. Returns params (n_runs, len(PARAM_NAMES)) [SI] and
    converged (n_runs,) after the last sample (the same numbers as ``Pipeline.run`` per run).
    """
    from .pipeline import Fleet

    config = config or RigConfig()
    samples = np.asarray(samples, dtype=float)
    n, t, _ = samples.shape
    fleet = Fleet(options, sample_rate=config.sample_rate, eval_every=max(t, 1) + 1, capacity=n)
    for i in range(n):
        fleet.add_rig(f"run-{i}", config)
    rig = np.tile(np.arange(n, dtype=np.int64), t)
    fleet.update(rig, samples.transpose(1, 0, 2).reshape(-1, 5))
    params = np.empty((n, len(PARAM_NAMES)))
    conv = np.empty(n, dtype=bool)
    for i in range(n):
        a = fleet.estimate(i)
        params[i] = [a.params[k] for k in PARAM_NAMES]
        conv[i] = a.converged
    return params, conv


def simulate_runs(n: int, noise: str = "none", seed: int = 0, config: RigConfig | None = None,
                  duration: float = 10.0, chunk: int = 25, options: IdentOptions | None = None,
                  progress=None) -> RunResults:
    """Simulate and identify n runs (step 1 of the module docstring), ``chunk`` rigs at a time.

    ``progress(k)`` (optional) is called with the number of runs just finished.
    """
    from plant_sim.noise import noise_model
    from plant_sim.simulate import simulate_fleet

    config = config or RigConfig()
    sev = severities(n)
    nm = noise_model(noise, config)
    x1m, params, conv = np.empty(n), np.empty((n, len(PARAM_NAMES))), np.empty(n, dtype=bool)
    for lo in range(0, n, chunk):
        hi = min(n, lo + chunk)
        runs = simulate_fleet(config, [degrade(float(s)) for s in sev[lo:hi]], [PaperIdentification()] * (hi - lo),
                              duration, noise=nm, seeds=[seed + i for i in range(lo, hi)])
        s = np.stack([r.samples for r in runs])
        x1m[lo:hi] = s[:, :, 1].mean(axis=1)
        params[lo:hi], conv[lo:hi] = identify_fleet(s, config, options)
        if progress is not None:
            progress(hi - lo)
    return RunResults(sev, x1m, params, conv)


def calibrate_labelled(params: np.ndarray, labels: np.ndarray, rig: RigConfig, template: Ranges | None = None,
                       commissioned: Ranges | None = None, what: str = "") -> Ranges:
    """Health ranges of one rig from its own labelled records (the method's section 4.1 on
    measured data): ``params`` (N, len(PARAM_NAMES)) identified [SI], ``labels`` (N,) their
    grades 0..4 (e.g. from maintenance records).

    Edges between two grades that both have records come from the records (:func:`fit_ranges`);
    a parameter that moves the other way than ``template`` says wear moves it (labels in reverse
    order, or records that do not differ in it) is left out, with why, in ``ungraded``;
    the others from ``commissioned`` (the rig's commissioned ranges: its baseline's relative
    bands), so a plant with records of some grades only still gets every edge. Without it, a
    grade with no record is a ValueError naming it. ``template`` (default ``Ranges.default()``)
    says which parameters are graded. ``what`` describes the records (for the file's source).
    """
    template = template or Ranges.default()
    labels = np.asarray(labels, dtype=np.int64)
    ok = np.all(np.isfinite(params), axis=1)
    params, labels = params[ok], labels[ok]
    present = sorted(set(labels.tolist()))
    if len(present) < 2 and commissioned is None:
        raise ValueError(f"records of {len(present)} grade(s) only: labelled calibration needs two grades or more, "
                         "or a commissioned ranges file (--baseline) for the rest")
    if commissioned is not None and commissioned.made_for(rig) is not None:
        raise ValueError(f"--baseline ranges: {commissioned.made_for(rig)}")
    graded = Ranges(params={k: v for k, v in template.params.items()
                            if commissioned is None or k in commissioned.params}, rig=rig)
    fitted, _, dropped = fit_ranges(params, labels, graded, strict=False, labels_present=present)
    out, missing = {}, set()
    for name, (direction, x) in fitted.items():
        wear = graded.params[name].direction
        placed = x is not None and (isinstance(x, float) or bool(np.isfinite(x).any()))
        if placed:  # the records place an edge: they must move the way wear moves the parameter
            v = params[:, PARAM_NAMES.index(name)]
            best, worst = np.median(v[labels == present[0]]), np.median(v[labels == present[-1]])
            if best == worst or direction != wear:
                moved = "does not change" if best == worst else "rises" if direction == "rising" else "falls"
                dropped[name] = (f"{name}: {moved} as the labels worsen, where wear makes it "
                                 f"{'rise' if wear == 'rising' else 'fall'}: are the labels in reverse order (0 health "
                                 ".. 4 fault), or do the records not differ in it?")
                continue
        direction = wear  # the commissioned edges alone: the direction they were made with
        base = None if commissioned is None else commissioned.params.get(name)
        if x is None or isinstance(x, tuple) and not all(np.isfinite(x)):
            if base is None:
                missing |= {j for j in range(5) if j not in present}
                continue
            if x is None:
                x = base.fault_threshold
            else:
                x = tuple(e if np.isfinite(e) else b for e, b in zip(x, base.edges))
        kind = {"fault_threshold": x} if isinstance(x, float) else {"edges": x}
        try:
            out[name] = ParamRange(direction=direction, **kind)
        except ValueError as exc:
            dropped[name] = f"{name}: the records' edges and the commissioned ones are not in order ({exc})"
    if missing:
        names = ", ".join(GRADES[j] for j in sorted(missing))
        raise ValueError(f"no record graded {names}: give records of every grade, or the rig's commissioned "
                         "ranges (--baseline) for the edges they cannot place")
    if not out:
        raise ValueError("no graded parameter could be calibrated: " + "; ".join(dropped.values()))
    src = (f"hydromon calibrate --labelled: {len(labels)} records ({what}) of grades "
           f"{', '.join(GRADES[j] for j in present)}; edges between two recorded grades are midpoints between their "
           "values (medians where they overlap)" + ("; the others from the commissioned ranges" if commissioned else ""))
    if dropped:
        src += f"; left out: {'; '.join(dropped.values())}"
    return Ranges(params=out, source=src, rig=rig,
                  baseline=commissioned.baseline if commissioned is not None else {},
                  ungraded={k: v for k, v in dropped.items()})
