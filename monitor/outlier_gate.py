"""The identifier's outlier gate: sensor glitches (a sample, or on x1, x3 and x4 a pair of
samples, jumping away from both neighbours) are replaced before any filter sees them.

``gate_step`` is the streaming step (inlined into ``monitor.identify.identify_step``);
``gated`` runs it over a whole record for whole-record methods and plots.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .ident_options import IdentOptions, Kernels, new_state, reset_signals
from .layout import (
    H_GATE2,
    H_NOISE_N,
    N_CH,
    O_GATE,
    O_GATE_HAS,
    O_GATE_N,
    O_GATE_S,
    O_N,
    O_OUTLIERS,
    O_RING,
)

GATE_SETTLE = 50  # samples of the gate's scale estimate before it judges any sample


@njit(cache=True, error_model="numpy", inline="always")
def gate_step(st, hyper, ug, x1, x3, x4, x5, out):
    """Outlier gate with two samples of lookahead: hold the two newest arrivals, release the
    one before them.

    ``out`` gets the released sample (ug, x1, x3, x4, x5) with a glitched sensor value
    replaced. Returns False when nothing is released (the first two arrivals after a start
    or a gap). Per sensor, with L the last released value, g1 the sample being released,
    g2 the next one and r the arrival:

    * a lone glitch: g1 jumps away from both L and g2 (centred second difference above the
      threshold, both jumps of the same sign and large) -> the mean of L and g2;
    * a pair (x1, x3, x4 only: the spool's own overshoot lasts two samples): g1 and g2 sit
      together away from both L and r (each end jumps the same way by at least 3/4 of the
      departure, the two within 1/4 of it, L and r within 1/4 of it, the departure past the
      lone test's threshold) -> both on the line from L to r (g2 is replaced where it is
      held, and released as that at the next arrival).

    A step, a kink or a reversal does not jump away from both sides, so they pass.
    """
    has = st[O_GATE_HAS]
    if has < 2.0:
        o = O_GATE + N_CH if has > 0.0 else O_GATE
        st[o], st[o + 1], st[o + 2], st[o + 3], st[o + 4] = ug, x1, x3, x4, x5
        st[O_GATE_HAS] = has + 1.0
        return False
    for ch in range(N_CH):  # release g1; g2 moves to the first slot, the arrival to the second
        out[ch] = st[O_GATE + ch]
        st[O_GATE + ch] = st[O_GATE + N_CH + ch]
    o = O_GATE + N_CH
    st[o], st[o + 1], st[o + 2], st[o + 3], st[o + 4] = ug, x1, x3, x4, x5
    if st[O_N] < 1.0 or hyper[H_GATE2] <= 0.0:
        return True  # no left neighbour yet, or the gate is off
    cnt = st[O_GATE_N] + 1.0
    st[O_GATE_N] = cnt
    w = 1.0 / min(cnt, hyper[H_NOISE_N])
    for c in range(4):
        ch = c + 1
        left = st[O_RING + ch]  # the last released sample
        mid = out[ch]
        right = st[O_GATE + ch]
        a = mid - left
        b = mid - right
        d2 = -(a + b)
        v = d2 * d2
        cur = st[O_GATE_S + c]
        if cnt > GATE_SETTLE:
            if v > hyper[H_GATE2] * cur and a * b > 0.0 and min(abs(a), abs(b)) > 0.25 * abs(d2):
                out[ch] = 0.5 * (left + right)
                st[O_OUTLIERS + c] += 1.0
                continue  # a glitch does not count toward the scale
            if c < 3:  # x1, x3, x4 (not x5: the spool's own peaks last two samples)
                far = st[O_GATE + N_CH + ch]
                dev = 0.5 * (mid + right) - 0.5 * (left + far)  # the pair's departure from its ends
                pa = mid - left
                pb = right - far
                if dev * dev > hyper[H_GATE2] * cur and pa * dev > 0.0 and pb * dev > 0.0 \
                        and min(abs(pa), abs(pb)) > 0.75 * abs(dev) and abs(mid - right) < 0.25 * abs(dev) \
                        and abs(far - left) < 0.25 * abs(dev):
                    out[ch] = left + (far - left) / 3.0
                    st[O_GATE + ch] = left + 2.0 * (far - left) / 3.0
                    st[O_OUTLIERS + c] += 2.0
                    continue
            if v > 100.0 * cur:
                v = 100.0 * cur
        st[O_GATE_S + c] = cur + w * (v - cur)
    return True


@njit(cache=True, error_model="numpy")
def _gate_record(st, hyper, samples, out):
    s = np.empty(N_CH)
    k = 0
    for i in range(samples.shape[0]):
        if gate_step(st, hyper, samples[i, 0], samples[i, 1], samples[i, 2], samples[i, 3], samples[i, 4], s):
            out[k] = s
            k += 1
            for ch in range(N_CH):  # the released sample is the next one's left neighbour
                st[O_RING + ch] = s[ch]
            st[O_N] += 1.0
    # the samples the gate still holds, as it holds them (the second of a burst is replaced
    # where it is held, and counted, before it is released)
    h = int(st[O_GATE_HAS])
    for j in range(h):
        for ch in range(N_CH):
            out[samples.shape[0] - h + j, ch] = st[O_GATE + j * N_CH + ch]
    return k


def gated(samples: np.ndarray, options: IdentOptions | None = None,
          restarts=()) -> tuple[np.ndarray, np.ndarray]:
    """A record (N, 5) as the identifier sees it after its outlier gate, and the glitches
    replaced per sensor (x1, x3, x4, x5). The last two samples, which the gate still holds in
    a stream, come back as it holds them (unjudged, but the second of a burst replaced). For whole-record methods (``monitor.refine``) and plots that
    should see what the streaming estimates saw. ``restarts``: indices of samples that follow
    a gap, where the stream restarts its filters (``reset_signals``; the samples the gate
    held before the gap come back as it held them)."""
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != N_CH:
        raise ValueError(f"samples must be (N, {N_CH}) = (ug, x1, x3, x4, x5), got {samples.shape}")
    hyper = Kernels(options or IdentOptions(), 0.01).hyper  # the gate needs no sample period
    st = new_state(hyper)
    out = samples.copy()
    bounds = [0, *sorted({int(i) for i in restarts if 0 < i < len(samples)}), len(samples)]
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if lo:
            reset_signals(st)
        _gate_record(st, hyper, samples[lo:hi], out[lo:hi])
    return out, st[O_OUTLIERS:O_OUTLIERS + 4].copy()
