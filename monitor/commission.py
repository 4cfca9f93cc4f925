"""Commissioning: a rig's own health ranges from a record of it in good condition.

1. **Baseline.** The record is identified as the live monitor would (``monitor.pipeline``): the
   rig's healthy parameters and their standard errors.
2. **Sensor noise.** Each sensor's white-noise rms from the record's 4th differences
   (``monitor.refine.sensor_noise``).
3. **What the record pins.** A graded parameter whose baseline is too uncertain to place its
   bands (its standard error more than :data:`PIN_SHARE` of the distance from the baseline to
   its first band edge) is left ungraded, with the input that would pin it.
4. **Relative bands.** The reference ranges carried over to the rig by its baseline
   (``monitor.relative``): how far the rig has degraded from itself when new.
5. **Digital twin.** The identified plant (``monitor.audit.freerun.plant_from_params``),
   driven by the record's own command at the record's noise, is degraded along the relative
   bands (``plant_sim.degradation.degrade_relative``, severities spread over [0, 1]) and each
   run identified with the same pipeline: labelled runs of *this* rig, as the method's section
   4.1 calibrates its ranges. Each band edge is then moved by the identification's median
   bias near it (identified over true value of the runs in the two bands the edge divides),
   so the ranges grade what the pipeline *reads* at this input and noise (within
   :data:`BIAS_LIMITS`; the leakages' fault thresholds stay where the baseline puts them).

:func:`commission` is pure: samples and constants in, :class:`Commissioning` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hydromon.contract import PARAM_NAMES, SENSORS, RigConfig
from plant_sim.degradation import degrade_relative
from plant_sim.noise import NoiseModel
from plant_sim.profiles import FromFile
from plant_sim.simulate import simulate_fleet

from .audit.freerun import plant_from_params
from .calibrate import identify_fleet, severities
from .ident_options import IdentOptions
from .evaluations import Assessment
from .pipeline import Pipeline
from .audit.wiring import wiring_words
from .readings import record_slip
from .ranges import Estimate, ParamRange, Ranges
from .refine import sensor_noise
from .relative import REFERENCE_HEALTHY, relative_ranges

__all__ = ["Commissioning", "TwinRuns", "commission", "PIN_SHARE", "PINNING_INPUT", "MIN_SECONDS"]

PIN_SHARE = 1.0 / 6.0
"""A baseline pins a parameter's bands when its standard error is at most this share of the
distance from the baseline to the first band edge [-]: three standard errors within half the
health band. The baseline's error moves every edge by the same factor, so a looser baseline
shifts the rig's grades by a band (measured: f_c's baseline 2.9 SE off, -52 %, graded every
record of a rig one grade worse)."""
BIAS_LIMITS = (0.8, 1.25)
"""The twin's median bias [-] an edge is moved by, at most; a larger one means the twin's runs
near that edge were not identified well enough to say (its edge stays where the baseline puts it)."""
MIN_SECONDS = 10.0
"""Shortest record commissioned [s]: the chamber and valve equations need about 3 s of samples
before they converge, and the baseline's standard errors shrink with the record's length."""
PINNING_INPUT = {
    "K_sv": "a command that moves the spool over much of its stroke (steps or a sine of a few volts)",
    "f_c": "many piston reversals at moderate speed (a slow sine or steps; --profile steps) over a longer record",
    "B_fv": "faster piston motion over a longer record (a sine of 1-3 Hz or the variable-condition input, 60 s)",
    "CdW_sqrt_rho": "larger spool openings against a pressure drop (steps of the command)",
    "C_ip": "pressure differences held between the chambers (steps of the command)",
    "C_ep": "pressure differences held between the chambers (steps of the command)",
}
"""What input would pin each graded parameter's baseline."""


@dataclass(frozen=True)
class TwinRuns:
    """The twin's labelled runs: true and identified values of the graded parameters.

    severity (n,) in [0, 1]; truth and identified: name -> (n,) [SI]; converged (n,) bool;
    bias: name -> per-edge median identified/true ratio (4,), NaN where too few runs.
    """

    severity: np.ndarray
    truth: dict
    identified: dict
    converged: np.ndarray
    bias: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Commissioning:
    """What :func:`commission` found and made.

    Attributes
    ----------
    assessment : Assessment
        The record's identification (every parameter with its standard error).
    noise : dict
        Sensor noise rms: x1 [m], x3 [Pa], x4 [Pa], x5 [m].
    relative : Ranges
        The reference ranges carried over by the baseline, before the twin.
    ranges : Ranges
        The rig's ranges: the relative ones with each edge moved by the twin's bias (the file
        ``hydromon commission`` writes, with its baseline, noise and origin).
    ungraded : dict
        Parameters left ungraded, and why (with the input that would pin them).
    twin : TwinRuns or None
        The twin's runs (None with ``runs`` = 0).
    warnings : list of str
        What a person should know about the record (each also in ``ungraded`` or the ranges).
    """

    assessment: Assessment
    noise: dict
    relative: Ranges
    ranges: Ranges
    ungraded: dict
    twin: TwinRuns | None
    warnings: list


