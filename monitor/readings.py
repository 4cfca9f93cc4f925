"""Whether a record's readings can be in the units its rig's config gives (SI: m, Pa).

A channel logged in other units can still fit the model's equations, with the units in its
parameters: on a healthy rig's 20 s record (``hydromon sim --severity 0.05 --profile paper-var
--noise realistic --seed 1 --duration 20 --to-csv h.csv``) the estimates from the spool times
100, and from both pressures with their sign turned, grade ``health`` with plausible values, as
the record's own do. Wrong units are rarely a factor near 1 (bar, MPa, kPa, psi, mm, cm), so a reading far
outside what the config's constants allow tells them:

- x1 or x5 peaking above ``RANGE`` times its sensor's span (``x1_span``, ``x5_span``), or a
  pressure above ``RANGE`` times ``p_span``;
- a pressure that never reaches ``PRESSURE_LOW`` of the supply pressure ``p_s``;
- a pressure below ``-PRESSURE_NEGATIVE`` of ``p_s``: far below vacuum (-0.1 MPa gauge).

Over the 2052 records of the audit's tuning sweeps (``python -m hydromon.tools.audit_sweep
--screen --seed-base 11700000`` with each of its record sets: every profile, health band, noise
level, effect and rig size) x1 peaked at 0.74 of its span, x5 at 3.1 of its (a rig whose spool
travels 3 mm against the default 1 mm span), the pressures at 0.96 of theirs, each pressure at
0.31 of p_s at least, and no pressure fell below 0. A slip by 10 in x1 or x5 (a reading in 0.1 mm)
stays within these bounds and is not told. Pure functions, SI units.
"""

from __future__ import annotations

import numpy as np

from hydromon.contract import CHANNELS

__all__ = ["RANGE", "PRESSURE_LOW", "PRESSURE_NEGATIVE", "GLITCH_SAMPLES", "range_ratios", "unit_slip", "record_slip",
           "sample_limits", "beyond", "longest_stretch"]

RANGE = 10.0
PRESSURE_LOW = 0.05
PRESSURE_NEGATIVE = 0.1
GLITCH_SAMPLES = 2
"""Samples beyond the single-sample bounds that the live monitor takes for a glitch in one
evaluation's window (``hydromon.engine.units_watch``; the outlier gate mends one sample, or two
in a row on x1, x3 and x4), and ``evaluate`` in a record after the gate."""


def range_ratios(samples: np.ndarray, cfg) -> dict[str, float]:
    """How the readings of samples ``ug, x1, x3, x4, x5`` [V, m, Pa, Pa, m] stand to the rig's
    config ``cfg`` (``hydromon.contract.RigConfig``) [-]: x1's and x5's largest magnitude over
    x1_span and x5_span, the pressures' largest over p_span (``p``), the lower of the two
    pressures' largest magnitudes over p_s (``p_peak``), and their smallest reading over p_s
    (``p_low``)."""
    s = np.asarray(samples, dtype=float)
    p = s[:, 2:4]
    return {"x1": float(np.max(np.abs(s[:, 1]))) / cfg.x1_span, "x5": float(np.max(np.abs(s[:, 4]))) / cfg.x5_span,
            "p": float(np.max(p)) / cfg.p_span, "p_peak": float(np.min(np.max(np.abs(p), axis=0))) / cfg.p_s,
            "p_low": float(np.min(p)) / cfg.p_s}


def _pressure(p: float) -> str:
    """A pressure [Pa] in MPa from 0.1 MPa, in kPa from 1 kPa, else in Pa."""
    return f"{p / 1e6:.3g} MPa" if abs(p) >= 1e5 else f"{p / 1e3:.3g} kPa" if abs(p) >= 1e3 else f"{p:.3g} Pa"


def _config_tail(key: str, value: str) -> str:
    return (f" hydromon reads SI units (m, Pa); if the rig's {key} is not {value}, its config must say so "
            f"(--config FILE for a CSV)")


def sample_limits(cfg) -> np.ndarray:
    """The bounds one sample is held against under the rig's config ``cfg`` (module docstring),
    (4,): the largest |x1| [m], |x5| [m] and pressure [Pa], and the smallest pressure [Pa]."""
    return np.array([RANGE * cfg.x1_span, RANGE * cfg.x5_span, RANGE * cfg.p_span, -PRESSURE_NEGATIVE * cfg.p_s])


