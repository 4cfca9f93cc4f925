"""A rig's evaluations: one (:class:`Assessment`) and a batch's worth (:class:`Events`), and when
each rig is evaluated (:func:`eval_phase`)."""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from hydromon.contract import PARAM_NAMES

from .plausibility import implausible_names
from .ranges import grade_name

__all__ = ["Assessment", "Events", "eval_phase"]


def eval_phase(rig_id: str, eval_every: int) -> int:
    """A rig's evaluation phase in [0, eval_every): the same in every process and run (CRC-32
    of the id), so a live monitor and a replay of its recording evaluate at the same samples."""
    return zlib.crc32(rig_id.encode()) % eval_every


@dataclass(frozen=True)
class Assessment:
    """One evaluation of one rig.

    Attributes
    ----------
    count : int
        Samples the rig had consumed when evaluated.
    level : int
        0 (health) .. 4 (fault); -1 unknown.
    confidence : float
        [0, 1], see monitor.grading.
    params, std_errors : dict
        By PARAM_NAMES, SI.
    param_levels : dict
        Graded parameters' levels (-1 = not placed).
    converged : bool
    implausible : tuple of str
        Parameters whose estimate is physically impossible (``monitor.plausibility``): the
        input is in wrong units, of the wrong sign or zero, or the rig constants are wrong;
        the rig is then not graded (level -1).
    """

    count: int
    level: int
    confidence: float
    params: dict
    std_errors: dict
    param_levels: dict
    converged: bool
    implausible: tuple = ()

    @property
    def grade(self) -> str:
        return grade_name(self.level)

    @property
    def param_grades(self) -> dict:
        return {k: grade_name(v) for k, v in self.param_levels.items()}


@dataclass(frozen=True)
class Events:
    """Evaluations produced by one ``Fleet.update`` (arrays, one row per event)."""

    rig: np.ndarray
    sample: np.ndarray  # index of the sample in the batch after which the rig was evaluated
    counts: np.ndarray  # the rig's sample count at the event
    level: np.ndarray
    confidence: np.ndarray
    params: np.ndarray
    std_errors: np.ndarray
    grades: np.ndarray
    converged: np.ndarray
    clamped: np.ndarray  # the rig's samples so far whose x1 emptied a chamber (wrong config or x1)
    implausible: np.ndarray  # physically impossible estimates: not graded (monitor.plausibility)

    def __len__(self) -> int:
        return len(self.rig)

    @staticmethod
    def concat(parts: list[Events], offsets: list[int]) -> Events:
        """One Events of several updates; ``offsets`` shift each part's sample indices."""
        f = {k: np.concatenate([getattr(p, k) for p in parts]) for k in Events.__dataclass_fields__}
        f["sample"] = np.concatenate([p.sample + o for p, o in zip(parts, offsets)])
        return Events(**f)

    def assessment(self, i: int, graded: tuple) -> Assessment:
        return Assessment(
            count=int(self.counts[i]), level=int(self.level[i]), confidence=float(self.confidence[i]),
            params=dict(zip(PARAM_NAMES, map(float, self.params[i]))),
            std_errors=dict(zip(PARAM_NAMES, map(float, self.std_errors[i]))),
            param_levels=dict(zip(graded, map(int, self.grades[i]))), converged=bool(self.converged[i]),
            implausible=(implausible_names(dict(zip(PARAM_NAMES, self.params[i].tolist())),
                                           dict(zip(PARAM_NAMES, self.std_errors[i].tolist())))
                         if self.implausible[i] else ()),
        )

    @staticmethod
    def of_kernel(arrays) -> Events:
        """Events from the kernel's event arrays (``EventArrays``, same fields in the same order;
        the kernel leaves rows with physically impossible estimates ungraded: level -1, confidence
        0, grades -1)."""
        return Events(*arrays)
