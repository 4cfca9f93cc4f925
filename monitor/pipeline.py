"""The per-rig pipeline (sample in; estimates and grade out), for one rig or a fleet.

``Fleet`` holds every rig's state as rows of a few arrays and runs one compiled call per
batch of arrivals: identification (monitor.identify), then, every ``eval_every`` samples
of a rig (counted on that rig's samples, so results never depend on how arrivals were
batched), read-out (monitor.estimates) and grading (monitor.grading), all in the compiled
kernels of monitor.fleet_kernel. ``Pipeline`` is a fleet of one; both run the same kernels,
and a test pins them equal.
"""

from __future__ import annotations

import heapq
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from hydromon.contract import SENSORS, RigConfig

from .evaluations import Assessment, Events, eval_phase
from .fleet_kernel import N_P, EventArrays, FleetRows, Grading, assess_rig, partition_rigs, pipeline_step, run_part
from .grading import Ranges, grade_kernel
from .ident_model import IdentModel
from .ident_options import IdentOptions, Kernels, new_state, reset_signals, rig_constants
from .layout import O_CLAMPED, O_OUTLIERS, RIG_CONST_SIZE, STATE_SIZE
from .plausibility import any_impossible


class Fleet:
    """Many rigs, one state array each, updated together.

    Parameters
    ----------
    options : IdentOptions
        Identifier hyperparameters (shared).
    ranges : Ranges
        The default health ranges (``Ranges.default()`` when None): a rig added with constants
        they were made for is graded on them (``Ranges.made_for``); any other rig is not graded
        until :meth:`set_ranges` gives it ranges of its own (its grade stays unknown, its
        parameters are still estimated).
    sample_rate : float
        Sample rate of every rig [Hz].
    eval_every : int
        Evaluate and grade a rig every this many of its samples.
    grade_z, grade_margin : float
        Grading's SE gate [standard errors] and hysteresis margin [fraction].
    stagger : bool
        Spread the rigs' evaluations over the eval_every samples of a window (rig ``id`` at
        the samples where count + eval_phase(id) is a multiple of eval_every) instead of all
        at once: a fleet's read-out and grading load is then even from sample to sample.
    threads : int
        Worker threads for large batches (rigs split between them; every rig still sees its
        samples in order, so the numbers do not depend on it). 1 = the caller's thread only.
    """

    #: batches smaller than this run on the caller's thread (a parallel region costs ~10 us)
    PARALLEL_MIN = 256

    def __init__(self, options: IdentOptions | None = None, ranges: Ranges | None = None,
                 sample_rate: float = 100.0, eval_every: int = 10, grade_z: float = 3.0,
                 grade_margin: float = 0.02, capacity: int = 16, threads: int = 1, stagger: bool = False):
        if eval_every < 1:
            raise ValueError(f"eval_every must be >= 1, got {eval_every}")
        if threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.threads = int(threads)
        self.stagger = bool(stagger)
        self._pool: ThreadPoolExecutor | None = None
        self.options = options or IdentOptions()
        self.ranges = ranges or Ranges.default()
        self.sample_rate = float(sample_rate)
        self.eval_every = int(eval_every)
        self.grade_z = float(grade_z)
        self.grade_margin = float(grade_margin)
        self._k = Kernels(self.options, 1.0 / self.sample_rate)
        self.ids: list[str] = []  # by row; "" for a row freed by remove_rig (no valid rig id is empty)
        self.index: dict[str, int] = {}
        self._free: list[int] = []  # rows freed by remove_rig, reused lowest first (a heap)
        capacity = max(1, capacity)
        self.states = np.zeros((capacity, STATE_SIZE))
        self.consts = np.zeros((capacity, RIG_CONST_SIZE))
        self.counts = np.zeros(capacity, dtype=np.int64)
        self.phase = np.zeros(capacity, dtype=np.int64)
        g = N_P  # graded slots per rig: any ranges fit
        self.bands = np.full((capacity, g), -1, dtype=np.int64)
        self.g_count = np.zeros(capacity, dtype=np.int64)
        self.g_index = np.zeros((capacity, g), dtype=np.int64)
        self.g_sign = np.ones((capacity, g))
        self.g_edges = np.zeros((capacity, g, 4))
        self.g_margins = np.zeros((capacity, g, 4))
        self._names: list[tuple] = []      # by row: the graded parameters' names
        self._tags: list[str | None] = []  # by row: the tag of the ranges it is graded on
        self.why: list[str | None] = []    # by row: why no ranges grade it (None: some do)
        self._ev_cap = 0
        self._alloc_events(16)
        self._no_events = Events.of_kernel([v[:0].copy() for v in self._ev])
        self._bind()

    def _bind(self) -> None:
        """The kernels' fixed arguments (rebuilt when the per-rig arrays are reallocated)."""
        self._rows = FleetRows(self.states, self.consts, self.counts, self.phase, self.bands)
        self._model = IdentModel.of(self._k)
        self._grading = Grading(self.g_count, self.g_index, self.g_sign, self.g_edges, self.g_margins, self.grade_z,
                                float(self.options.min_rows))
        # pipeline_step's and run_part's: the records' fields, in their order
        self._fields = (*self._rows, *self._model, *self._grading, self.eval_every)

    def graded(self, rig: int) -> tuple:
        """The names of the parameters rig ``rig`` (a row) is graded on (empty: not graded)."""
        return self._names[rig]

    def ranges_tag(self, rig: int) -> str | None:
        """The tag of the ranges rig ``rig`` is graded on (None: not graded)."""
        return self._tags[rig]

    def set_ranges(self, rig: int, ranges: Ranges | None, tag: str | None = None, why: str | None = None) -> None:
        """Grade rig ``rig`` (a row) on ``ranges`` from its next evaluation on (its hysteresis
        restarts); None: do not grade it (``why`` says why). ``tag`` names the ranges."""
        self.bands[rig] = -1
        if ranges is None:
            self.g_count[rig] = 0
            self._names[rig], self._tags[rig], self.why[rig] = (), None, why
            return
        ra = ranges.to_arrays(self.grade_margin)
        n = len(ra.index)
        self.g_count[rig] = n
        self.g_index[rig, :n], self.g_sign[rig, :n] = ra.index, ra.sign
        self.g_edges[rig, :n], self.g_margins[rig, :n] = ra.edges, ra.margins
        self._names[rig], self._tags[rig], self.why[rig] = ra.names, tag, None

    def __len__(self) -> int:
        return len(self.ids)

    def add_rig(self, rig_id: str, config: RigConfig | None = None) -> int:
        """Register a rig (its constants from ``config``); returns its row index. It is graded on
        the default ranges when they were made for its constants, else not (:meth:`set_ranges`)."""
        if rig_id in self.index:
            raise ValueError(f"rig {rig_id!r} already in the fleet")
        config = config or RigConfig()
        if abs(config.sample_rate - self.sample_rate) > 1e-9:
            raise ValueError(f"rig {rig_id!r} samples at {config.sample_rate} Hz; the fleet runs at {self.sample_rate} Hz")
        if self._free:
            i = heapq.heappop(self._free)
            self.ids[i] = rig_id
        else:
            i = len(self.ids)
            if i == self.states.shape[0]:
                self._grow()
            self.ids.append(rig_id)
            self._names.append(())
            self._tags.append(None)
            self.why.append(None)
        self.index[rig_id] = i
        self.states[i] = new_state(self._k.hyper)
        self.consts[i] = rig_constants(config)
        self.counts[i] = 0
        self.phase[i] = eval_phase(rig_id, self.eval_every) if self.stagger else 0
        self.apply_default_ranges(i, config)
        return i

    def apply_default_ranges(self, rig: int, config: RigConfig | None) -> None:
        """Grade rig ``rig`` on the default ranges if they were made for ``config``, else not."""
        why = self.ranges.made_for(config)
        if why is None:
            self.set_ranges(rig, self.ranges, "default")
        else:
            self.set_ranges(rig, None, why=why)

    def remove_rig(self, rig_id: str) -> int:
        """Forget a rig: its row is freed (its state cleared) for the next :meth:`add_rig`, so a
        fleet whose rigs come and go stays the size of the rigs it holds. Returns the row."""
        i = self.index.pop(rig_id)
        self.ids[i] = ""
        self.states[i] = 0.0
        self.counts[i] = 0
        self.set_ranges(i, None)
        heapq.heappush(self._free, i)
        return i

    def _grow(self) -> None:
        n = self.states.shape[0] * 2
        self.states = np.vstack([self.states, np.zeros_like(self.states)])[:n]
        self.consts = np.vstack([self.consts, np.zeros_like(self.consts)])[:n]
        self.counts = np.concatenate([self.counts, np.zeros_like(self.counts)])[:n]
        self.phase = np.concatenate([self.phase, np.zeros_like(self.phase)])[:n]
        self.bands = np.vstack([self.bands, np.full_like(self.bands, -1)])[:n]
        self.g_count = np.concatenate([self.g_count, np.zeros_like(self.g_count)])[:n]
        self.g_index = np.concatenate([self.g_index, np.zeros_like(self.g_index)])[:n]
        self.g_sign = np.concatenate([self.g_sign, np.ones_like(self.g_sign)])[:n]
        self.g_edges = np.concatenate([self.g_edges, np.zeros_like(self.g_edges)])[:n]
        self.g_margins = np.concatenate([self.g_margins, np.zeros_like(self.g_margins)])[:n]
        self._bind()

    def set_config(self, rig: int, config: RigConfig) -> None:
        """New rig constants; the estimates restart (they were identified against the old ones).
        The caller decides again which ranges grade the rig (:meth:`set_ranges`,
        :meth:`apply_default_ranges`): ranges made for the old constants do not fit the new."""
        self.consts[rig] = rig_constants(config)
        self.reset(rig)

    def reset(self, rig: int) -> None:
        """Forget everything about one rig."""
        self.states[rig] = new_state(self._k.hyper)
        self.counts[rig] = 0
        self.bands[rig] = -1

    def reset_signals(self, rig: int) -> None:
        """Restart one rig's filters after a gap in its samples; the estimates carry on."""
        reset_signals(self.states[rig])

    def update(self, rig: np.ndarray, samples: np.ndarray) -> Events:
        """Consume samples (m, 5) = ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] of rigs ``rig`` (m,).

        The caller validates samples (finite, SI); rows are consumed in the given order.
        """
        rig = np.ascontiguousarray(rig, dtype=np.int64)
        samples = np.ascontiguousarray(samples, dtype=np.float64)
        m = rig.shape[0] if rig.ndim == 1 else -1
        if samples.ndim != 2 or samples.shape[1] != 5 or samples.shape[0] != m:
            raise ValueError(f"need rig (m,) and samples (m, 5), got {rig.shape} and {samples.shape}")
        if m == 1:
            if not 0 <= rig[0] < len(self.ids):
                raise ValueError("rig index out of range")
        elif m and (rig.min() < 0 or rig.max() >= len(self.ids)):
            raise ValueError("rig index out of range")
        cap = m // self.eval_every + len(self.ids) + 1
        if self.threads > 1 and m >= self.PARALLEL_MIN:
            return self._update_parallel(rig, samples, cap)
        if cap > self._ev_cap:
            self._alloc_events(cap)
        n = pipeline_step(*self._fields, rig, samples, *self._ev)
        if n == 0:
            return self._no_events
        return Events.of_kernel([v[:n].copy() for v in self._ev])

    def _update_parallel(self, rig: np.ndarray, samples: np.ndarray, cap: int) -> Events:
        t = self.threads
        if t * cap > self._ev_cap:
            self._alloc_events(t * cap)
        if self._pool is None:
            self._pool = ThreadPoolExecutor(t - 1, thread_name_prefix="fleet")
        order, start = partition_rigs(rig, t, len(self.ids))
        args = (*self._fields, rig, samples, *self._ev)

        def part(k):
            return run_part(order, start[k], start[k + 1], k * cap, *args) - k * cap

        futures = [self._pool.submit(part, k) for k in range(1, t)]
        n_ev = [part(0)] + [f.result() for f in futures]
        if not any(n_ev):
            return self._no_events
        take = np.concatenate([np.arange(k * cap, k * cap + n_ev[k]) for k in range(t)])
        # each part's events are in arrival order; merge them into the serial path's order
        take = take[np.argsort(self._ev.sample[take], kind="stable")]
        return Events.of_kernel([v[take] for v in self._ev])

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_pool"] = None  # threads do not pickle; a restored fleet starts its own
        return state

    def _alloc_events(self, cap: int) -> None:
        # reused between calls: a sample's call allocates nothing until it has events to return
        cap = max(cap, 2 * self._ev_cap)
        ng = N_P
        self._ev = EventArrays(
            rig=np.empty(cap, np.int64), sample=np.empty(cap, np.int64), counts=np.empty(cap, np.int64),
            level=np.empty(cap, np.int64), confidence=np.empty(cap), params=np.empty((cap, N_P)),
            std_errors=np.empty((cap, N_P)), grades=np.empty((cap, ng), np.int64), converged=np.empty(cap, np.bool_),
            clamped=np.empty(cap, np.int64), implausible=np.empty(cap, np.bool_))
        self._ev_cap = cap

    def glitches(self, rig: int) -> dict[str, int]:
        """Sensor samples of one rig the outlier gate replaced so far, per sensor."""
        counts = self.states[rig, O_OUTLIERS:O_OUTLIERS + len(SENSORS)]
        return {name: int(c) for name, c in zip(SENSORS, counts)}

    def x1_clamped(self, rig: int) -> int:
        """Samples of one rig whose x1 would have emptied a chamber (V_i under 1 % of V_i0): not
        physical, so the rig constants (A1, A2, V10, V20) or x1's zero, sign or unit are wrong;
        the chamber rows took the clamped volume and their parameters are not to be trusted."""
        return int(self.states[rig, O_CLAMPED])

    def x1_clamped_all(self) -> np.ndarray:
        """:meth:`x1_clamped` of every rig, (n_rigs,) int64, in row order."""
        return self.states[:len(self), O_CLAMPED].astype(np.int64)

    def estimate(self, rig: int) -> Assessment:
        """Evaluate one rig now (does not move its hysteresis state)."""
        p = np.empty((1, N_P))
        s = np.empty((1, N_P))
        g = self._grading
        conv = np.array([assess_rig(self.states[rig], self._model, g.min_rows, p[0], s[0])])
        bad = np.array([any_impossible(p[0], s[0])])
        n = int(g.count[rig])
        band = self.bands[rig:rig + 1, :n].copy()
        level, grades, conf = grade_kernel(p, s, conv & ~bad, g.index[rig, :n], g.sign[rig, :n], g.edges[rig, :n],
                                           g.margins[rig, :n], g.z, band)
        one = Events.of_kernel([np.array([rig]), np.array([-1]), self.counts[rig:rig + 1].copy(), level, conf, p, s,
                                grades, conv, np.array([self.x1_clamped(rig)]), bad])
        return one.assessment(0, self._names[rig])


