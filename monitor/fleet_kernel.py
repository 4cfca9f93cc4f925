"""The fleet's compiled kernels: a batch of samples in arrival order through identification
(monitor.identify), and at each rig's evaluation points read-out (monitor.estimates) and
grading (monitor.grading) into event arrays. Driven by ``monitor.pipeline.Fleet``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from hydromon.contract import PARAM_NAMES

from .estimates import estimates
from .grading import grade_kernel
from .identify import WORK_SIZE, identify_step, scratch_2d
from .layout import O_CLAMPED, O_ROWS
from .plausibility import any_impossible

N_P = len(PARAM_NAMES)


@njit(cache=True, error_model="numpy")
def assess_rig(st, hyper, g_f, g_c, min_rows, p, s):
    """Estimates of one rig; an equation with fewer than min_rows rows has its parameters'
    standard errors set to inf (not gradable). Converged once the chamber and valve equations
    have their rows: the force balance is not required, because at fault-grade leakage the
    piston barely moves and that equation is unidentifiable (the grade then comes from the rest).
    """
    estimates(st, hyper, g_f, g_c, p, s)
    for eq, lo, hi in ((0, 0, 4), (1, 4, 8), (2, 8, N_P)):  # force, chambers, valve (with K_sv)
        if st[O_ROWS + eq] < min_rows:
            for j in range(lo, hi):
                s[j] = np.inf
    return st[O_ROWS + 1] >= min_rows and st[O_ROWS + 2] >= min_rows


@njit(cache=True, error_model="numpy")
def _evaluate(r, i, states, counts, bands, hyper, g_f, g_c, min_rows, index, sign, edges, margins, z,
              ev_rig, ev_sample, ev_count, ev_level, ev_conf, ev_params, ev_se, ev_grades, ev_conv, ev_clamped,
              ev_bad, slot, p, s, conv):
    """Read out and grade rig r after batch sample i into event ``slot``.

    Kept out of the per-sample loop: it runs once per eval_every samples, and a call with this
    many arguments costs more than a sample's identification when made on every sample.
    ``p``, ``s`` (1, len(PARAM_NAMES)) and ``conv`` (1,) are the caller's scratch space.
    """
    converged = assess_rig(states[r], hyper, g_f, g_c, min_rows, p[0], s[0])
    bad = any_impossible(p[0], s[0])
    # impossible estimates are not graded, and leave the hysteresis state as it was
    conv[0] = converged and not bad
    level, grades, confidence = grade_kernel(p, s, conv, index, sign, edges, margins, z, bands[r:r + 1])
    ev_rig[slot] = r
    ev_sample[slot] = i
    ev_count[slot] = counts[r]
    ev_level[slot] = level[0]
    ev_conf[slot] = confidence[0]
    ev_params[slot] = p[0]
    ev_se[slot] = s[0]
    ev_grades[slot] = grades[0]
    ev_conv[slot] = converged
    ev_clamped[slot] = states[r, O_CLAMPED]  # samples whose x1 emptied a chamber, so far
    ev_bad[slot] = bad


# nogil: Fleet's worker threads call it directly. Threads, not numba's prange: every view a
# kernel takes of a shared array counts references on that array's one meminfo, and two cores
# bumping one counter ~40 times a sample serialised a prange version (1.15x on 2 cores); each
# Python thread's call unboxes the arrays with its own meminfo.
@njit(cache=True, nogil=True, error_model="numpy")
def _run(order, lo, hi, states, consts, counts, phase, bands, hyper, m_f, m_c, m_o, g_f, g_c, min_rows, eval_every,
         index, sign, edges, margins, z, rig, samples,
         ev_rig, ev_sample, ev_count, ev_level, ev_conf, ev_params, ev_se, ev_grades, ev_conv, ev_clamped, ev_bad,
         slot):
    """Samples order[lo:hi] of the batch, in that order; events from ``slot`` on. Returns the next slot."""
    work, p, s, conv = _scratch(ev_params.shape[1])
    bufs = scratch_2d()
    for q in range(lo, hi):
        i = order[q]
        r = rig[i]
        identify_step(states[r], consts[r], hyper, m_f, m_c, m_o, g_f, g_c, samples[i, 0], samples[i, 1], samples[i, 2],
                      samples[i, 3], samples[i, 4], work, bufs)
        counts[r] += 1
        if (counts[r] + phase[r]) % eval_every == 0:
            _evaluate(r, i, states, counts, bands, hyper, g_f, g_c, min_rows, index, sign, edges, margins, z,
                      ev_rig, ev_sample, ev_count, ev_level, ev_conf, ev_params, ev_se, ev_grades, ev_conv,
                      ev_clamped, ev_bad, slot, p, s, conv)
            slot += 1
    return slot


@njit(cache=True, error_model="numpy")
def pipeline_step(states, consts, counts, phase, bands, hyper, m_f, m_c, m_o, g_f, g_c, min_rows, eval_every,
                  index, sign, edges, margins, z, rig, samples,
                  ev_rig, ev_sample, ev_count, ev_level, ev_conf, ev_params, ev_se, ev_grades, ev_conv, ev_clamped,
                  ev_bad):
    """Identify a batch of samples in arrival order; evaluate and grade rigs at their evaluation points
    (every eval_every samples of a rig, counted on that rig's samples, so results never depend on
    how arrivals were batched).

    Returns the number of evaluation events written into the ``ev_*`` arrays (sized by the
    caller to len(samples) // eval_every + number of rigs).
    """
    return _run(np.arange(rig.shape[0]), 0, rig.shape[0], states, consts, counts, phase, bands, hyper, m_f, m_c,
                m_o, g_f, g_c, min_rows, eval_every, index, sign, edges, margins, z, rig, samples,
                ev_rig, ev_sample, ev_count, ev_level, ev_conf, ev_params, ev_se, ev_grades, ev_conv, ev_clamped,
                ev_bad, 0)


@njit(cache=True, error_model="numpy")
def partition_rigs(rig, n_parts, n_rows):
    """Sample indices grouped by part, arrival order kept within a part, and the parts' start
    offsets (n_parts + 1,). Part k takes the rows [k n_rows / n_parts, (k + 1) n_rows / n_parts):
    contiguous blocks, so two threads never write the same cache line of the per-rig arrays
    (counts, bands), which rig % n_parts made them do for every sample."""
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


@njit(cache=True, error_model="numpy")
def _scratch(n_params):
    return (np.empty(WORK_SIZE), np.empty((1, n_params)), np.empty((1, n_params)),
            np.zeros(1, dtype=np.bool_))