def _pinned(name: str, value: float, se: float, relative: ParamRange, reference: ParamRange) -> str | None:
    """None when the baseline pins the bands of ``name``, else why not (in words)."""
    if not (math.isfinite(value) and math.isfinite(se)):
        return f"the record does not identify it (standard error unknown); it needs {PINNING_INPUT.get(name, 'more excitation')}"
    if relative.fault_threshold is not None:
        if value >= relative.fault_threshold:
            return (f"its healthy value {value:.3g} is already past the fault threshold {relative.fault_threshold:.3g}: "
                    "is the rig in good condition?")
        return None
    gap = abs(relative.edges[0] - value)
    if se > PIN_SHARE * gap:
        return (f"the record does not pin it: {value:.4g} +- {se:.2g} against a first band edge {gap:.3g} away; "
                f"it needs {PINNING_INPUT.get(name, 'more excitation')}")
    return None


def _twin_runs(samples: np.ndarray, config: RigConfig, params: dict, noise: dict, names, runs: int, seed: int,
               options: IdentOptions | None, progress=None) -> TwinRuns:
    """Simulate and identify ``runs`` runs of the twin, severities spread over [0, 1]."""
    healthy, _ = plant_from_params(params, REFERENCE_HEALTHY)
    n = len(samples)
    t = np.arange(n) * config.h
    command = FromFile(path="<record>", t_data=t, u_data=samples[:, 0].copy())
    model = NoiseModel(name="record", **{k: float(noise[k]) for k in SENSORS})
    sev = severities(runs)
    plants = [degrade_relative(float(s), healthy, config) for s in sev]
    truth = {k: np.array([p.identified()[k] for p in plants]) for k in names}
    ident = {k: np.empty(runs) for k in names}
    conv = np.empty(runs, dtype=bool)
    chunk = 25
    for lo in range(0, runs, chunk):
        hi = min(runs, lo + chunk)
        sim = simulate_fleet(config, plants[lo:hi], [command] * (hi - lo), n * config.h, noise=model,
                             seeds=[seed + i for i in range(lo, hi)])
        est, ok = identify_fleet(np.stack([r.samples for r in sim]), config, options)
        for k in names:
            ident[k][lo:hi] = est[:, PARAM_NAMES.index(k)]
        conv[lo:hi] = ok
        if progress is not None:
            progress(hi, runs)
    return TwinRuns(sev, truth, ident, conv)


def _edge_bias(twin: TwinRuns, name: str) -> np.ndarray:
    """Median identified/true ratio of the converged runs in the two bands each edge divides."""
    band = np.minimum((twin.severity / 0.2).astype(int), 4)
    ok = twin.converged & np.isfinite(twin.identified[name]) & (twin.truth[name] != 0)
    ratio = np.where(ok, twin.identified[name] / np.where(twin.truth[name] != 0, twin.truth[name], 1.0), np.nan)
    out = np.full(4, np.nan)
    for j in range(4):
        near = ok & ((band == j) | (band == j + 1))
        if near.sum() >= 4:
            out[j] = float(np.median(ratio[near]))
    return out


def _fitted(pr: ParamRange, bias: np.ndarray) -> ParamRange:
    """``pr`` with each edge moved by its bias, where the twin measured one within
    :data:`BIAS_LIMITS` (an edge without one keeps its place); a fault threshold keeps its place
    (healthy and fault leakages are a factor of ten apart); the relative range as it is when the
    moved edges would not be in order."""
    if pr.fault_threshold is not None:
        return pr
    ok = np.isfinite(bias) & (bias >= BIAS_LIMITS[0]) & (bias <= BIAS_LIMITS[1])
    edges = tuple(float(e * f) if k else float(e) for e, f, k in zip(pr.edges, bias, ok))
    try:
        return ParamRange(direction=pr.direction, edges=edges)
    except ValueError:
        return pr


