"""The fleet's compiled kernels: a batch of samples in arrival order through identification
(monitor.identify), and at each rig's evaluation points read-out (monitor.estimates) and
grading (monitor.grading) into event arrays. Driven by ``monitor.pipeline.Fleet``.

The kernels take their arrays grouped into the records below (module-level NamedTuples: numba
types them field by field and ``cache=True`` finds the classes again), except at the two ends
of a call, for speed: ``pipeline_step`` and ``run_part``, the entries Python calls once per
batch (down to one sample a batch) or per thread's part of it, take the records' fields one by
one and group them themselves, and the per-sample loop hands
``monitor.identify.identify_step`` the fields of ``IdentModel`` and ``Scratch`` (each says why).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from hydromon.contract import PARAM_NAMES

from .estimates import estimates
from .grading import grade_kernel
from .ident_model import IdentModel
from .identify import identify_step
from .layout import O_CLAMPED, O_ROWS
from .plausibility import any_impossible
from .scratch import new_scratch

N_P = len(PARAM_NAMES)


class FleetRows(NamedTuple):
    """The fleet's per-rig arrays, row r for the rig in row r (``monitor.pipeline.Fleet`` owns them)."""

    states: np.ndarray
    """(n_rows, STATE_SIZE) float64 identifier states (``monitor.layout``)."""
    consts: np.ndarray
    """(n_rows, RIG_CONST_SIZE) float64 rig constants (SI)."""
    counts: np.ndarray
    """(n_rows,) int64 samples consumed."""
    phase: np.ndarray
    """(n_rows,) int64 evaluation phase: a rig is evaluated where count + phase is a multiple of eval_every."""
    bands: np.ndarray
    """(n_rows, G) int64 grading hysteresis state, the band each graded parameter is held in."""


class Grading(NamedTuple):
    """How each rig is graded (``monitor.grading.grade_kernel``): row r's ranges in row r, its
    graded parameters in the first ``count[r]`` slots (none: the rig is not graded)."""

    count: np.ndarray
    """(n_rows,) int64 the rig's graded parameters (0: no ranges made for it)."""
    index: np.ndarray
    """(n_rows, G) int64 the graded parameters' indices in PARAM_NAMES."""
    sign: np.ndarray
    """(n_rows, G) +-1: the direction in which each parameter degrades."""
    edges: np.ndarray
    """(n_rows, G, 4) float64 band edges [SI unit of each parameter]."""
    margins: np.ndarray
    """(n_rows, G, 4) float64 hysteresis margins [SI unit of each parameter]."""
    z: float
    """The SE gate's half-width [standard errors]."""
    min_rows: float
    """Rows the chamber and valve equations each need before their rig counts as converged and is graded."""


class Arrivals(NamedTuple):
    """A batch of samples in arrival order."""

    rig: np.ndarray
    """(m,) int64 the row of each sample's rig."""
    samples: np.ndarray
    """(m, 5) float64 ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m]."""


class EventArrays(NamedTuple):
    """Evaluation events, one row per event, owned by the caller (fields as ``monitor.evaluations.Events``)."""

    rig: np.ndarray
    """(cap,) int64 the rig's row."""
    sample: np.ndarray
    """(cap,) int64 the batch sample after which the rig was evaluated."""
    counts: np.ndarray
    """(cap,) int64 the rig's sample count then."""
    level: np.ndarray
    """(cap,) int64 fused level 0..4, -1 unknown."""
    confidence: np.ndarray
    """(cap,) float64 in [0, 1]."""
    params: np.ndarray
    """(cap, N_P) float64 estimates, PARAM_NAMES order [SI]."""
    std_errors: np.ndarray
    """(cap, N_P) float64 their standard errors [SI]."""
    grades: np.ndarray
    """(cap, n_graded) int64 per-parameter grade, -1 not placed."""
    converged: np.ndarray
    """(cap,) bool."""
    clamped: np.ndarray
    """(cap,) int64 the rig's samples so far whose x1 would have emptied a chamber."""
    implausible: np.ndarray
    """(cap,) bool physically impossible estimates (not graded)."""


