"""A rig's recent verdicts in memory: two rings of decimated points (the last minutes finely, the
last hour coarsely), for the rig page's parameter plots and grade timeline.

A point is one verdict: the dashboard's arrival time (wall clock [s]), the rig time ``t`` [s],
level (-1 unknown), status, confidence, and every parameter of ``contract.PARAM_NAMES`` with its
standard error (NaN where the verdict has none). Values are float32: 7 digits are more than a
plot shows, and 1000 rigs hold an hour in about 110 MB.
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import PARAM_NAMES, STATUSES

__all__ = ["RigHistory", "FINE", "COARSE"]

FINE = (1.0, 300)      # spacing [s], points: the last 5 minutes at 1 s
COARSE = (6.0, 600)    # the last hour at 6 s
_N = len(PARAM_NAMES)
_STATUS_INDEX = {s: i for i, s in enumerate(STATUSES)}


class _Ring:
    def __init__(self, spacing: float, size: int):
        self.spacing, self.size = float(spacing), int(size)
        self.wall = np.full(size, np.nan)
        self.t = np.full(size, np.nan)
        self.level = np.full(size, -1, dtype=np.int8)
        self.status = np.zeros(size, dtype=np.int8)
        self.conf = np.zeros(size, dtype=np.float32)
        self.value = np.full((size, _N), np.nan, dtype=np.float32)
        self.se = np.full((size, _N), np.nan, dtype=np.float32)
        self.n = 0          # points ever taken
        self.last = -math.inf

    def due(self, wall: float) -> bool:
        return wall - self.last >= self.spacing

    def take(self, wall: float, h: dict) -> None:
        i = self.n % self.size
        self.wall[i], self.t[i] = wall, h["t"]
        self.level[i] = -1 if h["level"] is None else h["level"]
        self.status[i] = _STATUS_INDEX.get(h["status"], 0)
        self.conf[i] = h["confidence"]
        params, ses = h["params"], h["std_errors"]
        self.value[i] = [params.get(p, math.nan) for p in PARAM_NAMES]
        self.se[i] = [ses.get(p, math.nan) for p in PARAM_NAMES]
        self.n += 1
        self.last = wall

    def order(self) -> np.ndarray:
        """Indices of the held points, oldest first."""
        if self.n <= self.size:
            return np.arange(self.n)
        start = self.n % self.size
        return np.r_[start:self.size, 0:start]


def _clean(a: np.ndarray) -> list:
    """JSON-ready: NaN and inf become None (JSON has no NaN)."""
    out = a.astype(np.float64)
    return [None if not math.isfinite(v) else v for v in out.tolist()]


class RigHistory:
    """The decimated verdicts of one rig: :meth:`take` every verdict the dashboard sees (only
    those due in a ring are kept), :meth:`points` for the plots."""

    def __init__(self, fine: tuple[float, int] = FINE, coarse: tuple[float, int] = COARSE):
        self.fine, self.coarse = _Ring(*fine), _Ring(*coarse)

    def take(self, wall: float, h: dict) -> bool:
        """Keep verdict ``h`` (a ``contract.Health`` dict) seen at ``wall`` [s] where a ring is due;
        True if the fine ring took it (a new point to push to a rig page)."""
        if self.coarse.due(wall):
            self.coarse.take(wall, h)
        if self.fine.due(wall):
            self.fine.take(wall, h)
            return True
        return False

    def points(self, since: float | None = None) -> dict:
        """Columns of the held points, oldest first: the coarse ring before the fine ring's
        first point, then the fine ring; only points after ``since`` [s, wall] when given."""
        fi = self.fine.order()
        ci = self.coarse.order()
        first_fine = self.fine.wall[fi[0]] if len(fi) else math.inf
        ci = ci[self.coarse.wall[ci] < first_fine]
        cols = {"wall": [], "t": [], "level": [], "status": [], "conf": [],
                "value": {p: [] for p in PARAM_NAMES}, "se": {p: [] for p in PARAM_NAMES}}
        for ring, idx in ((self.coarse, ci), (self.fine, fi)):
            if since is not None:
                idx = idx[ring.wall[idx] > since]
            if not len(idx):
                continue
            cols["wall"] += ring.wall[idx].tolist()
            cols["t"] += ring.t[idx].tolist()
            cols["level"] += ring.level[idx].tolist()
            cols["status"] += [STATUSES[s] for s in ring.status[idx].tolist()]
            cols["conf"] += [round(c, 3) for c in ring.conf[idx].tolist()]
            for j, p in enumerate(PARAM_NAMES):
                cols["value"][p] += _clean(ring.value[idx, j])
                cols["se"][p] += _clean(ring.se[idx, j])
        return cols

    @property
    def last_wall(self) -> float:
        return self.fine.last
