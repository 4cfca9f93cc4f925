"""Health grading: parameter ranges (monitor.ranges), SE gating, hysteresis and fusion.

Grades are levels 0 health, 1 sub-health, 2 average, 3 deterioration, 4 fault; -1 is unknown.

Rules (all in :func:`grade_kernel`, which the single-rig and batched paths share):

- **Bands.** A graded parameter has four inner edges ``e_0..e_3`` between the five grades and a
  direction. Rising: grade = #{j : v > e_j}; falling: grade = #{j : v < e_j}. A value on an edge
  belongs to the better grade, as Table 3's ``(10, 20]`` brackets say for f_c and B+f_v (its
  ``[2.6, 2.2], [2.2, 1.7]`` for K_sv omega^2 are ambiguous; we use the same rule). Values
  beyond Table 3's outer ends clamp: below 4 N f_c is health, above 120 N fault. A two-level
  parameter (C_ip, C_ep) has all four edges at its fault threshold: grade 0 or 4.
- **SE gating.** With standard error ``s``, the interval ``v +- z s`` is graded at both ends.
  A parameter is placed when the interval lies inside one band, or straddles one edge with the
  band it is held in (hysteresis) on one side. Otherwise it is not placed (-1) and takes no
  part in the fusion: f_c's 6 N health band under an SE of several N, or B+f_v's 1 % bands
  under a few % of SE, would otherwise decide the worst-of fusion by noise. A parameter that
  straddles one edge (grades lo|lo+1) still proves the grade is at least lo: the fused level
  is never below that floor, and when the floor is what sets the level, that parameter shows
  grade lo and counts as placed in the confidence (it showed ``unknown``, and the confidence
  over the placed parameters, all better than the level, was ~0: a grade with no reason
  shown). When no multi-band parameter is placed (the two-level leakages
  alone say nothing between health and deterioration), the straddler with the smallest SE
  relative to its band's width is graded at its value, so a rig near a band edge still gets a
  grade. (Measured on 180 seeded random rigs, tests/monitor/test_grading_random_rigs.py: 97 %
  right; promoting the most precise straddler whenever it is worse than the placed ones: 95 %.)
  A non-finite value or SE is never placed. For a two-level parameter an interval over the
  threshold spans four grades, so it is not placed.
- **Hysteresis.** Once placed in band ``b`` a parameter leaves it only when its value is past
  the edge by a margin ``m_j = min(margin * |e_j|, half the narrower inner band next to e_j)``
  (default 2 %): the new band is ``b`` clamped to [grade with every edge moved ``m_j`` towards
  worse, grade with every edge moved towards better]. The cap keeps the rule that a value
  strictly past the middle of a band is graded in that band whatever the history; it matters
  for B+f_v, whose bands are 1-2 % of its value (2 % of 6150 is 123 N s/m, its sub-health
  band is 75 wide). Two-level parameters have no cap. While a parameter is not placed its band
  memory is kept.
- **Fusion.** level = max of the placed grades; -1 while the rig has not converged (then no
  parameter is placed and the state is left as it was) or if nothing is placed.
- **Confidence.** With independent Gaussian errors ``N(v_p, s_p^2)``, the probability that the
  true fused grade equals the reported level L over the placed parameters,
  ``prod_p P_p(grade <= L) - prod_p P_p(grade <= L-1)``, times the fraction of graded
  parameters that were placed (an unplaced parameter could be anything; this discount is a
  heuristic). In [0, 1]; 0 when the level is unknown. With ``s = 0`` the probabilities are 0/1,
  so a level held by hysteresis while the value is just past an edge has confidence 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numba import njit

from hydromon.contract import PARAM_NAMES

from .ranges import DEFAULT_RANGES_PATH, ParamRange, RangeArrays, Ranges, grade_name  # noqa: F401  (re-exported)

__all__ = [
    "ParamRange", "Ranges", "RangeArrays", "grade_kernel", "GradeResult", "BatchGradeResult",
    "Grader", "BatchGrader", "grade_of_values", "grade_name", "DEFAULT_RANGES_PATH",
]

@njit(cache=True, error_model="numpy")
def _count_past(u: float, f: np.ndarray, m: np.ndarray, shift: float) -> int:
    """#{j : u > f_j + shift m_j}, u and edges f in the worsening coordinate (sign * value)."""
    n = 0
    for j in range(f.shape[0]):
        if u > f[j] + shift * m[j]:
            n += 1
    return n


