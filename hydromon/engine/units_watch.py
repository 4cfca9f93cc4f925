"""Readings a rig's config cannot hold, watched sample by sample (``monitor.readings``): a rig
whose samples keep breaking its config's bounds says ``bad-input`` and is warned of once.

A spool logged in 0.01 mm or pressures with their sign turned fit the model with the units in
the parameters, and their estimates grade as the right record's would (``health``). Each sample is
held against its rig's bounds: |x1| and |x5| at most 10 times their sensors' spans, the
pressures at most 10 times p_span and at least -10 % of p_s
(``monitor.readings.sample_limits``). An evaluation whose window (the rig's samples since its
previous one) holds more than ``GLITCH_SAMPLES`` samples beyond them says ``bad-input``: one or
two are a glitch, which the outlier gate mends, wherever they come in a long run. From the
``UNITS_WINDOWS``-th such evaluation on, every one says it until the rig's estimates restart (a
new config, a seq restart): a spool in 0.01 mm passes 10 mm only where it opens wide, and its
health would otherwise say ``ok`` between. The windows are the evaluations' own, so the health
does not depend on how messages were batched. ``evaluate`` also tells pressures that never reach
5 % of p_s (bar, MPa, psi), which takes a whole record; the estimates' plausibility
(``monitor.plausibility``) tells those live.

A mixin of :class:`hydromon.engine.core.MonitorCore`: ``_units`` (samples beyond since the rig's
latest evaluation), ``_units_windows`` (evaluations that found more than GLITCH_SAMPLES) and
``_units_warned`` (once per (re)start of its estimates) are rows of its ``ROW_STATE``; the
bounds, ``_limits``, follow each rig's config. The three rows are saved in a checkpoint
(``hydromon.engine.checkpoint``): a restored rig whose slip was established says so from its
first evaluation, as one that ran on through the same gap does.
"""

from __future__ import annotations

import numpy as np

from hydromon.contract import RigConfig
from monitor.readings import GLITCH_SAMPLES, beyond, sample_limits, unit_slip

__all__ = ["UNITS_WINDOWS", "UnitsWatch"]

UNITS_WINDOWS = 3  # evaluations with more than GLITCH_SAMPLES beyond that make it a slip, not a sensor's dropout

_DEFAULT = sample_limits(RigConfig())


class UnitsWatch:
    """MonitorCore's watch over readings its rigs' configs cannot hold (a mixin)."""

    _limits: np.ndarray  # (rows, 4): each row's bounds (``monitor.readings.sample_limits``)
    _tight: np.ndarray  # (4,): the tightest of every bound any row was given (a batch within them is fine)
    _units_live: bool  # some row has samples beyond counted, or a slip established

    def units_flagged(self) -> dict[str, int]:
        """The rigs whose evaluations found more than GLITCH_SAMPLES samples beyond their config's
        bounds since their estimates (re)started, with how many such evaluations, by rig id."""
        return {rig_id: int(self._units_windows[r.row]) for rig_id, r in sorted(self.rigs.items())
                if self._units_windows[r.row]}

    def _set_limits(self, row: int, config: RigConfig | None) -> None:
        """Row ``row`` is held against ``config``'s bounds (None: the reference rig's)."""
        if row >= len(self._limits):
            grow = max(row + 1 - len(self._limits), len(self._limits))
            self._limits = np.concatenate([self._limits, np.tile(_DEFAULT, (grow, 1))])
        lim = self._limits[row] = _DEFAULT if config is None else sample_limits(config)
        self._tight = np.array([min(self._tight[0], lim[0]), min(self._tight[1], lim[1]),
                                min(self._tight[2], lim[2]), max(self._tight[3], lim[3])])

    def _refresh_units_live(self) -> None:
        """Whether any row needs its samples held to its own bounds (also after a checkpoint set the rows)."""
        self._units_live = bool(self._units.any() or (self._units_windows >= UNITS_WINDOWS).any())

    def _within_tightest(self, vals: np.ndarray) -> bool:
        """Every sample of ``vals`` (m, 6: t, ug, x1, x3, x4, x5) within the tightest bounds: the
        common case, told without taking each sample's own (a replay of 300,000 samples a second
        lost 7-9 % to that)."""
        t = self._tight
        x1, x5, p = vals[:, 2], vals[:, 5], vals[:, 3:5]
        return bool(x1.max() <= t[0] and -x1.min() <= t[0] and x5.max() <= t[1] and -x5.min() <= t[1]
                    and p.max() <= t[2] and p.min() >= t[3])

    def _units_flagged(self, rows: np.ndarray, vals: np.ndarray, ev) -> None:
        """Before the health of a batch: the evaluations of ``ev`` that say ``bad-input`` for
        readings beyond the rig's bounds (module docstring), counted in the order of the rig's
        samples; a rig is warned of at its first (``rows`` (m,), ``vals`` (m, 6): t, ug, x1, x3,
        x4, x5, the batch's samples in order)."""
        if not self._units_live and self._within_tightest(vals):
            return
        idx = np.flatnonzero(beyond(vals[:, 1:], self._limits[rows]))
        brow = rows[idx]
        ev_rig, ev_sample = (ev.rig, ev.sample) if len(ev) else (np.zeros(0, np.int64), np.zeros(0, np.int64))
        # evaluated now, with samples beyond from an earlier batch or a slip already established
        carried = ev_rig[(self._units[ev_rig] > 0) | (self._units_windows[ev_rig] >= UNITS_WINDOWS)]
        if not len(idx) and not len(carried):
            self._refresh_units_live()
            return
        for r in np.union1d(brow, carried).tolist():
            mine = idx[brow == r]  # this rig's samples beyond, in batch order
            ends = ev_sample[ev_rig == r]  # its evaluations' samples, in batch order
            counts = np.diff(np.searchsorted(mine, ends, side="right"), prepend=0)
            if len(counts):
                counts[0] += self._units[r]  # beyond since its evaluation in an earlier batch
            flagged = False
            for i, n in zip(ends.tolist(), counts.tolist()):
                if n > GLITCH_SAMPLES:
                    self._units_windows[r] += 1
                if n > GLITCH_SAMPLES or self._units_windows[r] >= UNITS_WINDOWS:
                    self._b_status[i] = "bad-input"
                    flagged = True
            self._units[r] = (len(mine) - np.searchsorted(mine, ends[-1], side="right") if len(ends)
                              else self._units[r] + len(mine))
            if self.on_warning is not None and flagged and not self._units_warned[r] and len(mine):
                self._units_warned[r] = True
                rig_id = self.fleet.ids[r]
                words = unit_slip(vals[mine[0]:mine[0] + 1, 1:], self.rigs[rig_id].config or RigConfig(), record=False)
                self.on_warning(rig_id, f"{words}; its health says bad-input while its evaluations find more than "
                                        f"{GLITCH_SAMPLES} such samples, and from the {UNITS_WINDOWS}th such "
                                        "evaluation until its estimates restart")
        self._refresh_units_live()