class Pipeline:
    """One rig: ``update(sample) -> Assessment | None`` (an assessment every eval_every samples).

    ``run(samples)`` consumes a whole (N, 5) array at once and returns the last assessment.
    """

    def __init__(self, config: RigConfig | None = None, options: IdentOptions | None = None,
                 ranges: Ranges | None = None, eval_every: int = 10, **kw):
        config = config or RigConfig()
        self.fleet = Fleet(options, ranges, sample_rate=config.sample_rate, eval_every=eval_every,
                           capacity=1, **kw)
        self.fleet.add_rig("rig", config)

    def update(self, sample) -> Assessment | None:
        s = np.asarray(sample, dtype=float).reshape(1, 5)
        if not np.all(np.isfinite(s)):
            raise ValueError(f"non-finite sample {s[0].tolist()}")
        ev = self.fleet.update(np.zeros(1, np.int64), s)
        return ev.assessment(0, self.fleet.graded(0)) if len(ev) else None

    def run(self, samples: np.ndarray, restarts=()) -> tuple[Events, Assessment]:
        """Consume a record; ``restarts`` are the indices of samples that follow a gap (the
        filters restart there, the estimates carry on, as the monitor does on the bus)."""
        samples = np.asarray(samples, dtype=float)
        if samples.ndim != 2 or samples.shape[1] != 5:
            raise ValueError(f"samples must be (N, 5): ug, x1, x3, x4, x5; got {samples.shape}")
        if not np.all(np.isfinite(samples)):
            bad = int(np.argwhere(~np.isfinite(samples))[0, 0])
            raise ValueError(f"non-finite value in sample {bad}")
        cuts = sorted(set(int(i) for i in restarts))
        if cuts and (cuts[0] <= 0 or cuts[-1] >= len(samples)):
            raise ValueError(f"restarts must be inside the record (1..{len(samples) - 1}), got {cuts}")
        bounds = [0, *cuts, len(samples)]
        parts = []
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if lo:
                self.fleet.reset_signals(0)
            parts.append(self.fleet.update(np.zeros(hi - lo, np.int64), samples[lo:hi]))
        ev = parts[0] if len(parts) == 1 else Events.concat(parts, bounds[:-1])
        return ev, self.fleet.estimate(0)


def warm_up() -> None:
    """Compile (or load from the cache) every kernel of the pipeline on a few dummy samples.

    Nodes call this before they subscribe, so the first real samples do not wait for the
    compiler (about a minute on a fresh machine, well under a second once cached).
    """
    p = Pipeline()
    s = np.tile(np.array([2.0, 0.05, 4e6, 7e6, 1e-5]), (40, 1))
    s[:, 4] += np.linspace(0.0, 1e-6, 40)
    p.run(s)
    p.update(s[0])
