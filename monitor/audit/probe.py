"""Structure beyond the named model: generic columns of measured signals no candidate has.

The nearest candidate of the library can soak up the mean of an effect outside it (a load offset
takes the constant part of a pressure sensor's gain error, Coulomb friction the mean of a friction
that grows with pressure) and leave the rest. ``probe_fits`` fits families of generic force-equation
columns beyond the named model and scores each as the audit scores a candidate (held-out log ratio
of the force equation's residual variance above the nominal fit's floors, less ``penalty`` per
column, and no better than 0 unless the training part improves too); the audit takes off what
the same family scores on the nominal model's twin (``monitor.audit.equations._twin``), and
``monitor.audit.decide`` says ``unexplained`` when one scores above its ``PROBE``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .residuals import Spec, build_blocks, fit_blocks, merge_specs

__all__ = ["PROBES", "probe_fits"]

PROBES = {
    "pressure": {"probe_1": lambda sig, cfg, x1, v, vs: np.ones_like(v),
                 "probe_pressure_level": lambda sig, cfg, x1, v, vs: cfg.A1 * sig.x3 + cfg.A2 * sig.x4},
    "friction": {"probe_1": lambda sig, cfg, x1, v, vs: np.ones_like(v),
                 "probe_sign_v_dp": lambda sig, cfg, x1, v, vs: np.sign(v) * cfg.A1 * np.abs(sig.x3 - sig.x4)},
}
"""Force-equation columns of measured signals that no candidate of the library has [N per unit],
in two families: a constant and the chamber pressure forces' sum A1 x3 + A2 x4 (with the left
side A1 x3 - A2 x4 it spans either chamber's pressure force: a pressure sensor's gain error; one
pressure direction only, or the left side itself would be a regressor), and sign(v) times the
pressure difference across the piston, A1 |x3 - x4| (a friction that grows with the pressure that
presses the piston seal on the bore). The friction family's pressure term is one column, not
one per chamber: x3 + x4 stays near the supply pressure, so sign(v) x3 and sign(v) x4 are nearly
collinear with Coulomb friction's sign(v), and fitted apart they extrapolate badly to the
held-out part (a seal friction on the paper's sine scored -0.05 as two columns, 1.5-2.3 as one)."""


def _force_mse(fit, split: int, floors: tuple[dict, dict]) -> tuple[float, float]:
    rows = fit.blocks["force"].rows
    return (fit.mse("force", rows < split, floors[0]["force"]),
            fit.mse("force", rows >= split, floors[1]["force"]))


def probe_fits(names, fits, sig, cfg, split, theta0, cache, nominal, floors, penalty) -> dict:
    """{family: (score, base fit, probe fit)} for each family of ``PROBES`` fitted beyond the
    named candidates ``names`` (``fits``: name -> (candidate, searched value, fit); the nominal
    model when ``names`` is empty). The friction family is fitted beyond a velocity-dependent
    friction as well (the Stribeck hump at its searched v_s), so that what it finds depends on
    pressure, not on speed."""
    spec = Spec()
    for n in names:
        c, v, _ = fits[n]
        spec = merge_specs(spec, c.spec(v)) or spec
    out = {}
    for family, cols in PROBES.items():
        sp = spec
        if family == "friction" and "stribeck_friction" in fits and "stribeck_friction" not in names:
            c, v, _ = fits["stribeck_friction"]
            sp = merge_specs(spec, c.spec(v)) or spec
        # a model with a load offset has the constant already (twice would be singular)
        cols = {k: fn for k, fn in cols.items() if not (k == "probe_1" and "F_off" in sp.force_cols)}
        try:
            base = fit_blocks(build_blocks(sig, cfg, sp, theta0), split, cfg.h, cache) if sp != Spec() else nominal
            f = fit_blocks(build_blocks(sig, cfg, replace(sp, force_cols={**sp.force_cols, **cols}), theta0),
                           split, cfg.h, cache)
        except (ValueError, np.linalg.LinAlgError):
            continue
        tr0, te0 = _force_mse(base, split, floors)
        tr, te = _force_mse(f, split, floors)
        score = math.log(te0 / te) - penalty * len(cols)
        if math.log(tr0 / tr) <= 0:
            score = min(score, 0.0)
        out[family] = (score, base, f)
    return out
