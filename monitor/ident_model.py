"""The fleet-wide constants the identification and read-out kernels read, as one record.

A module-level ``NamedTuple`` of arrays: numba types it field by field, compiled code reads
the fields by name at no cost, and ``cache=True`` finds the class again by its module.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class IdentModel(NamedTuple):
    """The identifier's constants for a sample period: hyperparameters, filter matrices and the
    filters' noise Gram matrices (built by ``monitor.ident_options.Kernels``)."""

    hyper: np.ndarray
    """(HYPER_SIZE,) the hyperparameter row (``monitor.layout`` H_*)."""
    m_f: np.ndarray
    """(3, 7) the force SVF, [Phi | G0 G1 G2 G3] (``monitor.svf``)."""
    m_c: np.ndarray
    """(3, 7) the chamber SVF."""
    m_o: np.ndarray
    """(4, 8) the observer filter H (``monitor.force_observer``)."""
    g_f: np.ndarray
    """(4, 4) noise Gram of the force SVF's [F, sF, s^2F] and the observer's sH [1, 1/s, 1/s^2, 1/s]."""
    g_c: np.ndarray
    """(3, 3) noise Gram of the chamber SVF's [F, sF, s^2F] [1, 1/s, 1/s^2]."""

    @staticmethod
    def of(kernels) -> IdentModel:
        """The record of a ``monitor.ident_options.Kernels``."""
        return IdentModel(kernels.hyper, kernels.m_f, kernels.m_c, kernels.m_o, kernels.g_f, kernels.g_c)
