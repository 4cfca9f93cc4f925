"""Scratch memory of the identifier's per-sample path, declared as a table of named regions.

The per-sample path allocates nothing: a kernel that consumes samples makes one ``Scratch``
(``new_scratch``) and every sample's rows, filter inputs and solver workspace go into it. The
1-D regions lie one after another in ``Scratch.work``, declared below as ``monitor.layout``
declares the state row; each ``W_*`` is the slice of its region (a module constant, so the
compiled kernels see literal bounds). No value is kept in it from one sample to the next.

The filter banks' outputs are 2-D and get arrays of their own: a 2-D view of a slice of
``work`` would call numba's reshape helper on every sample (~100 instructions a call).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .force_observer import FREE, N_OBS_PARAMS, N_PRIOR
from .layout import N_CH, N_CH_SVF, N_FORCE_SVF, N_OBS, OBS_ORDER

_REGIONS = [
    ("GATE", N_CH),  # the sample the outlier gate releases: ug, x1, x3, x4, x5
    ("PHI_V", 5),  # the valve ARX(2,3) row's regressors
    ("Z_V", 5),  # and its instruments
    ("RLS", 10),  # rls_update / riv_update workspace (riv_update takes 2 n, n = 5 for the valve)
    ("U_C", N_CH_SVF),  # the chamber filters' inputs at this sample
    ("PHI_C", 4),  # a chamber row's regressors
    ("U_F", N_FORCE_SVF),  # the force filters' inputs: x1, Q1, sign(x2)
    ("PHI_F", 5),  # the force row's regressors (the observer's row starts from them)
    ("U_K", 2),  # the static-gain filters' inputs: x5, du
    ("PHI_K", 3),  # the static-gain row's regressors
    ("PHI_O", N_OBS_PARAMS),  # the force row with observed pressures
    ("NE", N_PRIOR + len(FREE) * (len(FREE) + 1)),  # ne_update's workspace: psi, F_0 and the elimination
]

SCRATCH: dict[str, slice] = {}
_o = 0
for _name, _size in _REGIONS:
    SCRATCH[_name] = slice(_o, _o + _size)
    _o += _size
SCRATCH_SIZE = _o

W_GATE = SCRATCH["GATE"]
W_PHI_V = SCRATCH["PHI_V"]
W_Z_V = SCRATCH["Z_V"]
W_RLS = SCRATCH["RLS"]
W_U_C = SCRATCH["U_C"]
W_PHI_C = SCRATCH["PHI_C"]
W_U_F = SCRATCH["U_F"]
W_PHI_F = SCRATCH["PHI_F"]
W_U_K = SCRATCH["U_K"]
W_PHI_K = SCRATCH["PHI_K"]
W_PHI_O = SCRATCH["PHI_O"]
W_NE = SCRATCH["NE"]


class Scratch(NamedTuple):
    """The per-sample path's scratch arrays."""

    work: np.ndarray
    """(SCRATCH_SIZE,) the W_* regions."""
    y_f: np.ndarray
    """(N_FORCE_SVF, 3) the force filters' outputs [F u, sF u, s^2F u] of x1, Q1, sign(x2)."""
    y_c: np.ndarray
    """(N_CH_SVF, 3) the chamber filters' outputs."""
    y_o: np.ndarray
    """(N_OBS, OBS_ORDER) the observer filters' outputs [H u, sH u, s^2H u, s^3H u]."""
    y_k: np.ndarray
    """(2, 3) the static-gain filters' outputs of x5 and du."""


@njit(cache=True, error_model="numpy")
def new_scratch() -> Scratch:
    """Uninitialised scratch for one caller of the per-sample path."""
    return Scratch(np.empty(SCRATCH_SIZE), np.empty((N_FORCE_SVF, 3)), np.empty((N_CH_SVF, 3)),
                   np.empty((N_OBS, OBS_ORDER)), np.empty((2, 3)))
