"""The batch path of frames: a batch's regular frames decoded, checked and queued together.

A *regular* frame is one on the known frame key of a rig, without the valve drive, that passes
every check of ``hydromon.engine.frames.frame_columns`` and whose first seq follows its rig's
last (or the rig's previous frame in the batch), of a rig with nothing pending (no gap being
counted out, no bad input to report, no sample held back) and no other message in the batch.
Such frames are taken at once: one typed decode per frame (msgspec, in C), then the checks and
the queueing on arrays of the whole batch (lengths, seq range, magnitude limits, strictly
increasing times, seq continuity), with no Python object per sample. Everything else goes
one by one, in arrival order, through the per-message path, which takes, holds back or rejects
it with its reason; rigs are independent, so every rig's health is the same as if every
message had gone one by one (a property test).
"""

from __future__ import annotations

from itertools import chain
from operator import attrgetter

import msgspec
import numpy as np

from hydromon.contract import FRAME_MAX, SAMPLE_COLUMNS, SEQ_MAX, parse_rig_key
from hydromon.engine.frames import frame_struct
from hydromon.engine.validate import VALUE_LIMITS

__all__ = ["FrameBatch"]

_COLUMNS = tuple(attrgetter(name) for name in SAMPLE_COLUMNS)  # t, ug, x1, x3, x4, x5
_SEQ = attrgetter("seq")
_TAKEN = frozenset(("sample", "frame", "config"))  # the leaves whose messages change a rig's state


def _struct(payload: bytes):
    """The frame's decoded fields, or None when the typed decode refuses it (the per-message
    path then says why)."""
    try:
        return frame_struct(payload)
    except msgspec.DecodeError:
        return None


class FrameBatch:
    """MonitorCore's batch path for frames (a mixin: it works on the core's rig table and
    sequence arrays, and queues through ``RegularBatch._take_regular``)."""

    def _regular_frames(self, rest: list) -> list:
        """Take the regular frames of ``rest`` (``(message index, key, payload)`` in order, what the
        sample pass left) at once; return the other messages, in order."""
        get = self._frame_rigs.get
        found = [(j, rig) for j, (_, key, _) in enumerate(rest) if (rig := get(key)) is not None]
        if len(found) < 2:
            return rest
        cand = [j for j, _ in found]
        structs = [_struct(rest[j][2]) for j in cand]
        rows = np.fromiter((rig.row for _, rig in found), np.int64, len(found))
        slow = np.zeros(len(self._last), dtype=np.bool_)
        # a rig with another message in the batch that the core takes (a sample, a config, a frame on a
        # key not yet known) goes one by one; health and events (a recording holds them) are ignored
        if len(cand) < len(rest):
            picked = set(cand)
            for j, (_, key, _) in enumerate(rest):
                if j not in picked:
                    parsed = parse_rig_key(key, self.namespace)
                    if parsed is not None and parsed[1] in _TAKEN and parsed[0] in self.rigs:
                        slow[self.rigs[parsed[0]].row] = True
        ok = np.array([f is not None and f.u is None for f in structs], dtype=np.bool_)
        if not ok.all():
            slow[rows[~ok]] = True
        good = [f for f in structs if f is not None and f.u is None]
        k_good = np.flatnonzero(ok)
        if not good:
            return rest
        lens = np.array([list(map(len, map(col, good))) for col in _COLUMNS])  # (6, frames)
        n = lens[0]
        try:
            seqs = np.fromiter(map(_SEQ, good), np.int64, len(good))
        except OverflowError:  # a seq beyond int64: the per-message path rejects it
            return rest
        fine = (n >= 1) & (n <= FRAME_MAX) & (lens == n).all(axis=0) & (seqs >= 0) & (seqs <= SEQ_MAX - n + 1)
        if not fine.all():
            slow[rows[k_good[~fine]]] = True
            good = [f for f, keep in zip(good, fine.tolist()) if keep]
            k_good, n, seqs = k_good[fine], n[fine], seqs[fine]
            if not good:
                return self._rest(rest, cand, slow, rows, k_good, n, seqs, None)
        total = int(n.sum())
        vals = np.empty((total, 6))
        for c, col in enumerate(_COLUMNS):
            vals[:, c] = np.fromiter(chain.from_iterable(map(col, good)), np.float64, total)
        frame_of = np.repeat(np.arange(len(good)), n)
        bad = (np.abs(vals[:, 1:]) > VALUE_LIMITS).any(axis=1)
        bad[1:] |= (vals[1:, 0] <= vals[:-1, 0]) & (frame_of[1:] == frame_of[:-1])  # times strictly increase
        bad_frame = np.bincount(frame_of, weights=bad, minlength=len(good)) > 0
        if bad_frame.any():
            slow[rows[k_good[bad_frame]]] = True
        return self._rest(rest, cand, slow, rows, k_good, n, seqs, vals)

    def _rest(self, rest, cand, slow, rows, k_good, n, seqs, vals) -> list:
        """Queue the frames ``k_good`` (indices into ``cand``; ``n`` samples from ``seqs`` each,
        their samples' ``vals`` t..x5) of rigs not ``slow`` whose seqs
        follow on; return the messages not taken."""
        if len(k_good):
            r_g = rows[k_good]
            slow |= self._out_of_turn(r_g, seqs, n)  # RegularBatch's rule, for runs of n samples
            keep = ~slow[r_g]
        else:
            keep = np.zeros(0, dtype=np.bool_)
        if keep.any():
            msg = np.array([rest[cand[k]][0] for k in k_good.tolist()], dtype=np.int64)
            take = np.repeat(keep, n)
            n_k, s_k = n[keep], seqs[keep]
            start = np.repeat(np.cumsum(n_k) - n_k, n_k)
            seq_s = np.repeat(s_k, n_k) + (np.arange(int(n_k.sum())) - start)
            r_k = r_g[keep]
            self._take_regular(np.repeat(r_k, n_k), seq_s.tolist(), vals[take], np.repeat(msg[keep], n_k).tolist())
            np.maximum.at(self._last, r_k, s_k + n_k - 1)  # a rig's last seq: its last frame's (seqs increase)
        taken = {cand[k] for k in k_good[keep].tolist()}
        return [m for j, m in enumerate(rest) if j not in taken]
