"""Physically impossible estimates: the sign of input in wrong units, of the wrong sign, or taken
under the wrong rig constants.

Compressibility (1/beta_e), the orifice coefficient (C_d W/sqrt(rho)) and the valve's static
gain are positive on every rig, and the chamber and valve equations pin them to better than 1 %
at realistic noise. An estimate of one of them that is negative by more than Z_IMPLAUSIBLE
standard errors cannot come from sensor noise (with honest SEs, below 3e-5 even if the truth
were 0): the record does not obey the model, so no grade made from it is worth anything.
Measured (10 s of a healthy rig): x1 in cm, x1 negated, pressures in bar or psi were each graded
``fault`` with confidence 0.8-1.0, and each has such an estimate (1/beta_e -10 to -200 SE,
K_sv -16 SE); the same record in SI has none.

Left out: friction, stiffness and the leakages (their true value can be 0); the valve's omega^2
and 2 zeta omega (a monitor joining a running rig cannot identify them and their SE does not
cover the error then: one false alarm in 59,760 evaluations, docs/limits.md); and the
force balance's m and B + f_v: an external load the config's F_L does not know (300-1500 N,
a real rig's weight on a vertical cylinder) drives B + f_v below -4 SE in 138 of 300
evaluations of one record, on a rig whose input is right. So a wrong x1 zero (5 cm: B + f_v
-5 SE, every other parameter plausible) is not caught here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from hydromon.contract import PARAM_NAMES

__all__ = ["POSITIVE", "Z_IMPLAUSIBLE", "any_impossible", "impossible", "implausible_names"]

POSITIVE = ("inv_beta_e", "CdW_sqrt_rho", "K_sv")
Z_IMPLAUSIBLE = 4.0
_IDX = tuple(PARAM_NAMES.index(n) for n in POSITIVE)


@njit(cache=True)
def impossible(v: float, s: float) -> bool:
    """The rule: an estimate below -Z_IMPLAUSIBLE standard errors (an infinite or NaN SE never counts)."""
    return math.isfinite(s) and v < -Z_IMPLAUSIBLE * s


@njit(cache=True)
def any_impossible(params, std_errors) -> bool:
    """One rig's (len(PARAM_NAMES),) estimates and SEs [SI]: a POSITIVE parameter is impossibly
    negative (the fleet kernel then leaves the rig ungraded and its hysteresis state as it was)."""
    for i in _IDX:
        if impossible(params[i], std_errors[i]):
            return True
    return False


def implausible_names(params: Mapping[str, float], std_errors: Mapping[str, float]) -> tuple[str, ...]:
    """The POSITIVE parameters of one estimate [SI, by name] that are impossibly negative."""
    return tuple(n for n in POSITIVE if impossible(float(params.get(n, np.nan)), float(std_errors.get(n, np.inf))))
