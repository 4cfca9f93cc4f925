"""Health ranges as data: the graded parameters' band edges between the five grades, as a
pydantic model and as the arrays the grading kernel reads. See ``monitor.grading`` for how a
value is graded against them.

A ranges file is made for one rig: it names the rig constants it was made for (``rig``), and
ranges are never applied to a rig whose constants differ (:meth:`Ranges.made_for`). Two files
ship, both made for the reference rig (the constants ``RigConfig()`` defaults to):
``monitor/data/table3.json``, the paper's Table 3 as printed (in SI units), and
``monitor/data/default_ranges.json``, the default: Table 3 with the valve graded on its static
gain K_sv (edges / omega_sv^2 = 1e4) instead of K_sv omega^2, which a record without excitation
at the valve's bandwidth does not identify (see that file's source note). Ranges for another
rig come from ``hydromon commission`` (its baseline, noise and the record they were made from
travel in the file) or ``hydromon calibrate --labelled``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, PrivateAttr, ValidationError, field_validator, model_validator

from plant_sim.validation import brief_error

from hydromon.contract import GRADES, PARAM_NAMES, RigConfig

__all__ = ["ParamRange", "Ranges", "RangeArrays", "Estimate", "grade_name", "DEFAULT_RANGES_PATH", "PAPER_TABLE3_PATH",
           "RIG_MATCH_RTOL", "RIG_MATCH_FIELDS"]

# The constants that decide which rig ranges were made for: everything the identification uses.
# The sensors' full-scale spans only set the simulator's "stress" noise model and are not compared.
RIG_MATCH_FIELDS = ("A1", "A2", "V10", "V20", "p_s", "F_L", "K_p", "K_f", "sample_rate")
# Rig constants are configuration, copied from one source: they agree to the last digit unless
# someone changed them. The tolerance only absorbs a decimal round trip through a file format
# that prints 7 significant digits (TOML or CSV written by hand, a spreadsheet).
RIG_MATCH_RTOL = 1e-6

PAPER_TABLE3_PATH = Path(__file__).with_name("data") / "table3.json"
DEFAULT_RANGES_PATH = Path(__file__).with_name("data") / "default_ranges.json"


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= RIG_MATCH_RTOL * max(abs(a), abs(b))


def grade_name(level: int) -> str:
    """Grade name of a level 0..4 (contract GRADES), ``"unknown"`` for -1."""
    return GRADES[level] if 0 <= level < len(GRADES) else "unknown"


class ParamRange(BaseModel):
    """Bands of one graded parameter, in its SI unit.

    direction : "rising" (the value grows as the rig degrades) or "falling".
    edges : the four boundaries between the five grades, in grade order (health|sub, sub|average,
        average|deterioration, deterioration|fault); strictly increasing if rising, strictly
        decreasing if falling.
    fault_threshold : instead of edges, a two-level parameter: on the healthy side of the
        threshold grade 0, past it grade 4.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    direction: Literal["rising", "falling"]
    edges: tuple[float, float, float, float] | None = None
    fault_threshold: float | None = None

    @model_validator(mode="after")
    def _check(self) -> ParamRange:
        if (self.edges is None) == (self.fault_threshold is None):
            raise ValueError("give exactly one of 'edges' (4 values) or 'fault_threshold'")
        if self.edges is not None:
            s = 1.0 if self.direction == "rising" else -1.0
            for a, b in zip(self.edges, self.edges[1:]):
                if not s * (b - a) > 0:
                    raise ValueError(f"edges {list(self.edges)} must be strictly "
                                     f"{'increasing' if s > 0 else 'decreasing'} for a "
                                     f"{self.direction} parameter (at {a} -> {b})")
        return self

    def edge_array(self) -> np.ndarray:
        """The four edges in grade order [unit of the parameter]; a threshold is repeated 4x."""
        if self.edges is not None:
            return np.array(self.edges, dtype=np.float64)
        return np.full(4, float(self.fault_threshold), dtype=np.float64)

    def margin_array(self, margin: float) -> np.ndarray:
        """Hysteresis margins of the four edges [unit of the parameter] for a relative margin
        [-]: ``margin * |e_j|``, capped at half the narrower inner band next to the edge."""
        e = self.edge_array()
        m = margin * np.abs(e)
        if self.edges is not None:
            w = np.abs(np.diff(e))  # widths of the inner bands 1, 2, 3
            m = np.minimum(m, 0.5 * np.minimum(np.r_[np.inf, w], np.r_[w, np.inf]))
        return m


