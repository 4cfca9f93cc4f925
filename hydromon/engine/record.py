"""One rig's record, validated: what ``evaluate`` and ``audit`` grade (``hydromon.store.recording``
reads it from a CSV or an MCAP)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hydromon.contract import RigConfig
from monitor.readings import longest_stretch

__all__ = ["Recording"]


@dataclass(frozen=True)
class Recording:
    """One rig's validated samples: t (N,) [s], samples (N, 5) = ug [V], x1 [m], x3 [Pa],
    x4 [Pa], x5 [m]; the rig id and the rig constants the data were taken with."""

    rig: str
    t: np.ndarray
    samples: np.ndarray
    config: RigConfig
    source: str
    restarts: tuple[int, ...] = ()  # indices of samples that follow a gap
    missing: int = 0  # samples missing in those gaps
    rejected: int = 0  # invalid samples skipped (MCAP)
    duplicate: int = 0  # samples dropped for a seq equal to the last one taken (MCAP)
    out_of_order: int = 0  # samples dropped for a seq below the last one taken (MCAP)
    jitter: int = 0  # intervals whose time stamps are off their seq step by > RATE_TOL (MCAP)
    jitter_max: float = 0.0  # the largest disagreement of those intervals [s]
    config_changes: int = 0  # rig config changes in the record (MCAP)
    skipped: int = 0  # samples before the last config change, not evaluated
    drive_samples: int = 0  # samples whose valve input is the drive u they carry (else K_p (ug - K_f x1))

    @property
    def duration(self) -> float:
        """The span the samples cover [s]: first to last sample plus one period, gaps included."""
        return (len(self.samples) + self.missing) / self.config.sample_rate

    def longest_stretch(self) -> tuple[int, int]:
        """``(lo, hi)``: samples[lo:hi] is the longest stretch without a gap (the first of equals)."""
        return longest_stretch(len(self.samples), self.restarts)
