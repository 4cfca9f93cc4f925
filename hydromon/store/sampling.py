"""The time grid of a record: strictly increasing t [s], one sample period apart but for gaps of
whole periods. A file in another rate or unit of t is refused with what it most likely is."""

from __future__ import annotations

import numpy as np

__all__ = ["RATE_TOL", "TYPICAL_TOL", "check_increasing", "check_sampling", "check_seq_rate", "time_jitter"]


RATE_TOL = 0.01  # allowed relative deviation of each sample interval from 1 / sample_rate


# the median interval further than this from one period [relative] means another rate or unit
# (a quarter, not a half: 200 Hz sits at half a period, where rounding goes either way)
TYPICAL_TOL = 0.25


def _rate_hint(typical: float, h: float, sample_rate: float) -> str:
    """What a typical interval ``typical`` [s] other than the period ``h`` [s] most likely means."""
    for factor, unit in ((1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")):
        if abs(typical / (factor * h) - 1) <= RATE_TOL:
            return f"t looks like {unit}; give t in seconds (SI)"
    return f"the file looks sampled at {1 / typical:.4g} Hz, not {sample_rate:g} Hz (or t is not in seconds)"


def check_increasing(t: np.ndarray, where=lambda i: f"sample {i}") -> np.ndarray:
    """The intervals of ``t`` [s], which must increase strictly (ValueError naming the first
    sample that does not, by ``where(i)``)."""
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s does not increase strictly "
                         f"(previous {float(t[i - 1])!r} s)")
    return dt


def check_sampling(t: np.ndarray, sample_rate: float, where=lambda i: f"sample {i}") -> tuple[list[int], int]:
    """t [s] must increase strictly, the median interval must be one sample period
    1/sample_rate [Hz] (within TYPICAL_TOL), and every interval within RATE_TOL of a whole
    number of periods.
    Returns the indices of samples after a gap (an interval of 2 periods or more) and the
    number of samples missing in the gaps.

    ``where(i)`` names sample i in the error (e.g. its CSV line).
    """
    h = 1.0 / sample_rate
    dt = check_increasing(t, where)
    if not dt.size:
        return [], 0
    periods = np.rint(dt / h)
    typical = float(np.median(dt))
    if abs(typical / h - 1) > TYPICAL_TOL:
        # another rate or unit: every interval may still be a whole number of periods (t in ms:
        # 1000 each), which would pass below as a record of nothing but gaps
        off = np.flatnonzero(periods != 1)
        i = int(off[0]) + 1 if off.size else 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous sample, "
                         f"and the median interval is {typical:.6g} s, but the rig samples every {h!r} s "
                         f"({sample_rate:g} Hz): {_rate_hint(typical, h, sample_rate)}")
    bad = np.flatnonzero(np.abs(dt - periods * h) > RATE_TOL * h)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous "
                         f"sample; the rig samples every {h!r} s ({sample_rate:g} Hz, 1 % tolerance)")
    gaps = np.flatnonzero(periods > 1)
    return [int(i) + 1 for i in gaps], int(np.sum(periods[gaps] - 1))


def time_jitter(t: np.ndarray, seq: np.ndarray, sample_rate: float) -> tuple[int, float]:
    """Intervals whose time stamps disagree with their seq step by more than RATE_TOL of a
    period, and the largest of those disagreements [s] (0 if none). The monitor goes by seq and
    never reads t, so this is reported, not refused."""
    off = np.abs(np.diff(t) - np.diff(seq) / sample_rate)
    bad = off[off > RATE_TOL / sample_rate]
    return int(bad.size), float(bad.max()) if bad.size else 0.0


def check_seq_rate(t: np.ndarray, seq: np.ndarray, sample_rate: float, where: str) -> None:
    """A record taken by seq (MCAP) must still be at its config's rate: the median time per seq
    step [s] within TYPICAL_TOL of 1/sample_rate [Hz], else ValueError naming ``where``. Jitter is
    counted, not refused (:func:`time_jitter`), but a config at another rate than the rig's time
    stamps would put every rate in the estimates off by that factor (a 40 s record at 100 Hz under
    a 50 Hz config reads as 80 s, its damping twice the true)."""
    steps = np.diff(seq)
    ok = steps > 0
    if not ok.any():
        return
    typical = float(np.median(np.diff(t)[ok] / steps[ok]))
    h = 1.0 / sample_rate
    if abs(typical / h - 1) > TYPICAL_TOL:
        raise ValueError(f"{where}: its time stamps step {typical:.6g} s per seq, but its config says the rig samples "
                         f"every {h!r} s ({sample_rate:g} Hz): {_rate_hint(typical, h, sample_rate)}; if the "
                         "recording's config is wrong, give the rig's constants with --config FILE")
