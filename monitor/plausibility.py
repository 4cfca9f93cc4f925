"""Physically impossible estimates: the sign of input in wrong units, with the wrong sign or zero,
or under the wrong rig constants.

Mass, viscous damping, compressibility, the orifice coefficient and the valve's static gain are
positive on every rig. An estimate of one of them that is negative by more
than Z_IMPLAUSIBLE standard errors cannot come from sensor noise (with honest SEs, below
3e-5 per parameter even if the truth were 0); the record does not obey the model, so no grade
made from it is worth anything. Measured (10 s of a healthy rig): x1 in cm, x1 negated, x1
offset by 5 cm, pressures in bar or psi were each graded ``fault`` with confidence 0.8-1.0,
and each has such an estimate (K_sv -16 SE, m and B + f_v -5 to -19 SE, 1/beta_e -10 to
-200 SE); the same record in SI has none (the nearest, m, is +4.7 SE).

Friction, stiffness and the leakages are left out: their true value can be 0. So are the valve's
omega^2 and 2 zeta omega: a monitor joining a running rig cannot identify them and their SE
does not cover the error then (README, Known limits); over 59,760 converged evaluations of 60
random rigs (3 noise models, from rest and 3 s in, 20 s each) they were the only false alarm,
once (2 zeta omega -9.5 SE, mid-run, realistic noise); without them, none.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hydromon.contract import PARAM_NAMES

__all__ = ["POSITIVE", "Z_IMPLAUSIBLE", "implausible_mask", "implausible_names"]

POSITIVE = ("m", "B_fv", "inv_beta_e", "CdW_sqrt_rho", "K_sv")
Z_IMPLAUSIBLE = 4.0
_IDX = np.array([PARAM_NAMES.index(n) for n in POSITIVE])


def implausible_mask(params: np.ndarray, std_errors: np.ndarray) -> np.ndarray:
    """(n,) bool: rows of (n, len(PARAM_NAMES)) estimates and SEs [SI] with a POSITIVE parameter
    below -Z_IMPLAUSIBLE standard errors (an infinite or NaN SE never counts)."""
    v = params[:, _IDX]
    s = std_errors[:, _IDX]
    with np.errstate(invalid="ignore"):
        bad = np.isfinite(s) & (v < -Z_IMPLAUSIBLE * s)
    return bad.any(axis=1)


def implausible_names(params: Mapping[str, float], std_errors: Mapping[str, float]) -> tuple[str, ...]:
    """The POSITIVE parameters of one estimate [SI, by name] that are impossibly negative."""
    out = []
    for n in POSITIVE:
        v, s = params.get(n, np.nan), std_errors.get(n, np.inf)
        if np.isfinite(s) and v < -Z_IMPLAUSIBLE * s:
            out.append(n)
    return tuple(out)