@njit(cache=True, error_model="numpy")
def _band_width(g: int, f: np.ndarray) -> float:
    """Width of band g between edges f (outer bands take their inner neighbour's width)."""
    if g <= 0:
        return f[1] - f[0]
    if g >= 4:
        return f[3] - f[2]
    return f[g] - f[g - 1]


@njit(cache=True, error_model="numpy")
def _p_at_most(g: int, u: float, s: float, f: np.ndarray) -> float:
    """P(true grade <= g) for a true value ~ N(u, s^2) in the worsening coordinate."""
    if g < 0:
        return 0.0
    if g >= f.shape[0]:
        return 1.0
    if s == 0.0:
        return 1.0 if u <= f[g] else 0.0
    return 0.5 * math.erfc((u - f[g]) / (s * math.sqrt(2.0)))


@njit(cache=True, error_model="numpy")
def grade_kernel(values, std_errors, converged, index, sign, edges, margins, z, band):
    """One grading step for many rigs; updates ``band`` in place.

    Parameters
    ----------
    values, std_errors : (n_rigs, n_params) float64
        Estimates and their standard errors, in PARAM_NAMES order [SI units of each parameter].
    converged : (n_rigs,) bool
        The identifier has converged for this rig.
    index, sign, edges, margins : from :meth:`Ranges.to_arrays` ((n_graded,) int64,
        (n_graded,) +-1, (n_graded, 4) float64 [SI], (n_graded, 4) float64 >= 0 [SI]).
    z : float
        Half-width of the gating interval in standard errors [-].
    band : (n_rigs, n_graded) int64
        Hysteresis state, the band each parameter is held in (-1 none yet); updated in place.

    Returns
    -------
    level : (n_rigs,) int64, fused level 0..4, -1 unknown.
    grades : (n_rigs, n_graded) int64, per-parameter grade, -1 not placed.
    confidence : (n_rigs,) float64 in [0, 1].
    """
    n_rigs = values.shape[0]
    n_g = index.shape[0]
    level = np.full(n_rigs, -1, dtype=np.int64)
    grades = np.full((n_rigs, n_g), -1, dtype=np.int64)
    confidence = np.zeros(n_rigs, dtype=np.float64)
    f = np.empty(4, dtype=np.float64)
    for r in range(n_rigs):
        if not converged[r]:
            continue
        n_placed = 0
        best_k = -1
        best_q = np.inf
        floor = -1
        floor_k = -1
        n_multi = 0
        for k in range(n_g):
            v = values[r, index[k]]
            s = std_errors[r, index[k]]
            if not (math.isfinite(v) and math.isfinite(s)) or s < 0.0:
                continue
            for j in range(4):
                f[j] = sign[k] * edges[k, j]
            u = sign[k] * v
            m = margins[k]
            lo = _count_past(u - z * s, f, m, 0.0)
            hi = _count_past(u + z * s, f, m, 0.0)
            if hi - lo > 1:
                continue
            b = band[r, k]
            if hi != lo and not (b == lo or b == hi):
                # straddles an edge and no held band agrees: not placed, but it proves the
                # grade is at least lo; the most precise such one (SE relative to its band's
                # width) may decide between lo and hi below
                if lo > floor:
                    floor = lo
                    floor_k = k
                g = _count_past(u, f, m, 0.0)
                width = _band_width(g, f)
                q = s / width if width > 0.0 else np.inf
                if q < best_q:
                    best_q = q
                    best_k = k
                continue
            if b < 0:
                b = lo
            elif hi == lo:
                b = min(max(b, _count_past(u, f, m, 1.0)), _count_past(u, f, m, -1.0))
            band[r, k] = b
            grades[r, k] = b
            n_placed += 1
            if edges[k, 0] != edges[k, 3]:
                n_multi += 1
            if b > level[r]:
                level[r] = b
        if best_k >= 0:
            k = best_k
            for j in range(4):
                f[j] = sign[k] * edges[k, j]
            b = _count_past(sign[k] * values[r, index[k]], f, margins[k], 0.0)
            if n_multi == 0:
                band[r, k] = b
                grades[r, k] = b
                n_placed += 1
                if b > level[r]:
                    level[r] = b
        if floor > level[r]:
            # the level is this parameter's doing: it shows as that grade (it is at least that
            # bad) and counts in the confidence; before, it showed "unknown" and the confidence,
            # taken over the placed parameters only, all below the level, was ~0
            level[r] = floor
            if grades[r, floor_k] < 0:
                grades[r, floor_k] = floor
                n_placed += 1
        if level[r] < 0:
            continue
        p_le = 1.0
        p_lt = 1.0
        for k in range(n_g):
            if grades[r, k] < 0:
                continue
            for j in range(4):
                f[j] = sign[k] * edges[k, j]
            u = sign[k] * values[r, index[k]]
            s = std_errors[r, index[k]]
            p_le *= _p_at_most(level[r], u, s, f)
            p_lt *= _p_at_most(level[r] - 1, u, s, f)
        confidence[r] = min(max(p_le - p_lt, 0.0), 1.0) * n_placed / n_g
    return level, grades, confidence


