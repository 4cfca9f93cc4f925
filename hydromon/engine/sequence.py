"""A rig's sequence numbers: which samples to take, and what a jump or a step back means.

One rule, used live (``hydromon.engine.core.MonitorCore``, one message at a time) and offline
(``hydromon.store.recording``, a whole record at once), so a recording is graded as the live
monitor took its stream:

* a seq one past the last taken is taken (``TAKE``); a seq further ahead is taken after a gap
  (``GAP``: the rig's filters restart, its estimates carry on);
* a seq equal to the last taken is a ``DUPLICATE``, a lower one ``OUT_OF_ORDER``: dropped;
* seq 0 after a higher seq is the rig restarting (``RESTART``: its estimates restart). A rig
  that restarted while its first samples were lost (a peer that reconnects after the restart)
  never shows seq 0: once ``RESTART_RUN`` samples in a row have come below the last seq taken,
  each above the one before, the last of that run is taken as the restart too (the run's
  earlier samples were dropped as out of order). A lone sample that goes back (a second
  publisher under the same rig id) never makes such a run.
"""

from __future__ import annotations

import numpy as np

from hydromon.contract import RESTART_RUN

__all__ = ["TAKE", "GAP", "DUPLICATE", "OUT_OF_ORDER", "RESTART", "TAKEN", "sequence_step", "sequence_verdicts"]

TAKE, GAP, DUPLICATE, OUT_OF_ORDER, RESTART = range(5)
TAKEN = (TAKE, GAP, RESTART)
"""The verdicts whose sample is taken (and becomes the rig's last seq)."""


def sequence_step(last: int, back_n: int, back_seq: int, seq: int) -> tuple[int, int, int]:
    """``(verdict, back_n, back_seq)`` for sample ``seq`` of a rig whose last taken seq is
    ``last`` (-1: none yet), after ``back_n`` samples in a row below it, the last of them
    ``back_seq``. A taken sample (``TAKEN``) becomes the rig's ``last``."""
    if last < 0 or seq > last:
        return (GAP if last >= 0 and seq > last + 1 else TAKE), 0, back_seq
    if seq < last and seq != 0:  # going back: a run of these is a restart whose seq 0 was lost
        back_n, back_seq = (back_n + 1 if 0 < back_n and back_seq < seq else 1), seq
    if seq == 0 and last > 0 or seq != last and back_n >= RESTART_RUN:
        return RESTART, 0, back_seq
    return (DUPLICATE if seq == last else OUT_OF_ORDER), back_n, back_seq


def sequence_verdicts(seq: np.ndarray) -> np.ndarray:
    """The verdict of every sample of a rig's stream ``seq`` (int, in arrival order), int8."""
    out = np.empty(len(seq), dtype=np.int8)
    last, back_n, back_seq = -1, 0, -1
    for i, s in enumerate(np.asarray(seq).tolist()):
        v, back_n, back_seq = sequence_step(last, back_n, back_seq, s)
        if v in TAKEN:
            last = s
        out[i] = v
    return out
