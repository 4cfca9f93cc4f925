"""A chamber pressure that stopped changing while the spool moves: a dead or stuck pressure
sensor. The rig's health says ``bad-input`` while it lasts, and the rig is warned of once per
stuck stretch.

A transducer whose wire broke reads one value, and a fieldbus that lost it repeats its last
one, while the other channels go on. The frozen watch (``hydromon.engine.frozen_watch``) needs
all five channels to repeat, and the estimates fit the stuck pressure as they can: a healthy
rig's 30 s record whose x3 read one value for its last 20 s was graded ``health``, ``ok``. The
rule: x3 or x4 repeats one reading for ``STUCK_S`` seconds while x5 travels more than
``SPOOL_MOVES`` of its span (10 um on the default 1 mm span) over those samples. Real pressure
sensors flicker by their resolution; a rig at rest may hold a coarse one's reading, hence the
moving spool; and a piston moving at one speed under one load holds its pressures within the
force of its acceleration (1.5 kPa for 124 kg at 0.1 m/s^2 on 80 cm^2, under a 12-bit
transducer's 10 kPa step over 40 MPa), hence the long ``STUCK_S``. docs/limits.md gives how
coarse a grid it stands (``benchmarks/stuck_scan.py``).

A mixin of :class:`hydromon.engine.core.MonitorCore`: ``_run3``, ``_run4`` (samples in a row
repeating the pressure before), ``_lo3`` .. ``_hi4`` (the spool's extremes over those samples)
and ``_stuck_from3``, ``_stuck_from4`` (where each channel's stuck stretch last warned of
began, counted in ``_watched``) are
rows of its ``ROW_STATE``; it reads each row's last sample in ``_prev`` before the frozen watch
moves it on. Not saved in a checkpoint. ``stuck_words`` says the same of a whole record.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from hydromon.engine.frozen_watch import repeats_in
from monitor.audit.wiring import SPOOL_MOVES
from monitor.readings import RANGE

__all__ = ["STUCK_S", "StuckWatch", "stuck_runs", "stuck_words"]

STUCK_S = 10.0  # [s] a chamber pressure repeating its reading this long under a moving spool is stuck


@njit(cache=True)
def stuck_runs(rows, p3, p4, x5, prev3, prev4, run3, run4, lo3, hi3, lo4, hi4, moves, need, seen):
    """Sample by sample, in the order taken: where the stuck stretch of its row's x3 and of its
    x4 that each sample ends began (module docstring), -1 where none.

    ``rows`` (m,) the samples' rows; ``p3``, ``p4`` [Pa] and ``x5`` [m] (m,) their readings;
    per row, updated in place: ``prev3``, ``prev4`` the last pressures [Pa] (NaN: none),
    ``run3``, ``run4`` the repeats in a row, ``lo3`` .. ``hi4`` the spool's extremes [m] since
    each run began; ``moves`` [m] per row the spool travel that makes a held pressure stuck;
    ``need`` the repeats that do; ``seen`` per row the samples before this batch (a stretch's
    start is counted in them). Every per-row array holds every row of ``rows``. Returns
    ``(began3 (m,), began4 (m,))``, int64."""
    m = len(rows)
    began3 = np.full(m, -1, dtype=np.int64)
    began4 = np.full(m, -1, dtype=np.int64)
    count = np.zeros(len(prev3), dtype=np.int64)
    for i in range(m):
        r = rows[i]
        at = seen[r] + count[r]
        count[r] += 1
        began3[i] = _held(p3[i], x5[i], r, at, prev3, run3, lo3, hi3, moves[r], need)
        began4[i] = _held(p4[i], x5[i], r, at, prev4, run4, lo4, hi4, moves[r], need)
    return began3, began4


@njit(cache=True, inline="always")
def _held(p, v, r, at, prev, run, lo, hi, moves, need):
    """One pressure reading ``p`` [Pa] of row ``r`` under spool ``v`` [m], its ``at``-th sample:
    its run and the spool's extremes moved on (in place); where its stuck stretch began, or -1."""
    if p == prev[r]:
        run[r] += 1
        lo[r] = min(lo[r], v)
        hi[r] = max(hi[r], v)
    else:
        run[r], lo[r], hi[r] = 0, v, v
    prev[r] = p
    return at - run[r] if run[r] >= need and hi[r] - lo[r] > moves else -1


