"""One record's signals for the audit: its channels, their noise levels and the equation filter L.

The audit works on a whole record at once, so it may filter without phase lag. Every term
of an equation goes through the same zero-phase Savitzky-Golay filter L; a derivative is the
central difference of the filtered signal, so (L x)' = L[x'] holds at every frequency L
passes (the SG derivative filter breaks that where L attenuates, which misfits fast
inputs). The chamber equations use a 31-sample window (pressure-rate noise), the force
equation 11 samples (friction acts near rest).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..fourth_difference import CHI2_1_MEDIAN, D4_VARIANCE_GAIN

__all__ = ["Signals", "signals", "require_length", "SG_WINDOW", "FORCE_WINDOW", "MARGIN", "MIN_SAMPLES"]

SG_WINDOW = 31  # [samples] window of the chamber equations' filter L (odd)
FORCE_WINDOW = 11  # [samples] window of the force equation's filter (friction acts near rest: keep it short)
SG_LIGHT = 11  # [samples] window of the light smoothing of nonlinear terms' ingredients
SG_ORDER = 3
MARGIN = 25  # [samples] rows dropped at both ends (filter edges and x1 re-alignment)
MIN_SAMPLES = 10 * MARGIN  # the shortest record the audit takes


@lru_cache(maxsize=8)
def _sg_weights(window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weights of a cubic least-squares fit over ``window`` samples evaluated at the window's
    centre, and at its first and last half (the record's edges, where the one fit over the
    first or last window is used: scipy.signal.savgol_filter's mode "interp")."""
    half = window // 2
    t = np.arange(window, dtype=float) - half
    v = np.vander(t, SG_ORDER + 1, increasing=True)
    fit = np.linalg.pinv(v)  # window samples -> polynomial coefficients
    return fit[0], v[:half] @ fit, v[half + 1:] @ fit


def _savgol(x: np.ndarray, window: int) -> np.ndarray:
    """Savitzky-Golay smoothing (cubic, odd ``window``) along axis 0, as
    ``scipy.signal.savgol_filter(x, window, 3, mode="interp", axis=0)`` (importing scipy.signal
    costs about a second, most of a short audit)."""
    centre, head, tail = _sg_weights(window)
    half, n = window // 2, len(x)
    y = np.empty_like(x)
    y[half:n - half] = sliding_window_view(x, window, axis=0) @ centre
    y[:half] = np.tensordot(head, x[:window], axes=(1, 0))
    y[n - half:] = np.tensordot(tail, x[n - window:], axes=(1, 0))
    return y


def _sg(x, deriv, h, window=SG_WINDOW):
    """Savitzky-Golay smoothing; derivatives are central differences of the smoothed signal,
    so that a derivative is the equation filter applied to the derivative, (L x)' = L[x'],
    at every frequency L passes (the SG derivative filter is not: it differs from
    j omega L(omega) where L attenuates, which misfits the equations on fast inputs)."""
    y = _savgol(np.asarray(x, dtype=float), window)
    if deriv == 0:
        return y
    if deriv == 1:
        return np.gradient(y, h, axis=0)
    if deriv == 2:
        d = np.zeros_like(y)
        d[1:-1] = (y[2:] - 2.0 * y[1:-1] + y[:-2]) / (h * h)
        d[0], d[-1] = d[1], d[-2]
        return d
    raise ValueError(f"derivative order must be 0, 1 or 2, got {deriv!r}")


@dataclass(frozen=True)
class Signals:
    """One record's channels (SI), lightly smoothed ingredients and noise levels.

    Attributes
    ----------
    h : float
        Sample period [s].
    ug, x1, x3, x4, x5 : arrays (N,)
        Raw measured channels [V, m, Pa, Pa, m].
    x1l, vl, x3l, x4l, x5l : arrays (N,)
        Lightly smoothed position [m], velocity [m/s], pressures [Pa], spool [m]: the
        ingredients of nonlinear terms (sign(v), the orifice factors), formed before the
        equation filter.
    vs : array (N,)
        Sample-to-sample velocity [m/s], the central difference of the raw x1: the ingredient of
        terms that change within a few samples of velocity (a Stribeck hump), which the light
        smoothing would average over a stick-slip surge.
    v_noise : float
        Noise rms of the equation-filtered velocity [m/s].
    sigma : array (4,)
        Sensor noise rms of x1 [m], x3 [Pa], x4 [Pa], x5 [m], from 4th differences.
    gain, gain_f : array (3,)
        White-noise gains (l2 norms) of the chamber (force) equation filter and its 1st and 2nd
        derivative [1, 1/s, 1/s^2]: a channel of noise rms s gives s * gain[k] in its k-th derivative.
    """

    h: float
    ug: np.ndarray
    x1: np.ndarray
    x3: np.ndarray
    x4: np.ndarray
    x5: np.ndarray
    x1l: np.ndarray
    vl: np.ndarray
    x3l: np.ndarray
    x4l: np.ndarray
    x5l: np.ndarray
    vs: np.ndarray
    v_noise: float
    sigma: np.ndarray
    gain: np.ndarray
    gain_f: np.ndarray

    @property
    def n(self) -> int:
        return len(self.ug)

    def smooth(self, x: np.ndarray, window: int = SG_WINDOW) -> np.ndarray:
        """The equation filter L (zero-phase Savitzky-Golay)."""
        return _sg(x, 0, self.h, window)

    def deriv(self, x: np.ndarray, k: int = 1, window: int = SG_WINDOW) -> np.ndarray:
        """k-th time derivative of L[x] [unit/s^k]."""
        return _sg(x, k, self.h, window)