class Estimate(BaseModel):
    """A parameter's value [its SI unit] and standard error [same unit; None when unknown]."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    value: float
    std_error: float | None = None


class RangeArrays(NamedTuple):
    """Plain arrays for :func:`grade_kernel`: graded names, their index in the estimate vector,
    sign (+1 rising, -1 falling), edges and hysteresis margins (n_graded, 4) in grade order [SI]."""

    names: tuple[str, ...]
    index: np.ndarray
    sign: np.ndarray
    edges: np.ndarray
    margins: np.ndarray


class Ranges(BaseModel):
    """Health ranges of one rig: one :class:`ParamRange` per graded parameter, keyed by bus name.

    Attributes
    ----------
    params : dict
        The graded parameters' ranges [SI].
    source : str
        How they were made, in words.
    rig : RigConfig or None
        The rig constants they were made for (None: unknown, so they apply to no rig).
    baseline : dict
        The rig's own healthy values (name -> :class:`Estimate`), when commissioned.
    noise : dict
        The sensors' noise rms they were made at: x1 [m], x3 [Pa], x4 [Pa], x5 [m].
    made_on : str
        The record they were made from (file and rig), and its length.
    created : str
        When (ISO 8601, UTC).
    ungraded : dict
        Parameters the reference ranges grade that these leave out, and why.
    """

    model_config = ConfigDict(extra="forbid")
    _arrays: dict = PrivateAttr(default_factory=dict)  # (margin, names, params id) -> RangeArrays
    params: dict[str, ParamRange]
    source: str = ""
    rig: RigConfig | None = None
    baseline: dict[str, Estimate] = {}
    noise: dict[str, float] = {}
    made_on: str = ""
    created: str = ""
    ungraded: dict[str, str] = {}

    @field_validator("params")
    @classmethod
    def _names(cls, v: dict[str, ParamRange]) -> dict[str, ParamRange]:
        bad = [k for k in v if k not in PARAM_NAMES]
        if bad:
            raise ValueError(f"unknown parameter name(s) {bad}; known: {list(PARAM_NAMES)}")
        if not v:
            raise ValueError("ranges grade no parameter")
        return v

    @classmethod
    def load(cls, path: str | Path) -> Ranges:
        """Read a ranges JSON file; ValueError naming the file and what is wrong (unreadable,
        not UTF-8, or the bad entry)."""
        try:
            text = Path(path).read_text()
        except OSError as e:
            raise ValueError(f"ranges file {str(path)!r}: {e.strerror or e}") from None
        except UnicodeDecodeError as e:
            raise ValueError(f"ranges file {str(path)!r}: byte {e.object[e.start]:#04x} at offset {e.start} "
                             "is not UTF-8 text (a ranges JSON file?)") from None
        try:
            return cls.model_validate_json(text)
        except ValidationError as e:
            raise ValueError(f"bad ranges file {str(path)!r}: {brief_error(e)}") from None

    @classmethod
    def default(cls) -> Ranges:
        """hydromon's default: Table 3, the valve on K_sv (``monitor/data/default_ranges.json``)."""
        return cls.load(DEFAULT_RANGES_PATH)

    @classmethod
    def resolve(cls, spec: str | Path) -> Ranges:
        """``"paper"`` (:meth:`paper`), ``"default"`` (:meth:`default`) or a ranges JSON file
        (a file of one of those names: ``./paper``)."""
        if str(spec) == "paper":
            return cls.paper()
        if str(spec) == "default":
            return cls.default()
        return cls.load(spec)

    @classmethod
    def paper(cls) -> Ranges:
        """The paper's Table 3 as printed (``monitor/data/table3.json``)."""
        return cls.load(PAPER_TABLE3_PATH)

    def made_for(self, config: RigConfig | None) -> str | None:
        """None when these ranges were made for a rig with the constants ``config`` (None: the
        reference rig's), else why not, in words (for the log and the commands' output)."""
        config = config or RigConfig()
        if self.rig is None:
            return "the ranges name no rig constants they were made for"
        diff = [f"{k} {getattr(config, k):g} (ranges made for {getattr(self.rig, k):g})" for k in RIG_MATCH_FIELDS
                if not _close(getattr(config, k), getattr(self.rig, k))]
        if not diff:
            return None
        return "the rig's constants differ from those the ranges were made for: " + ", ".join(diff)

    def save(self, path: str | Path) -> None:
        """Write as JSON (readable by :meth:`load`)."""
        Path(path).write_text(json.dumps(self.model_dump(exclude_none=True), indent=2) + "\n")

    def to_arrays(self, margin: float = 0.02,
                  param_names: tuple[str, ...] = PARAM_NAMES) -> RangeArrays:
        """Arrays for the kernel, graded parameters in ``param_names`` order; ``margin`` is the
        relative hysteresis margin [-] (see :meth:`ParamRange.margin_array`).

        Made once per ranges, margin and names, and shared (the fleet copies them into its own
        arrays): a monitor grades each new rig on them, and making them took 0.12 ms, a third of
        taking a new rig in (ranges are not changed in place; new ranges are a new object)."""
        key = (margin, param_names, id(self.params))
        arrays = self._arrays.get(key)
        if arrays is None:
            arrays = self._arrays[key] = self._make_arrays(margin, param_names)
        return arrays

    def _make_arrays(self, margin: float, param_names: tuple[str, ...]) -> RangeArrays:
        names = tuple(n for n in param_names if n in self.params)
        missing = [n for n in self.params if n not in param_names]
        if missing:
            raise ValueError(f"graded parameter(s) {missing} not in the estimate vector")
        index = np.array([param_names.index(n) for n in names], dtype=np.int64)
        sign = np.array([1.0 if self.params[n].direction == "rising" else -1.0 for n in names])
        edges = np.array([self.params[n].edge_array() for n in names], dtype=np.float64)
        margins = np.array([self.params[n].margin_array(margin) for n in names], dtype=np.float64)
        return RangeArrays(names, index, sign, edges, margins)
