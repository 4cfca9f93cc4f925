"""Frames of a simulated fleet, each rig's ending at its own phase, so a fleet's frames (and the
health they complete) come spread over the frame period instead of all on one tick.

Rig ``i`` of a ``hydromon sim --frame N`` fleet ends its frames after the samples ``seq`` with
``(seq + 1 + eval_phase(id, N)) % N == 0`` (``monitor.pipeline.eval_phase``: CRC-32 of the id, the
phase the monitor grades it at when N is its ``eval_every``), so a frame of N ends exactly where
the monitor's window of the rig ends and its health follows at once; a rig's first frame (and,
at the end of a run, its last) may be shorter. Frames span the simulator's blocks: the last N
ticks of a block are kept for the next.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hydromon.engine.frames import block_frames
from monitor.pipeline import eval_phase

__all__ = ["Framer"]


class Framer:
    """Frames of ``ids`` (rig ids in fleet order) of ``frame`` samples; ``with_u``: indices of the
    rigs that carry their valve drive. Call :meth:`block` with each new block, :meth:`due` at each
    of its ticks, :meth:`rest` once after the last."""

    def __init__(self, ids, frame: int, with_u=frozenset()):
        self.n, self.with_u = int(frame), with_u
        offsets = np.array([eval_phase(i, self.n) for i in ids])
        self.groups = [np.flatnonzero(offsets == o) for o in range(self.n)]
        self.win = None  # the previous block's last n ticks, then the current block
        self.base = 0    # index in win of the current block's first tick
        self.last = -1   # the last tick given to due(), index in win

    def block(self, blk) -> None:
        """The next block (``plant_sim.live.Block``: seq, t, samples, u) from now on."""
        if self.win is None:
            self.win, self.base = blk, 0
        else:
            k, w = min(self.n, len(self.win.t)), self.win
            self.win = SimpleNamespace(seq=np.concatenate([w.seq[-k:], blk.seq]), t=np.concatenate([w.t[-k:], blk.t]),
                                       samples=np.concatenate([w.samples[:, -k:], blk.samples], axis=1),
                                       u=np.concatenate([w.u[:, -k:], blk.u], axis=1))
            self.base = k
        self.last = -1

    def due(self, j: int) -> list[tuple[int, bytes]]:
        """``(rig index, frame payload)`` of the frames that end at tick ``j`` of the current block."""
        end = self.base + j + 1
        self.last = end - 1
        seq = int(self.win.seq[end - 1])
        rigs = self.groups[(-seq - 1) % self.n]
        if not len(rigs):
            return []
        return list(zip(rigs.tolist(), block_frames(self.win, max(0, end - self.n), end, self.with_u, rigs)))

    def rest(self) -> list[tuple[int, bytes]]:
        """The frames of every rig whose samples up to the last tick given to :meth:`due` did not end one."""
        if self.win is None or self.last < 0:
            return []
        out = []
        last_seq = int(self.win.seq[self.last])
        for o, rigs in enumerate(self.groups):
            pending = (last_seq + 1 + o) % self.n  # samples after the group's last frame end
            if pending and len(rigs):
                start = max(0, self.last + 1 - pending)
                out += zip(rigs.tolist(), block_frames(self.win, start, self.last + 1, self.with_u, rigs))
        return out