def commission(samples: np.ndarray, config: RigConfig, *, restarts=(), options: IdentOptions | None = None,
               reference: Ranges | None = None, runs: int = 60, seed: int = 0, made_on: str = "",
               created: str = "", progress=None) -> Commissioning:
    """Commission a rig from a record of it in good condition (module docstring).

    Parameters
    ----------
    samples : (N, 5) array
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] at the rig's sample rate (the valve drive, when
        the rig publishes one, already taken in: ``monitor.drive``).
    config : RigConfig
        The rig's constants; the ranges are made for them.
    restarts : sequence of int
        Samples that follow a gap.
    reference : Ranges
        The reference ranges to carry over (default ``Ranges.default()``).
    runs : int
        Twin runs (0: no twin, the relative ranges as they are).
    seed : int
        Base seed of the twin's noise.
    made_on, created : str
        Where the record came from and when, written into the ranges.
    progress : callable or None
        ``progress(done, total)`` with the twin's runs.

    Raises ValueError (one line) for a record too short, one whose readings cannot be in the
    config's units (``monitor.readings``), one whose sensors look wired wrong
    (``monitor.audit.wiring``), one the identifier cannot converge on, one with
    physically impossible estimates, or one that pins no graded parameter.
    """
    samples = np.asarray(samples, dtype=float)
    if samples.ndim != 2 or samples.shape[1] != 5:
        raise ValueError(f"samples must be (N, 5) ug, x1, x3, x4, x5; got {samples.shape}")
    seconds = len(samples) / config.sample_rate
    if seconds < MIN_SECONDS:
        raise ValueError(f"a commissioning record of {seconds:.1f} s is too short: give at least {MIN_SECONDS:g} s "
                         "(30 s or more of the rig's usual motion pins its baseline well)")
    slip = record_slip(samples, config, options, restarts)
    if slip is not None:  # its estimates would carry the units, and its ranges be made around them
        raise ValueError(f"the record's readings cannot be in the rig config's units: {slip}")
    wiring = wiring_words(samples, config, restarts)
    if wiring is not None:  # its ranges would be made around the wrong pressures, and grade them health
        raise ValueError(f"the record's sensors look wired wrong: {wiring}")
    reference = reference or Ranges.default()
    pipe = Pipeline(config=config, options=options, ranges=None)
    _, a = pipe.run(samples, restarts)
    if a.implausible:
        raise ValueError(f"the record gives physically impossible estimates ({', '.join(a.implausible)}): "
                         "wrong units, signs or zeros of a signal, or wrong rig constants")
    if not a.converged:
        raise ValueError("the identifier did not converge on the record (too little excitation or too few "
                         "samples): give a longer record with the rig moving")
    noise = dict(zip(SENSORS, map(float, sensor_noise(samples))))
    base = {k: float(a.params[k]) for k in PARAM_NAMES}
    relative, left_out = relative_ranges(base, config, reference)
    ungraded, warnings = dict(left_out), []
    for name in list(relative.params):
        why = _pinned(name, base[name], float(a.std_errors[name]), relative.params[name], reference.params[name])
        if why is not None:
            ungraded[name] = why
    for name, why in ungraded.items():
        warnings.append(f"{name} left ungraded: {why}")
    graded = {k: v for k, v in relative.params.items() if k not in ungraded}
    if not graded:
        raise ValueError("the record pins no graded parameter: " + "; ".join(warnings))
    twin = None
    params = dict(graded)
    if runs > 0:
        twin = _twin_runs(samples, config, a.params, noise, tuple(graded), runs, seed, options, progress)
        for name in graded:
            bias = _edge_bias(twin, name)
            twin.bias[name] = bias
            params[name] = _fitted(graded[name], bias)
    estimates = {k: Estimate(value=base[k], std_error=float(a.std_errors[k]) if math.isfinite(a.std_errors[k]) else None)
                 for k in PARAM_NAMES if math.isfinite(base[k])}
    how = ("hydromon commission: the reference ranges relative to the rig's baseline"
           + (f", each edge moved by the identification's median bias in {runs} runs of its digital twin "
              f"({int(twin.converged.sum())} converged)" if twin is not None else ""))
    ranges = Ranges(params=params, source=how, rig=config, baseline=estimates, noise=noise, made_on=made_on,
                    created=created, ungraded=ungraded)
    return Commissioning(a, noise, relative, ranges, ungraded, twin, warnings)
