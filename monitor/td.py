"""Han's tracking differentiator (T-D), paper section 3.2, batched over rigs and channels.

For an input x(k) sampled every h [s] the T-D keeps mu1 (tracks x) and mu2 (tracks dx/dt):

    fh        = fhan(mu1(k) - x(k), mu2(k), r, h0)
    mu1(k+1)  = mu1(k) + h * mu2(k)
    mu2(k+1)  = mu2(k) + h * fh

fhan(g1, g2, r, h0), paper's symbols in brackets (iota = r h0, d = iota h0):

    d  = r h0            [iota]        d0 = d h0          [d]
    y  = g1 + h0 g2      [varsigma]    a0 = sqrt(d^2 + 8 r |y|)
    a  = g2 + (a0 - d)/2 sign(y)   if |y| > d0,   else g2 + y / h0          [sigma]
    fhan = -r sign(a)              if |a| > d,    else -r a / d

This is Han's fhan (Han 2009, "From PID to active disturbance rejection control", IEEE
TIE 56(3)) rescaled: Han's d = r h0^2 is our d0, his y is ours, his a is h0 times ours, and
sqrt(r h0^2 (r h0^2 + 8|y|)) = h0 a0, so both give the same fhan (pinned by a test). We keep
the paper's form. Units: g1 in the signal's unit [u], g2 [u/s], r [u/s^2], h0 and h [s]; in
the kernels r acts on x / scale, so it is in [1/s^2] and the SI acceleration limit is r scale.

Magnitude. fhan is homogeneous: fhan(S g1, S g2, S r, h0) = S fhan(g1, g2, r, h0), so the
paper's r = 100, h0 = 0.05 (tuned for signals of order 1) mean an acceleration limit of
100 [u/s^2]. On a pressure of 1e7 Pa that limit freezes the tracker (the trap, pinned by a
test). Every kernel therefore takes ``scale`` S [u]: it runs the T-D on x / S with the given
r and returns mu * S (state is kept in SI units; fh_SI = S fhan(g1/S, g2/S, r, h0)).

Lag. Near steady tracking fhan is on its linear band (|y| <= d0, |a| <= d) where
fh = -(mu1 - x)/h0^2 - 2 mu2/h0, independent of r: with c = h/h0 the outputs of ``update``
(the state after consuming x(k)) are, exactly,

    value(z)/x(z) = z c^2 / (z - 1 + c)^2,   derivative = (value(k+1) - value(k)) / h,

a critically damped low-pass with its double pole at 1/h0 [rad/s]. At low frequency the value
lags 2 h0/h - 1 samples and the derivative lags the true derivative by 2 h0/h - 1.5 samples.
Measured by ``td_lag`` for the paper's r = 100, h0 = 0.05, h = 0.01 (unit amplitude, scale 1):

    f [Hz]  value lag  deriv lag  gain      (same gain for value and derivative, to 1e-3)
    0.1     9.00       8.50       0.999
    0.5     8.94       8.44       0.981
    1.0     8.97       8.47       0.923     (amplitude 0.1: 8.77 / 8.27 / 0.927, linear)
    2.0     10.54      10.04      0.704     (amplitude 0.1: 8.20 / 7.70 / 0.760, linear)

so the paper's "first derivative one sample back, second two" is far off for h0 = 0.05: a
second T-D on the derivative adds another ~8.5 samples (17 in all for the second derivative).
The band stays linear while the normalised slope A w / S stays below about r h0 (5 [1/s] for
the paper; 5.7 at 2 Hz); past that fhan saturates, lag grows and harmonics appear.
Choosing S = the sensor span (``config_scales``) keeps the paper's signals linear.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["fhan", "td_step", "td_step_batch", "td_filter", "TrackingDifferentiator", "td_lag", "TDLag",
           "config_scales"]


@njit(cache=True)
def fhan(g1: float, g2: float, r: float, h0: float) -> float:
    """Han's time-optimal synthesis function (paper section 3.2), [u/s^2] for r in [u/s^2]."""
    d = r * h0
    d0 = d * h0
    y = g1 + h0 * g2
    if abs(y) > d0:
        a = g2 + 0.5 * (math.sqrt(d * d + 8.0 * r * abs(y)) - d) * math.copysign(1.0, y)
    else:
        a = g2 + y / h0
    if abs(a) > d:
        return -r * math.copysign(1.0, a)
    return -r * a / d