def beyond(samples: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Which samples ``ug, x1, x3, x4, x5`` (N, 5) lie beyond their ``limits`` (N, 4) or (4,) of
    ``sample_limits``, (N,) bool: the rules a single sample can break (a pressure that never
    reaches PRESSURE_LOW of p_s takes a record to tell)."""
    s = np.asarray(samples, dtype=float)
    lim = np.broadcast_to(np.asarray(limits, dtype=float), (len(s), 4))
    p = s[:, 2:4]
    return ((np.abs(s[:, 1]) > lim[:, 0]) | (np.abs(s[:, 4]) > lim[:, 1]) | (p.max(axis=1) > lim[:, 2])
            | (p.min(axis=1) < lim[:, 3]))


def unit_slip(samples: np.ndarray, cfg, record: bool = True, allow: int = 0) -> str | None:
    """Why the readings of samples ``ug, x1, x3, x4, x5`` cannot be in the units of the rig's
    config ``cfg`` (module docstring), naming the channel, its reading and the constant it was
    held against; None when they can. Samples that are not (N, 5) finite numbers give None
    (their reader says what is wrong with them). ``record`` False: only the rules a single
    sample can break (``beyond``), for samples that are not a whole record; ``allow``: samples
    beyond those rules that are still a glitch (``GLITCH_SAMPLES`` where the live monitor's
    judgement is wanted)."""
    s = np.asarray(samples, dtype=float)
    if s.ndim != 2 or s.shape[1] != 5 or not len(s) or not np.all(np.isfinite(s)):
        return None
    r = range_ratios(s, cfg)
    p = s[:, 2:4]
    if int(np.count_nonzero(beyond(s, sample_limits(cfg)))) > allow:
        for name, span, key in (("x1", cfg.x1_span, "x1_span"), ("x5", cfg.x5_span, "x5_span")):
            if r[name] > RANGE:
                peak = float(np.max(np.abs(s[:, CHANNELS.index(name)])))
                return (f"{name} reaches {peak:.3g} m, {r[name]:.0f} times its sensor's span {key} = {span:.3g} m: "
                        f"is {name} in mm or another unit than m?" + _config_tail(key, f"{span:.3g} m"))
        if r["p"] > RANGE:
            return (f"the pressures reach {_pressure(float(np.max(p)))}, {r['p']:.0f} times the pressure sensors' "
                    f"span p_span = {_pressure(cfg.p_span)}: are they in another unit than Pa?"
                    + _config_tail("p_span", _pressure(cfg.p_span)))
        k = 2 + int(np.argmin(np.min(p, axis=0)))
        return (f"{CHANNELS[k]} falls to {_pressure(float(np.min(s[:, k])))}, far below vacuum (-0.1 MPa gauge): a "
                f"pressure logged with its sign turned, or with a zero offset; hydromon reads absolute (or gauge) "
                f"pressures in Pa")
    if record and r["p_peak"] < PRESSURE_LOW:
        peaks = np.max(np.abs(p), axis=0)
        low = [k for k in (0, 1) if peaks[k] < PRESSURE_LOW * cfg.p_s]
        who = "the pressures x3 and x4 never exceed" if len(low) == 2 else f"{CHANNELS[2 + low[0]]} never exceeds"
        peak = float(max(peaks[k] for k in low))
        return (f"{who} {_pressure(peak)}, {peak / cfg.p_s:.2g} times the supply pressure p_s = {_pressure(cfg.p_s)}: "
                f"{'are they' if len(low) == 2 else 'is it'} in bar, MPa or psi?"
                + _config_tail("p_s", _pressure(cfg.p_s)))
    return None


def record_slip(samples: np.ndarray, cfg, options=None, restarts=()) -> str | None:
    """``unit_slip`` of a whole record as the identifier sees it: after the outlier gate
    (``monitor.outlier_gate.gated`` with ``options`` and the ``restarts`` that follow gaps), with
    GLITCH_SAMPLES samples beyond still a glitch, as the live monitor judges one evaluation's."""
    from .outlier_gate import gated

    return unit_slip(gated(samples, options, restarts)[0], cfg, allow=GLITCH_SAMPLES)


def longest_stretch(n: int, restarts=()) -> tuple[int, int]:
    """``(lo, hi)``: samples[lo:hi] of a record of ``n`` samples is its longest stretch without a
    gap (``restarts``: the samples that follow gaps; the first of equals)."""
    bounds = [0, *restarts, n]
    return max(zip(bounds[:-1], bounds[1:]), key=lambda b: b[1] - b[0])