class Readout(NamedTuple):
    """Scratch of one evaluation, shaped as ``grade_kernel`` takes it (one rig)."""

    params: np.ndarray
    """(1, N_P) float64 [SI]."""
    std_errors: np.ndarray
    """(1, N_P) float64 [SI]."""
    converged: np.ndarray
    """(1,) bool: converged and plausible."""


@njit(cache=True, error_model="numpy")
def assess_rig(st, model, min_rows, p, s):
    """Estimates of one rig into p, s (N_P,) [SI]; an equation with fewer than min_rows rows has
    its parameters' standard errors set to inf (not gradable). Converged once the chamber and
    valve equations have their rows: the force balance is not required, because at fault-grade
    leakage the piston barely moves and that equation is unidentifiable (the grade then comes
    from the rest).
    """
    estimates(st, model, p, s)
    for eq, lo, hi in ((0, 0, 4), (1, 4, 8), (2, 8, N_P)):  # force, chambers, valve (with K_sv)
        if st[O_ROWS + eq] < min_rows:
            for j in range(lo, hi):
                s[j] = np.inf
    return st[O_ROWS + 1] >= min_rows and st[O_ROWS + 2] >= min_rows


@njit(cache=True, error_model="numpy")
def _evaluate(fleet, model, grading, events, r, i, slot, out):
    """Read out and grade the rig in row r after batch sample i into event ``slot``; ``out`` is
    the caller's ``Readout``.

    A call of its own, not in the per-sample loop: it runs once per eval_every samples, and
    inlined into the loop it slowed every sample.
    """
    p, s = out.params[0], out.std_errors[0]
    converged = assess_rig(fleet.states[r], model, grading.min_rows, p, s)
    bad = any_impossible(p, s)
    # impossible estimates are not graded, and leave the hysteresis state as it was
    out.converged[0] = converged and not bad
    n = grading.count[r]
    level, grades, confidence = grade_kernel(out.params, out.std_errors, out.converged, grading.index[r, :n],
                                             grading.sign[r, :n], grading.edges[r, :n], grading.margins[r, :n],
                                             grading.z, fleet.bands[r:r + 1, :n])
    events.rig[slot] = r
    events.sample[slot] = i
    events.counts[slot] = fleet.counts[r]
    events.level[slot] = level[0]
    events.confidence[slot] = confidence[0]
    events.params[slot] = p
    events.std_errors[slot] = s
    events.grades[slot, :n] = grades[0]
    events.grades[slot, n:] = -1
    events.converged[slot] = converged
    events.clamped[slot] = fleet.states[r, O_CLAMPED]  # samples whose x1 emptied a chamber, so far
    events.implausible[slot] = bad


@njit(cache=True, error_model="numpy")
def _run(order, lo, hi, fleet, model, grading, eval_every, arrivals, events, slot):
    """Samples order[lo:hi] of the batch ``arrivals``, in that order, through identification;
    each rig's evaluations (every eval_every of its samples) into ``events`` from ``slot`` on.
    Returns the next free slot."""
    out = Readout(np.empty((1, N_P)), np.empty((1, N_P)), np.zeros(1, dtype=np.bool_))
    # the arrays the loop reads on every sample, as locals: read from the records inside the
    # loop, each costs a reference count a sample (identify_step says how much)
    work, y_f, y_c, y_o, y_k = new_scratch()
    hyper, m_f, m_c, m_o, g_f, g_c = model
    rig, samples = arrivals
    states, consts, counts, phase = fleet.states, fleet.consts, fleet.counts, fleet.phase
    for q in range(lo, hi):
        i = order[q]
        r = rig[i]
        identify_step(states[r], consts[r], hyper, m_f, m_c, m_o, g_f, g_c, samples[i, 0], samples[i, 1], samples[i, 2],
                      samples[i, 3], samples[i, 4], work, y_f, y_c, y_o, y_k)
        counts[r] += 1
        if (counts[r] + phase[r]) % eval_every == 0:
            _evaluate(fleet, model, grading, events, r, i, slot, out)
            slot += 1
    return slot


# The two entries Python calls take the records' fields one by one: numba's dispatcher types a
# plain array argument in C and a NamedTuple in Python, field by field. At one sample a call
# (Fleet.update of a single rig) the five records as arguments take 8.7 us a call, their fields
# 4.2 us (measured); a worker thread's dispatch holds the GIL the other threads need.

