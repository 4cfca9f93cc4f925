"""Flat per-rig state layout of the identifier: one float64 row per rig.

A fleet's whole estimator state is one 2-D array ``(n_rigs, STATE_SIZE)``: it batches,
pickles and checkpoints as plain numbers. The ``O_*`` offsets are module constants so the
compiled kernels see them as literals.
"""

from __future__ import annotations

import hashlib

SG_HALF = 3  # half-width of the centred velocity window [samples]
RING = 2 * SG_HALF + 1
N_CH = 5  # ug, x1, x3, x4, x5
N_LAGS = 8  # residual autocorrelation lags used for honest standard errors
N_STREAMS = 6  # residual streams: force, chamber 1, chamber 2, valve, force with observed pressures, static gain
SVF_STATE = 6  # per filtered signal: the filter's 3 states and the last 3 inputs (monitor.svf)
N_FORCE_SVF = 3  # x1, Q1, sign(v)
N_CH_SVF = 10  # x3, x4, L1, L2, w1 x5 z1, w2 x5 z2, w1 dp, w2 dp, w1 x3, w2 x4 (monitor.identify)
N_OBS = 5  # Fm, Lc, G_theta, G_ip, G_ep (monitor.force_observer)
OBS_ORDER = 4  # the observer filter's states: its output and three derivatives
OBS_STATE = OBS_ORDER + 3  # per observer signal: its 4 states and the last 3 inputs

_FIELDS = [
    ("N", 1),  # samples since the last signal reset
    ("RING", RING * N_CH),
    ("SVF_F", N_FORCE_SVF * SVF_STATE),
    ("SVF_C", N_CH_SVF * SVF_STATE),
    ("TH_F", 5), ("P_F", 25),  # m, B + f_v, f_c, K_t and the constant force F_0
    ("TH_C", 4), ("P_C", 16),
    ("TH_V", 5), ("P_V", 25),
    ("XH", 2),  # auxiliary model output x5_hat(k-1), x5_hat(k-2) [scaled]
    ("ROWS", 3),  # rows taken by force, chamber, valve
    ("NOISE", 4),  # running mean of squared 4th differences of x1, x3, x4, x5
    ("NOISE_N", 1),
    ("SLOW", 1),  # samples since the piston was last near rest (|v| small)
    ("BC", 3),  # force weight sum, chamber sum of V1^2, sum of V2^2 (forgetting-weighted)
    ("RES_W", N_STREAMS), ("RES_E2", N_STREAMS),
    ("RES_HIST", N_STREAMS * N_LAGS), ("RES_COV", N_STREAMS * N_LAGS),
    ("GATE", 2 * N_CH),  # the two newest arrivals (older first), held for the outlier gate's lookahead
    ("GATE_HAS", 1),  # how many samples GATE holds (0, 1, 2)
    ("GATE_S", 4),  # running mean of squared centred 2nd differences of x1, x3, x4, x5
    ("GATE_N", 1),
    ("OUTLIERS", 4),  # samples the gate replaced, per sensor x1, x3, x4, x5
    ("CLAMPED", 1),  # samples whose x1 would have emptied a chamber (volume clamped, see identify)
    ("OBS_IN", N_OBS * (SG_HALF + 1)),  # its filters' inputs of the last SG_HALF + 1 samples (newest first)
    ("SVF_O", N_OBS * OBS_STATE),  # the force balance with observed pressures (monitor.force_observer)
    ("NE_A", 55), ("NE_B", 10), ("NE_YY", 1),  # its normal equations (A's upper triangle, packed by rows)
    ("TH_O", 10),  # the reference estimate its residual statistics are taken against
    ("OBS_SOL", 4),  # its latest solution's B + f_v, f_c and their variances (scaled; 0: none)
    ("OBS_IC", 1),  # e^(-w_c t) since its filters started: the start transient's regressor
    ("OBS_KL", 1),  # d Lc / d x1 = A1^2 / V1 + A2^2 / V2 [m] where its filters started (x1 noise in Lc)
    ("ROWS_O", 1),
    ("OBS_SGN", 3),  # its rows with F[sign(x2)] > 0, < 0, and the reference fits made (see force_observer)
    ("SVF_K", 2 * SVF_STATE),  # the valve's static gain: x5 and du through the force SVF (monitor.identify)
    ("TH_K", 3), ("P_K", 9),
    ("ROWS_K", 1),
    ("SINCE_STEP", 1),  # samples since a step in ug at the static-gain rows' instant
    ("REST", 1),  # samples in a row with the piston near rest (the chamber rows pause after H_REST)
    ("OBS_STEP", 1),  # samples since a step in ug for the observer rows (the start is not a step)
    ("EXC_C", 1),  # running mean square of the filtered pressure rates sF x3, sF x4 [Pa^2/s^2]
]

