"""Readings that stopped changing, watched sample by sample: a rig whose five channels repeat one
reading for ``FROZEN_S`` seconds says ``bad-input`` and is warned of, once per freeze.

An acquisition that stalls and keeps re-sending its last reading (its seq still counting) is not
silent, so the silence watch does not see it, and its estimates, which learn nothing from a
reading that does not change, would go on saying ``ok`` with the grade they had. Real sensors
flicker by at least their resolution, and a simulated rig without noise never repeats all five
channels from one sample to the next (steps, sines, multisines at every health band), so a repeat
of every channel for ``FROZEN_S`` is a stall, not a rig at rest.

A mixin of :class:`hydromon.engine.core.MonitorCore`: ``_same`` (samples in a row equal to the one
before, every channel), ``_watched`` (samples seen) and ``_frozen_from`` (where the freeze last
warned of began) are rows of its ``ROW_STATE``; ``_prev`` holds each row's last sample. Not saved
in a checkpoint: a restored rig that is still frozen says so again after ``FROZEN_S`` seconds of
its samples.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FROZEN_S", "FrozenWatch", "frozen_words", "repeats_in"]

FROZEN_S = 2.0  # [s] every channel repeating its reading this long is a stalled acquisition


def repeats_in(seconds: float, sample_rate: float) -> int:
    """Repeats in a row [samples] that hold a reading for ``seconds`` [s] at ``sample_rate`` [Hz]
    (at least 2); the frozen and the stuck-pressure watch count their stretches so."""
    return max(2, int(round(seconds * sample_rate)))


def frozen_words(samples: np.ndarray, sample_rate: float) -> str | None:
    """Why a whole record's readings are not to be trusted when its five channels (``samples``
    (N, 5): ug, x1, x3, x4, x5, SI) repeat one reading for ``FROZEN_S`` seconds or more in a row
    (what the live monitor flags), else None. ``sample_rate`` [Hz]."""
    s = np.asarray(samples, dtype=float)
    if len(s) < 2:
        return None
    same = np.all(s[1:] == s[:-1], axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], same.astype(np.int8), [0]])))
    starts, ends = edges[::2], edges[1::2]  # runs of repeats: samples starts+1 .. ends repeat the one before
    if not len(starts):
        return None
    k = int(np.argmax(ends - starts))
    run = int(ends[k] - starts[k])
    if run < repeats_in(FROZEN_S, sample_rate):
        return None
    return (f"ug, x1, x3, x4 and x5 repeat one reading for {run / sample_rate:g} s from sample {int(starts[k])}: a "
            "stalled acquisition re-sending its last reading, or a record made up of one sample? The estimates "
            "learn nothing from readings that do not change")


class FrozenWatch:
    """MonitorCore's watch over readings that stopped changing (a mixin)."""

    _prev: np.ndarray  # (rows, 5): each row's last sample (ug, x1, x3, x4, x5); NaN: none yet

    def _frozen_flagged(self, rows: np.ndarray, vals: np.ndarray, ev) -> None:
        """Before the health of a batch: the evaluations of ``ev`` at which their rig's readings
        have repeated for ``FROZEN_S`` say ``bad-input``; a rig is warned of once a freeze
        (``rows`` (m,), ``vals`` (m, 6): t, ug, x1, x3, x4, x5, the batch's samples in order)."""
        order = np.argsort(rows, kind="stable")
        r_s, v_s = rows[order], vals[order, 1:]
        first = np.ones(len(r_s), dtype=np.bool_)
        first[1:] = r_s[1:] != r_s[:-1]
        before = np.empty_like(v_s)
        before[1:] = v_s[:-1]
        before[first] = self._prev[r_s[first]]
        same = np.all(v_s == before, axis=1)
        last = np.ones(len(r_s), dtype=np.bool_)
        last[:-1] = r_s[1:] != r_s[:-1]
        if not same.any():  # the common case: no sample repeats its row's last one
            rl = r_s[last]
            self._watched[rl] += np.flatnonzero(last) - np.flatnonzero(first) + 1
            self._same[rl] = 0
            self._prev[rl] = v_s[last]
            return
        # run of repeats ending at each sample: the row's run carried into its first sample
        pos = np.arange(len(r_s))
        start = np.maximum.accumulate(np.where(~same | first, pos, 0))
        carry = np.where(same[start] & first[start], self._same[r_s[start]], 0)
        run = pos - start + same[start] + carry
        # each sample's place among its row's samples ever seen, so a freeze is known by where it began
        index = self._watched[r_s] + pos - np.maximum.accumulate(np.where(first, pos, 0))
        self._watched[r_s[last]] = index[last] + 1
        self._same[r_s[last]] = run[last]
        self._prev[r_s[last]] = v_s[last]
        need = repeats_in(FROZEN_S, self.fleet.sample_rate)
        if not len(ev) or run.max(initial=0) < need:
            return
        at = np.empty(len(r_s), dtype=np.int64)
        at[order] = np.arange(len(r_s))  # batch index -> sorted position
        p_ev = at[ev.sample]
        frozen = run[p_ev] >= need
        began = (index - run)[p_ev]
        for i, r, b in zip(ev.sample[frozen].tolist(), ev.rig[frozen].tolist(), began[frozen].tolist()):
            self._b_status[i] = "bad-input"
            if self._frozen_from[r] != b:  # a freeze not warned of yet
                self._frozen_from[r] = b
                if self.on_warning is not None:
                    self.on_warning(self.fleet.ids[r], f"ug, x1, x3, x4 and x5 have repeated one reading for "
                                                       f"{need / self.fleet.sample_rate:g} s: a stalled acquisition "
                                                       "re-sending its last reading? Its health says bad-input "
                                                       "until they change")