@njit(cache=True)
def _advance(m1: float, m2: float, x: float, r: float, h0: float, h: float, scale: float):
    # fh = S fhan((mu1 - x)/S, mu2/S, r, h0);  mu1 += h mu2;  mu2 += h fh
    fh = scale * fhan((m1 - x) / scale, m2 / scale, r, h0)
    return m1 + h * m2, m2 + h * fh


@njit(cache=True)
def td_step(mu: np.ndarray, x: float, r: float, h0: float, h: float, scale: float) -> None:
    """Advance one T-D by one sample, in place.

    mu : array (2,), [value [u], derivative [u/s]]; x : sample [u]; r [1/s^2] (on x/scale);
    h0, h [s]; scale [u].
    """
    mu[0], mu[1] = _advance(mu[0], mu[1], x, r, h0, h, scale)


@njit(cache=True)
def td_step_batch(mu: np.ndarray, x: np.ndarray, r: np.ndarray, h0: np.ndarray, h: float,
                  scale: np.ndarray) -> None:
    """Advance every rig and channel by one sample, in place.

    mu : (n_rigs, n_channels, 2); x : (n_rigs, n_channels); r, h0, scale : (n_channels,).
    """
    for i in range(mu.shape[0]):
        for j in range(mu.shape[1]):
            mu[i, j, 0], mu[i, j, 1] = _advance(mu[i, j, 0], mu[i, j, 1], x[i, j], r[j], h0[j], h, scale[j])


@njit(cache=True)
def td_filter(x: np.ndarray, r: float, h0: float, h: float, scale: float) -> np.ndarray:
    """Run one T-D over a whole series (offline path), starting at x[0] with zero derivative.

    Returns (n, 2): row k is the state after consuming x[k], as ``update`` returns it.
    """
    out = np.empty((x.shape[0], 2))
    m1, m2 = x[0], 0.0
    for k in range(x.shape[0]):
        m1, m2 = _advance(m1, m2, x[k], r, h0, h, scale)
        out[k, 0], out[k, 1] = m1, m2
    return out


