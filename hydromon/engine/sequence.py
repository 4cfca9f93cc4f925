"""A rig's sequence numbers: which samples to take, in which order, and what a jump or a step
back means.

One rule, used live (``hydromon.engine.core.MonitorCore``, one message at a time) and offline
(``hydromon.store.recording``, a whole record at once), so a recording is graded as the live
monitor took its stream:

* a seq one past the last taken is taken (``TAKE``); a seq further ahead is taken after a gap
  (``GAP``: the rig's filters restart, its estimates carry on);
* a seq up to :data:`REORDER` + 1 ahead is held back until the samples before it arrive (a swap
  of neighbours on the network is put back in order), or until it is clear they are lost (then
  it is taken after a gap);
* a seq more than :data:`FAR` ahead is held back too, and taken only once :data:`CONFIRM`
  samples in a row have followed it: a lone sample far ahead (a corrupt or forged seq) is
  dropped (``AHEAD``) and changes nothing, while a rig that really jumped (it kept counting
  through a long outage) loses nothing;
* a seq equal to the last taken is a ``DUPLICATE``, a lower one ``OUT_OF_ORDER``: dropped;
* seq 0 after a higher seq is the rig restarting (``RESTART``: its estimates restart). A rig
  that restarted while its first samples were lost (a peer that reconnects after the restart)
  never shows seq 0: once ``RESTART_RUN`` samples in a row have come below the last seq taken,
  each above the one before, the last of that run is taken as the restart too (the run's
  earlier samples were dropped as out of order). A lone sample that goes back (a second
  publisher under the same rig id) never makes such a run.

:func:`sequence_push` is the rule: a rig's state and one arriving sample in; the samples to take
now (in order, each with its verdict) and the ones dropped out. A sample is carried as an opaque
token (a payload live, an index offline).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from operator import itemgetter

import numpy as np

from hydromon.contract import RESTART_RUN

__all__ = [
    "AHEAD",
    "CONFIRM",
    "DUPLICATE",
    "FAR",
    "GAP",
    "OUT_OF_ORDER",
    "REORDER",
    "RESTART",
    "TAKE",
    "TAKEN",
    "SeqState",
    "sequence_order",
    "sequence_push",
]

TAKE, GAP, DUPLICATE, OUT_OF_ORDER, RESTART, AHEAD = range(6)
TAKEN = (TAKE, GAP, RESTART)
"""The verdicts whose sample is taken (and becomes the rig's last seq)."""
REORDER = 2
"""Samples that may go missing ahead of an arrival before it is taken after a gap: a hole of up to
this many is waited for (two neighbours swapped: a hole of one)."""
FAR = 1000
"""A jump of more than this many samples ahead (10 s at 100 Hz) is held until confirmed."""
CONFIRM = 10
"""Samples in a row that confirm a far jump."""
_SEQ = itemgetter(0)


@dataclass
class SeqState:
    """One rig's sequence state: the last seq taken (-1: none yet), the run of samples below it
    (a restart?), and the samples held back, ``(seq, token)`` in seq order (``far``: held for a
    far jump's confirmation, else waiting for a hole to fill)."""

    last: int = -1
    back_n: int = 0
    back_seq: int = -1
    held: list = field(default_factory=list)
    far: bool = False


def _back(st: SeqState, seq: int, token, out: list, dropped: list) -> None:
    """A seq at or below the last taken: a restart, a duplicate or out of order."""
    last = st.last
    if seq < last and seq != 0:  # going back: a run of these is a restart whose seq 0 was lost
        st.back_n, st.back_seq = (st.back_n + 1 if 0 < st.back_n and st.back_seq < seq else 1), seq
    if seq == 0 and last > 0 or seq != last and st.back_n >= RESTART_RUN:
        st.last, st.back_n = seq, 0
        out.append((RESTART, seq, token))
    else:
        dropped.append((DUPLICATE if seq == last else OUT_OF_ORDER, seq, token))


def _take(st: SeqState, seq: int, token, out: list) -> None:
    out.append((GAP if st.last >= 0 and seq > st.last + 1 else TAKE, seq, token))
    st.last, st.back_n = seq, 0


def _release(st: SeqState, out: list) -> None:
    """The held samples, in order (the first after a gap when the hole never filled)."""
    held, st.held, st.far = st.held, [], False
    for s, tok in held:
        _take(st, s, tok, out)


def sequence_push(st: SeqState, seq: int, token) -> tuple[list, list]:
    """Sample ``seq`` (carried as ``token``) arrives for a rig in state ``st`` (updated in place).

    Returns ``(taken, dropped)``: lists of ``(verdict, seq, token)``, the taken ones in the order
    to take them (any held samples this arrival releases among them).
    """
    out: list = []
    dropped: list = []
    if st.held:
        if st.far:
            if seq == st.held[-1][0] + 1:  # the far run goes on
                st.held.append((seq, token))
                if len(st.held) >= CONFIRM:
                    _release(st, out)
                return out, dropped
            # not the far run's next: it was a lone sample far ahead, never confirmed
            dropped += [(AHEAD, s, tok) for s, tok in st.held]
            st.held, st.far = [], False
        elif any(seq == s for s, _ in st.held):
            dropped.append((DUPLICATE, seq, token))
            return out, dropped
        elif st.last < seq <= st.last + 1 + REORDER:
            st.held.append((seq, token))
            st.held.sort(key=_SEQ)
            if st.held[0][0] == st.last + 1:  # the hole filled: take what is in order, hold the rest
                held, st.held = st.held, []
                for s, tok in held:
                    if st.held or s != st.last + 1:
                        st.held.append((s, tok))
                    else:
                        _take(st, s, tok, out)
            return out, dropped
        else:  # the hole is lost (or the rig went back): what was held goes first
            _release(st, out)
    last = st.last
    if last < 0 or seq == last + 1:
        _take(st, seq, token, out)
    elif seq > last + 1:
        if seq - last - 1 > FAR:
            st.held, st.far = [(seq, token)], True
        elif seq - last - 1 <= REORDER:
            st.held, st.far = [(seq, token)], False
        else:
            _take(st, seq, token, out)
    else:
        _back(st, seq, token, out, dropped)
    return out, dropped


def sequence_order(seq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rig's stream ``seq`` (int, in arrival order) taken as the live monitor takes it:
    ``(order, verdicts, dropped)`` — the indices of the samples taken, in the order taken, their
    verdicts (int8), and the verdict of every sample not taken (-1 for taken ones). Samples still
    held at the end of the stream are taken (a record is over)."""
    st = SeqState()
    order, verdicts = [], []
    dropped = np.full(len(seq), -1, dtype=np.int8)
    for i, s in enumerate(np.asarray(seq).tolist()):
        taken, drop = sequence_push(st, s, i)
        for v, _, j in taken:
            order.append(j)
            verdicts.append(v)
        for v, _, j in drop:
            dropped[j] = v
    tail: list = []
    _release(st, tail)
    for v, _, j in tail:
        order.append(j)
        verdicts.append(v)
    return np.array(order, dtype=np.int64), np.array(verdicts, dtype=np.int8), dropped