def _one_row_runs(s: np.ndarray, moves: float, need: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`stuck_runs` over one record (``s`` (N, 5): ug, x1, x3, x4, x5 [SI]) from a fresh state."""
    fresh = [np.full(1, np.nan), np.full(1, np.nan), np.zeros(1, np.int64), np.zeros(1, np.int64),
             np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)]
    return stuck_runs(np.zeros(len(s), np.int64), s[:, 2], s[:, 3], s[:, 4], *fresh, np.full(1, moves), need,
                      np.zeros(1, np.int64))


def stuck_words(samples: np.ndarray, sample_rate: float, x5_span: float) -> str | None:
    """Why a whole record's pressures cannot be trusted when x3 or x4 holds one reading for
    ``STUCK_S`` under a moving spool (what the live monitor flags), naming the first such
    stretch; else None. A pressure that reads one value throughout is left to the wiring check
    (``monitor.audit.wiring``), which names it dead. ``samples`` (N, 5): ug, x1, x3, x4, x5
    [SI]; ``sample_rate`` [Hz]; ``x5_span`` [m] the spool sensor's span."""
    s = np.asarray(samples, dtype=float)
    if len(s) < 2:
        return None
    began = _one_row_runs(s, SPOOL_MOVES * x5_span, repeats_in(STUCK_S, sample_rate))
    found = []
    for k, b in zip((3, 4), began):
        col, hit = k - 1, np.flatnonzero(b >= 0)  # x3, x4 are columns 2, 3
        if len(hit) and np.ptp(s[:, col]) > 0.0:
            found.append((int(b[hit[0]]), k, col))
    if not found:
        return None
    start, k, col = min(found)
    end = start + 1
    while end < len(s) and s[end, col] == s[start, col]:
        end += 1
    return (f"x{k} reads {s[start, col]:.6g} Pa for {(end - start) / sample_rate:g} s from sample {start} while the "
            f"spool moves {1e3 * np.ptp(s[start:end, 4]):.3g} mm: a dead or stuck pressure sensor? The estimates fit "
            "a pressure that does not follow the rig")


class StuckWatch:
    """MonitorCore's watch over a chamber pressure that stopped changing (a mixin)."""

    def _stuck_flagged(self, rows: np.ndarray, vals: np.ndarray, ev) -> None:
        """Before the frozen watch and the health of a batch: the evaluations of ``ev`` whose
        rig's x3 or x4 is stuck say ``bad-input``; a rig is warned of once a stuck stretch
        (``rows`` (m,), ``vals`` (m, 6): t, ug, x1, x3, x4, x5, the batch's samples in order)."""
        n_rows = len(self._run3)
        prev3, prev4 = self._prev[:, 2].copy(), self._prev[:, 3].copy()  # the frozen watch moves _prev on
        moves = np.full(n_rows, np.inf)  # [m] per row; rows without a rig yet hold nothing
        known = min(n_rows, len(self._limits))
        moves[:known] = SPOOL_MOVES * self._limits[:known, 1] / RANGE  # the limits hold RANGE x5 spans
        need = repeats_in(STUCK_S, self.fleet.sample_rate)
        began = stuck_runs(rows, vals[:, 3], vals[:, 4], vals[:, 5], prev3, prev4, self._run3, self._run4,
                           self._lo3, self._hi3, self._lo4, self._hi4, moves, need, self._watched)
        if not len(ev) or (began[0].max(initial=-1) < 0 and began[1].max(initial=-1) < 0):
            return
        for k, b, warned in zip((3, 4), began, (self._stuck_from3, self._stuck_from4)):
            at = b[ev.sample]
            for i, r, start in zip(ev.sample[at >= 0].tolist(), ev.rig[at >= 0].tolist(), at[at >= 0].tolist()):
                self._b_status[i] = "bad-input"
                if warned[r] != start:  # a stretch of this channel not warned of yet
                    warned[r] = start
                    if self.on_warning is not None:
                        self.on_warning(self.fleet.ids[r], f"x{k} has read {vals[i, k]:.6g} Pa for {STUCK_S:g} s or "
                                                           "more while the spool moved: a dead or stuck pressure "
                                                           "sensor? Its health says bad-input until it changes")