@dataclass(frozen=True)
class GradeResult:
    """Grade of one rig at one sample: level 0..4 (-1 unknown), its name, per-parameter levels
    (-1 not placed) by bus name, and confidence in [0, 1]."""

    level: int
    grade: str
    param_levels: dict[str, int]
    confidence: float

    @property
    def param_grades(self) -> dict[str, str]:
        """Per-parameter grade names (``"unknown"`` where not placed), as in the Health payload."""
        return {k: grade_name(v) for k, v in self.param_levels.items()}


@dataclass(frozen=True)
class BatchGradeResult:
    """Grades of many rigs: level (n_rigs,), param_levels (n_rigs, n_graded) in ``names``
    order, confidence (n_rigs,)."""

    names: tuple[str, ...]
    level: np.ndarray
    param_levels: np.ndarray
    confidence: np.ndarray

    def rig(self, i: int) -> GradeResult:
        lv = int(self.level[i])
        return GradeResult(lv, grade_name(lv),
                           {n: int(g) for n, g in zip(self.names, self.param_levels[i])},
                           float(self.confidence[i]))


def _vector(x, n_rigs: int, what: str) -> np.ndarray:
    """(n_rigs, n_params) float64 from an array, or for one rig a name -> value mapping
    (missing names are NaN: not placed)."""
    if isinstance(x, Mapping):
        bad = [k for k in x if k not in PARAM_NAMES]
        if bad:
            raise ValueError(f"{what}: unknown parameter name(s) {bad}")
        x = [float(x.get(n, math.nan)) for n in PARAM_NAMES]
    a = np.array(x, dtype=np.float64)
    if n_rigs == 1 and a.ndim == 1:
        a = a[None, :]
    if a.shape != (n_rigs, len(PARAM_NAMES)):
        raise ValueError(f"{what} has shape {a.shape}, expected ({n_rigs}, {len(PARAM_NAMES)})")
    return a