OFFSETS: dict[str, tuple[int, int]] = {}
_o = 0
for _name, _size in _FIELDS:
    OFFSETS[_name] = (_o, _size)
    _o += _size
STATE_SIZE = _o

O_N = OFFSETS["N"][0]
O_RING = OFFSETS["RING"][0]
O_SVF_F = OFFSETS["SVF_F"][0]
O_SVF_C = OFFSETS["SVF_C"][0]
O_TH_F = OFFSETS["TH_F"][0]
O_P_F = OFFSETS["P_F"][0]
O_TH_C = OFFSETS["TH_C"][0]
O_P_C = OFFSETS["P_C"][0]
O_TH_V = OFFSETS["TH_V"][0]
O_P_V = OFFSETS["P_V"][0]
O_XH = OFFSETS["XH"][0]
O_ROWS = OFFSETS["ROWS"][0]
O_NOISE = OFFSETS["NOISE"][0]
O_NOISE_N = OFFSETS["NOISE_N"][0]
O_SLOW = OFFSETS["SLOW"][0]
O_BC = OFFSETS["BC"][0]
O_RES_W = OFFSETS["RES_W"][0]
O_RES_E2 = OFFSETS["RES_E2"][0]
O_RES_HIST = OFFSETS["RES_HIST"][0]
O_RES_COV = OFFSETS["RES_COV"][0]
O_GATE = OFFSETS["GATE"][0]
O_GATE_HAS = OFFSETS["GATE_HAS"][0]
O_GATE_S = OFFSETS["GATE_S"][0]
O_GATE_N = OFFSETS["GATE_N"][0]
O_OUTLIERS = OFFSETS["OUTLIERS"][0]
O_CLAMPED = OFFSETS["CLAMPED"][0]
O_SVF_O = OFFSETS["SVF_O"][0]
O_OBS_IN = OFFSETS["OBS_IN"][0]
O_NE_A = OFFSETS["NE_A"][0]
O_NE_B = OFFSETS["NE_B"][0]
O_NE_YY = OFFSETS["NE_YY"][0]
O_TH_O = OFFSETS["TH_O"][0]
O_OBS_SGN = OFFSETS["OBS_SGN"][0]
O_OBS_SOL = OFFSETS["OBS_SOL"][0]
O_OBS_IC = OFFSETS["OBS_IC"][0]
O_OBS_KL = OFFSETS["OBS_KL"][0]
O_ROWS_O = OFFSETS["ROWS_O"][0]
O_SVF_K = OFFSETS["SVF_K"][0]
O_TH_K = OFFSETS["TH_K"][0]
O_P_K = OFFSETS["P_K"][0]
O_ROWS_K = OFFSETS["ROWS_K"][0]
O_SINCE_STEP = OFFSETS["SINCE_STEP"][0]
O_REST = OFFSETS["REST"][0]
O_EXC_C = OFFSETS["EXC_C"][0]
O_OBS_STEP = OFFSETS["OBS_STEP"][0]

# Per-rig constants row (SI): the rig config the equations need.
(C_A1, C_A2, C_V10, C_V20, C_PS, C_FL, C_KP, C_KF) = range(8)
RIG_CONST_SIZE = C_KF + 1

# Hyperparameter row shared by a fleet (see ident_options.IdentOptions).
(H_H, H_LAM, H_WARM, H_STEP_TOL, H_BC, H_IV, H_IV_START, H_P0, H_PMAX, H_NOISE_N, H_VSTICK, H_GUARD,
 H_GATE2, H_OBS, H_WC, H_WC_DECAY, H_STEP_GUARD, H_REST, H_REST_DECAY, H_OBS_STEP) = range(20)
HYPER_SIZE = H_OBS_STEP + 1

# The layout's version: a digest of every field's name and size, of the constants' and the
# hyperparameters' rows. Saved state (a monitor's checkpoint) records it, and state of another
# layout is refused rather than read into the wrong offsets; no one has to remember to bump it.
LAYOUT_VERSION = hashlib.sha256(repr((_FIELDS, RIG_CONST_SIZE, HYPER_SIZE)).encode()).hexdigest()[:16]
