"""The naive twin's state as ``monitor.layout``'s flat row: the shared read-out
(``monitor.estimates``) and the tests read it as they read the compiled kernel's.
"""

from __future__ import annotations

import numpy as np

from monitor.force_observer import N_OBS_PARAMS
from monitor.layout import (
    N_CH, N_LAGS, N_OBS, N_STREAMS, O_BC, O_CLAMPED, O_EXC_C, O_GATE, O_GATE_HAS, O_GATE_N, O_GATE_S, O_N, O_NE_A,
    O_NE_B, O_NE_YY, O_NOISE, O_NOISE_N, O_OBS_IC, O_OBS_IN, O_OBS_KL, O_OBS_SGN, O_OBS_SOL, O_OBS_STEP, O_OUTLIERS,
    O_P_C, O_P_F, O_P_K, O_P_V, O_RES_COV, O_RES_E2, O_RES_HIST, O_RES_W, O_REST, O_RING, O_ROWS, O_ROWS_K, O_ROWS_O,
    O_SINCE_STEP, O_SLOW, O_SVF_C, O_SVF_F, O_SVF_K, O_SVF_O, O_TH_C, O_TH_F, O_TH_K, O_TH_O, O_TH_V, O_XH,
    OBS_STATE, RING, SG_HALF, STATE_SIZE, SVF_STATE,
)


def pack_state(ident) -> np.ndarray:
    """The state of a ``monitor.reference.NaiveIdentifier`` packed into a (STATE_SIZE,) row."""
    st = np.zeros(STATE_SIZE)
    st[O_N] = ident.n
    # the compiled kernel's ring is a shift register: slot j holds the sample j before the newest
    lags = (ident.n - 1 - np.arange(RING)) % RING
    st[O_RING:O_RING + RING * N_CH] = ident.ring[lags].ravel()
    st[O_SVF_F:O_SVF_F + 3 * SVF_STATE] = ident.svf_f.ravel()
    st[O_SVF_C:O_SVF_C + 10 * SVF_STATE] = ident.svf_c.ravel()
    st[O_TH_F:O_TH_F + 5], st[O_P_F:O_P_F + 25] = ident.th_f, ident.P_f.ravel()
    st[O_TH_C:O_TH_C + 4], st[O_P_C:O_P_C + 16] = ident.th_c, ident.P_c.ravel()
    st[O_TH_V:O_TH_V + 5], st[O_P_V:O_P_V + 25] = ident.th_v, ident.P_v.ravel()
    st[O_XH:O_XH + 2] = ident.xh
    st[O_ROWS:O_ROWS + 3] = ident.rows
    st[O_NOISE:O_NOISE + 4] = ident.noise
    st[O_NOISE_N] = ident.noise_n
    st[O_SLOW] = ident.slow
    st[O_REST] = ident.rest
    st[O_EXC_C] = ident.exc_c
    st[O_BC:O_BC + 3] = ident.bc
    st[O_RES_W:O_RES_W + N_STREAMS] = ident.res_w
    st[O_RES_E2:O_RES_E2 + N_STREAMS] = ident.res_e2
    st[O_RES_HIST:O_RES_HIST + N_STREAMS * N_LAGS] = ident.res_hist.ravel()
    st[O_RES_COV:O_RES_COV + N_STREAMS * N_LAGS] = ident.res_cov.ravel()
    for i, held in enumerate(ident.held):
        st[O_GATE + i * N_CH:O_GATE + (i + 1) * N_CH] = held
    st[O_GATE_HAS] = len(ident.held)
    st[O_GATE_S:O_GATE_S + 4], st[O_GATE_N] = ident.gate_s, ident.gate_n
    st[O_OUTLIERS:O_OUTLIERS + 4] = ident.outliers
    st[O_CLAMPED] = ident.clamped
    st[O_OBS_IN:O_OBS_IN + N_OBS * (SG_HALF + 1)] = ident.obs_in.ravel()
    st[O_SVF_O:O_SVF_O + N_OBS * OBS_STATE] = ident.svf_o.ravel()
    # the normal equations' upper triangle, packed by rows
    st[O_NE_A:O_NE_A + N_OBS_PARAMS * (N_OBS_PARAMS + 1) // 2] = ident.ne_a[np.triu_indices(N_OBS_PARAMS)]
    st[O_NE_B:O_NE_B + N_OBS_PARAMS] = ident.ne_b
    st[O_NE_YY] = ident.ne_yy
    st[O_TH_O:O_TH_O + N_OBS_PARAMS] = ident.th_o
    st[O_ROWS_O] = ident.rows_o
    st[O_OBS_SGN:O_OBS_SGN + 3] = ident.obs_sgn
    st[O_OBS_IC] = ident.obs_ic
    st[O_OBS_KL] = ident.obs_kl
    st[O_OBS_SOL:O_OBS_SOL + 4] = ident.obs_sol
    st[O_SVF_K:O_SVF_K + 2 * SVF_STATE] = ident.svf_k.ravel()
    st[O_TH_K:O_TH_K + 3], st[O_P_K:O_P_K + 9] = ident.th_k, ident.P_k.ravel()
    st[O_ROWS_K] = ident.rows_k
    st[O_SINCE_STEP] = ident.since_step
    st[O_OBS_STEP] = ident.obs_step
    return st