# nogil: Fleet's worker threads call it directly. Threads, not numba's prange: every view a
# kernel takes of a shared array counts references on that array's one meminfo, and two cores
# bumping one counter ~40 times a sample serialise a prange version (1.15x on 2 cores); each
# Python thread's call unboxes the arrays with its own meminfo.
@njit(cache=True, nogil=True, error_model="numpy")
def run_part(order, lo, hi, slot,
             states, consts, counts, phase, bands,  # FleetRows
             hyper, m_f, m_c, m_o, g_f, g_c,  # IdentModel
             g_count, index, sign, edges, margins, z, min_rows,  # Grading
             eval_every, rig, samples,  # the schedule and the Arrivals
             ev_rig, ev_sample, ev_counts, ev_level, ev_confidence, ev_params, ev_std_errors, ev_grades,
             ev_converged, ev_clamped, ev_implausible):  # EventArrays
    """Samples order[lo:hi] of the batch (rig, samples), in that order, through identification and
    the rigs' evaluations; events from ``slot`` on. Returns the next free slot. The arguments
    after ``slot`` are ``pipeline_step``'s."""
    return _run(order, lo, hi, FleetRows(states, consts, counts, phase, bands),
                IdentModel(hyper, m_f, m_c, m_o, g_f, g_c), Grading(g_count, index, sign, edges, margins, z, min_rows),
                eval_every, Arrivals(rig, samples),
                EventArrays(ev_rig, ev_sample, ev_counts, ev_level, ev_confidence, ev_params, ev_std_errors,
                            ev_grades, ev_converged, ev_clamped, ev_implausible), slot)


@njit(cache=True, error_model="numpy")
def pipeline_step(states, consts, counts, phase, bands,  # FleetRows
                  hyper, m_f, m_c, m_o, g_f, g_c,  # IdentModel
                  g_count, index, sign, edges, margins, z, min_rows,  # Grading
                  eval_every, rig, samples,  # the schedule and the Arrivals
                  ev_rig, ev_sample, ev_counts, ev_level, ev_confidence, ev_params, ev_std_errors, ev_grades,
                  ev_converged, ev_clamped, ev_implausible):  # EventArrays
    """Identify a batch of samples in arrival order; evaluate and grade rigs at their evaluation
    points (every eval_every samples of a rig, counted on that rig's samples, so results never
    depend on how arrivals were batched). Returns the number of events written into the event
    arrays (sized by the caller to len(samples) // eval_every + number of rigs)."""
    return _run(np.arange(rig.shape[0]), 0, rig.shape[0], FleetRows(states, consts, counts, phase, bands),
                IdentModel(hyper, m_f, m_c, m_o, g_f, g_c), Grading(g_count, index, sign, edges, margins, z, min_rows),
                eval_every, Arrivals(rig, samples),
                EventArrays(ev_rig, ev_sample, ev_counts, ev_level, ev_confidence, ev_params, ev_std_errors,
                            ev_grades, ev_converged, ev_clamped, ev_implausible), 0)


@njit(cache=True, error_model="numpy")
def partition_rigs(rig, n_parts, n_rows):
    """Sample indices grouped by part, arrival order kept within a part, and the parts' start
    offsets (n_parts + 1,). Part k takes the rows [k n_rows / n_parts, (k + 1) n_rows / n_parts):
    contiguous blocks, so two threads never write the same cache line of the per-rig arrays
    (counts, bands), as interleaved rows (rig % n_parts) would for every sample."""
    m = rig.shape[0]
    start = np.zeros(n_parts + 1, np.int64)
    part = np.empty(m, np.int64)
    for i in range(m):
        t = min(rig[i] * n_parts // max(n_rows, 1), n_parts - 1)
        part[i] = t
        start[t + 1] += 1
    for t in range(n_parts):
        start[t + 1] += start[t]
    order = np.empty(m, np.int64)
    fill = start[:-1].copy()
    for i in range(m):
        t = part[i]
        order[fill[t]] = i
        fill[t] += 1
    return order, start