def _d4_sigma(d4: np.ndarray) -> np.ndarray:
    """Noise rms [unit of the signal] from 4th differences along axis 0: the median of their
    squares, which ignores transients."""
    return np.sqrt(np.median(d4 * d4, axis=0) / D4_VARIANCE_GAIN / CHI2_1_MEDIAN)


def resolution(x: np.ndarray) -> float:
    """The step [unit of x] of which every change of ``x`` is a whole multiple (a quantized
    sensor, or values written with few decimals), 0 when there is none (99 % of the nonzero
    changes within 1 % of a multiple of the smallest)."""
    d = np.abs(np.diff(np.asarray(x, dtype=float)))
    d = d[d > 0]
    if len(d) < 10:
        return 0.0
    q = float(d.min())
    k = d / q
    return q if np.mean(np.abs(k - np.round(k)) <= 0.01) >= 0.99 else 0.0


def rounding_noise(x: np.ndarray) -> float:
    """The rms [unit of x] of a quantized channel's rounding: its ``resolution`` over sqrt(12); 0
    for a channel without one."""
    return resolution(x) / math.sqrt(12.0)


def noise_levels(s: np.ndarray) -> np.ndarray:
    """Noise rms of x1 [m], x3 [Pa], x4 [Pa], x5 [m] in the (N, 5) samples ``ug, x1, x3, x4, x5``:
    from 4th differences, and at least a quantized channel's ``rounding_noise``: where the
    rounding step exceeds the noise the reading holds still between steps, its 4th differences
    are mostly 0, and a 1 mm step of x1 read as a noise-free sensor."""
    s = np.asarray(s, dtype=float)
    floor = np.array([rounding_noise(s[:, k]) for k in range(1, 5)])
    return np.maximum(_d4_sigma(np.diff(s[:, 1:], 4, axis=0)), floor)


def noise_at(x: np.ndarray, rows: np.ndarray) -> float:
    """Noise rms [unit of x] from the 4th differences of x centred on ``rows`` (sample
    indices); nan when there are none. Over a whole record the motion's own 4th differences
    count as noise where the motion is jerky (a noise-free record with a 240 N stick-slip hump
    read 7.8 um on x1); where the piston stands they are the sensor's noise alone."""
    d4 = np.diff(np.asarray(x, dtype=float), 4)
    idx = np.asarray(rows, dtype=int) - 2
    idx = idx[(idx >= 0) & (idx < len(d4))]
    return float(_d4_sigma(d4[idx])) if len(idx) else math.nan


def require_length(samples: np.ndarray) -> None:
    """Refuse (ValueError) fewer than MIN_SAMPLES samples: the first thing to say of a record."""
    if len(samples) < MIN_SAMPLES:
        raise ValueError(f"need at least {MIN_SAMPLES} samples, got {len(samples)}")


def signals(samples: np.ndarray, h: float) -> Signals:
    """Noise levels and lightly smoothed ingredients of the (N, 5) samples ``ug, x1, x3, x4, x5``
    with period h [s]."""
    s = np.asarray(samples, dtype=float)
    if s.ndim != 2 or s.shape[1] != 5:
        raise ValueError(f"samples must be (N, 5): ug, x1, x3, x4, x5; got shape {s.shape}")
    require_length(s)
    if not np.all(np.isfinite(s)):
        raise ValueError(f"non-finite value in sample {int(np.argwhere(~np.isfinite(s))[0, 0])}")
    if not (h > 0 and math.isfinite(h)):
        raise ValueError(f"sample period must be > 0, got {h!r}")
    ug, x1, x3, x4, x5 = (s[:, i].copy() for i in range(5))
    # noise from the median of squared 4th differences (monitor.fourth_difference; the median
    # ignores transients)
    sigma = noise_levels(s)
    imp = np.zeros(4 * SG_WINDOW)
    imp[2 * SG_WINDOW] = 1.0
    gain = np.array([float(np.sqrt(np.sum(_sg(imp, k, h) ** 2))) for k in range(3)])
    gain_f = np.array([float(np.sqrt(np.sum(_sg(imp, k, h, FORCE_WINDOW) ** 2))) for k in range(3)])
    light = _sg(s[:, 1:], 0, h, SG_LIGHT)
    return Signals(h=h, ug=ug, x1=x1, x3=x3, x4=x4, x5=x5,
                   x1l=light[:, 0], vl=_sg(x1, 1, h, SG_LIGHT), x3l=light[:, 1], x4l=light[:, 2],
                   x5l=light[:, 3], vs=np.gradient(x1, h), v_noise=float(sigma[0] * gain_f[1]), sigma=sigma,
                   gain=gain, gain_f=gain_f)