class BatchGrader:
    """Grades many rigs together (state: ``band``, (n_rigs, n_graded) int64).

    Parameters
    ----------
    n_rigs : int
        Number of rigs.
    ranges : Ranges, optional
        Health ranges; ``Ranges.default()`` (Table 3, the valve on K_sv) by default.
    z : float
        Gating half-width in standard errors [-].
    margin : float
        Hysteresis margin as a fraction of the edge value [-], capped per edge (module doc).
    """

    def __init__(self, n_rigs: int, ranges: Ranges | None = None, z: float = 2.0,
                 margin: float = 0.02):
        if not (isinstance(n_rigs, int) and n_rigs >= 1):
            raise ValueError(f"n_rigs={n_rigs!r} must be an integer >= 1")
        if not (math.isfinite(z) and z > 0):
            raise ValueError(f"z={z!r} must be finite and > 0")
        if not (math.isfinite(margin) and 0 <= margin < 1):
            raise ValueError(f"margin={margin!r} must be in [0, 1)")
        self.n_rigs, self.z, self.margin = n_rigs, float(z), float(margin)
        self.ranges = Ranges.default() if ranges is None else ranges
        self._arrays = self.ranges.to_arrays(self.margin)
        self.band = np.full((n_rigs, len(self._arrays.names)), -1, dtype=np.int64)

    @property
    def names(self) -> tuple[str, ...]:
        """Graded parameter names, in kernel order."""
        return self._arrays.names

    def reset(self, rig: int | None = None) -> None:
        """Forget the hysteresis state of one rig (or all)."""
        self.band[slice(None) if rig is None else rig] = -1

    def update(self, values, std_errors, converged) -> BatchGradeResult:
        """Grade one sample of every rig.

        values, std_errors : (n_rigs, n_params) in PARAM_NAMES order [SI]; SE >= 0, inf/NaN
            means unidentified (not placed). converged : (n_rigs,) bool.
        """
        v = _vector(values, self.n_rigs, "values")
        s = _vector(std_errors, self.n_rigs, "std_errors")
        neg = np.argwhere(s < 0)
        if neg.size:
            r, p = neg[0]
            raise ValueError(f"std_errors[{r}] of {PARAM_NAMES[p]} = {s[r, p]} is negative")
        c = np.asarray(converged, dtype=np.bool_).reshape(-1)
        if c.shape != (self.n_rigs,):
            raise ValueError(f"converged has shape {c.shape}, expected ({self.n_rigs},)")
        a = self._arrays
        level, grades, conf = grade_kernel(v, s, c, a.index, a.sign, a.edges, a.margins,
                                           self.z, self.band)
        return BatchGradeResult(a.names, level, grades, conf)


class Grader:
    """Streaming grader of one rig; the batched kernel with n_rigs = 1 (see module docstring).

    Parameters are those of :class:`BatchGrader` without ``n_rigs``.
    """

    def __init__(self, ranges: Ranges | None = None, z: float = 2.0, margin: float = 0.02):
        self.ranges, self.z, self.margin = ranges, z, margin
        self._batch = BatchGrader(1, ranges, z, margin)

    @property
    def band(self) -> np.ndarray:
        """Hysteresis state (n_graded,), -1 where no band yet."""
        return self._batch.band[0]

    def reset(self) -> None:
        self._batch.reset()

    def update(self, values, std_errors, converged: bool) -> GradeResult:
        """Grade one sample: values, std_errors (n_params,) in PARAM_NAMES order or mappings by
        name [SI]; converged: the identifier has converged."""
        return self._batch.update(values, std_errors, [bool(converged)]).rig(0)


def grade_of_values(values: Mapping[str, float], ranges: Ranges | None = None) -> int:
    """Level 0..4 of TRUE parameter values (no SE, no hysteresis) [SI, by bus name].

    Uses the kernel with zero standard errors and a fresh state; parameters missing from
    ``values`` are left out. ValueError if a value is not finite or none is graded.
    """
    ranges = Ranges.default() if ranges is None else ranges
    bad = {k: v for k, v in values.items() if not math.isfinite(v)}
    if bad:
        raise ValueError(f"true values must be finite: {bad}")
    if not any(k in ranges.params for k in values):
        raise ValueError(f"none of {sorted(values)} is graded by the ranges")
    return Grader(ranges, margin=0.0).update(values, dict.fromkeys(values, 0.0), True).level