def _per_channel(name: str, v, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape not in ((), (n,)):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {v!r}")
    a = np.array(np.broadcast_to(a, (n,)))  # own copy
    if not np.all(np.isfinite(a) & (a > 0)):
        raise ValueError(f"{name} must be finite and > 0 for every channel, got {v!r}")
    return a


class TrackingDifferentiator:
    """Streaming T-D bank for one rig: ``update(x) -> (value [u], derivative [u/s])`` per channel.

    Parameters
    ----------
    r : float or array (n_channels,)
        Acceleration limit on the normalised signal x / scale [1/s^2] (paper: 100).
    h0 : float or array (n_channels,)
        Filter factor [s], >= h (paper: 0.05); small-signal bandwidth 1/h0 [rad/s].
    h : float
        Sample period [s] (paper: 0.01).
    scale : float or array (n_channels,)
        Magnitude of each channel [u] (e.g. the sensor span); see ``config_scales``.
    n_channels : int
        Number of signals tracked together.

    The first ``update`` (after construction or ``reset()``) starts tracking at that sample
    with zero derivative, so there is no start-up transient from 0.
    """

    def __init__(self, r=100.0, h0=0.05, h=0.01, scale=1.0, n_channels=1):
        if int(n_channels) != n_channels or n_channels < 1:
            raise ValueError(f"n_channels must be a positive integer, got {n_channels!r}")
        if not (math.isfinite(h) and h > 0):
            raise ValueError(f"h must be finite and > 0 [s], got {h!r}")
        self.r, self.h0, self.h, self.scale, self.n_channels = r, h0, h, scale, int(n_channels)
        self._r = _per_channel("r", r, self.n_channels)
        self._h0 = _per_channel("h0", h0, self.n_channels)
        self._scale = _per_channel("scale", scale, self.n_channels)
        if np.any(self._h0 < h):
            raise ValueError(f"h0 must be >= h = {h!r} s (else the T-D rings or diverges), got {h0!r}")
        self.state = np.zeros((1, self.n_channels, 2))  # [rig, channel, (value, derivative)]
        self.initialised = False

    def _check(self, x) -> np.ndarray:
        a = np.asarray(x, dtype=np.float64)
        if a.ndim == 0:
            a = np.full(self.n_channels, float(a))
        if a.shape != (self.n_channels,):
            raise ValueError(f"x must have shape ({self.n_channels},), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"x must be finite, got {x!r}")
        return a

    def reset(self, x=None) -> None:
        """Forget the state; with x, start tracking at x [u] with zero derivative."""
        start = None if x is None else self._check(x)  # validate before touching the state
        self.state[:] = 0.0
        self.initialised = start is not None
        if start is not None:
            self.state[0, :, 0] = start

    def update(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Consume one sample x [u] (scalar or (n_channels,)); return (value [u], derivative [u/s])."""
        a = self._check(x)
        if not self.initialised:
            self.reset(a)
        td_step_batch(self.state, a[None, :], self._r, self._h0, self.h, self._scale)
        return self.state[0, :, 0].copy(), self.state[0, :, 1].copy()


class TDLag(NamedTuple):
    """Fitted response of a T-D to a sine: lags in samples, gains as fractions."""

    value_lag: float
    derivative_lag: float
    value_gain: float
    derivative_gain: float


def td_lag(r: float, h0: float, h: float, freq: float, amplitude: float = 1.0, scale: float = 1.0) -> TDLag:
    """Effective delay [samples] and gain of ``update``'s outputs for x = amplitude sin(2 pi freq t).

    Simulates the T-D (``td_filter``), drops the start-up (at least 1000 samples and one
    period), fits offset + sine at ``freq`` by least squares over at least two whole periods,
    and compares with x and dx/dt. freq [Hz], amplitude and scale [u]. Pure and deterministic.
    """
    if not (freq > 0 and math.isfinite(freq) and freq < 0.5 / h):
        raise ValueError(f"freq must be in (0, Nyquist = {0.5 / h}) Hz, got {freq!r}")
    per = 1.0 / (freq * h)  # samples per period
    settle = int(max(1000, math.ceil(per)))
    nfit = int(round(max(2.0, math.ceil(500.0 / per)) * per))
    t = np.arange(settle + nfit) * h
    w = 2.0 * math.pi * freq
    out = td_filter(amplitude * np.sin(w * t), r, h0, h, scale)[settle:]
    m = np.column_stack([np.sin(w * t[settle:]), np.cos(w * t[settle:]), np.ones(nfit)])
    coef = np.linalg.lstsq(m, out, rcond=None)[0]  # (3, 2): columns value, derivative
    gain = np.hypot(coef[0], coef[1])
    phase = np.arctan2(coef[1], coef[0]) - np.array([0.0, 0.5 * math.pi])  # vs sin, cos
    lag = np.mod(-phase / (w * h) + 0.5 * per, per) - 0.5 * per
    return TDLag(float(lag[0]), float(lag[1]), float(gain[0] / amplitude), float(gain[1] / (amplitude * w)))


def config_scales(config, omega: float = 2.0 * math.pi * 2.5) -> dict[str, float]:
    """Per-channel T-D scale [SI] from a ``hydromon.contract.RigConfig``'s sensor spans.

    x1 [m], x3/x4 [Pa], x5 [m] use the spans; the second-stage T-Ds on the derivatives
    x2 [m/s] and x6 [m/s] use span * omega, omega [rad/s] the fastest tracked motion
    (default 2.5 Hz, the paper's section 4.2 input).
    """
    return {"x1": config.x1_span, "x3": config.p_span, "x4": config.p_span, "x5": config.x5_span,
            "x2": config.x1_span * omega, "x6": config.x5_span * omega}
