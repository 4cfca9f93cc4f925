"""One severity in [0, 1] that moves the variable parameters through the paper's five grades.

The paper (section 4) varies C_d, W, rho, K_sv, C_ip, C_ep, f_c and f_v and grades the
identified K_sv omega^2, C_d W / sqrt(rho), f_c, B + f_v, C_ip and C_ep against Table 3.
Severity s is split into five equal bands, in grade order: [0, 0.2) health,
[0.2, 0.4) sub-health, [0.4, 0.6) average, [0.6, 0.8) deterioration, [0.8, 1] fault.
Inside a band each graded parameter moves linearly between that band's Table 3 bounds,
so a rig at severity s has every parameter in the band of s and its true grade is the
band of s. C_d W / sqrt(rho), for which Table 3 only says "falls", follows knots
through the paper's Table 4 values. The leakages stay at 3e-11 and 0 below the fault
band and take Table 3's fault values 3e-10 inside it.
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import GRADES, RigConfig

from .params import PlantParams

# Table 3 bounds at s = 0, 0.2, 0.4, 0.6, 0.8, 1.0 (band edges), SI.
KNOTS_S = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
K_SV_OMEGA2 = np.array([2.6, 2.2, 1.7, 1.4, 1.0, 0.5])  # [m/(V s^2)]
F_C = np.array([4.0, 10.0, 20.0, 45.0, 75.0, 120.0])  # [N]
B_FV = np.array([6020.0, 6075.0, 6150.0, 6250.0, 6400.0, 6600.0])  # [N s/m]
CDW_SQRT_RHO = np.array([6.07e-4, 5.60e-4, 5.15e-4, 4.75e-4, 4.35e-4, 3.60e-4])
LEAK_HEALTHY = (3e-11, 0.0)
LEAK_FAULT = (3e-10, 3e-10)


def grade_of_severity(severity: float) -> str:
    """The true grade of a rig degraded to ``severity``."""
    _check(severity)
    return GRADES[min(int(severity / 0.2), 4)]


def _check(severity: float) -> None:
    if not (0.0 <= severity <= 1.0):
        raise ValueError(f"severity must lie in [0, 1], got {severity!r}")


def degrade(severity: float, base: PlantParams | None = None, **overrides: float) -> PlantParams:
    """Plant parameters at ``severity`` in [0, 1], with per-parameter overrides.

    Parameters
    ----------
    severity : float
        0 = new, 1 = worst fault.
    base : PlantParams
        Invariant parameters (m, B, K_t, beta_e, rho, C_d, omega_sv, zeta_sv) come from here;
        default the paper's Table 1.
    **overrides : float
        Any PlantParams field, applied last (e.g. ``f_c=30``).
    """
    _check(severity)
    base = base or PlantParams()
    w2 = base.omega_sv**2
    cdw = float(np.interp(severity, KNOTS_S, CDW_SQRT_RHO))
    c_ip, c_ep = LEAK_FAULT if severity >= 0.8 else LEAK_HEALTHY
    values = dict(
        K_sv=float(np.interp(severity, KNOTS_S, K_SV_OMEGA2)) / w2,
        f_c=float(np.interp(severity, KNOTS_S, F_C)),
        f_v=float(np.interp(severity, KNOTS_S, B_FV)) - base.B,
        # C_d W / sqrt(rho) falls through the orifice width W (wear shows as lost gain)
        W=cdw * base.rho**0.5 / base.C_d,
        C_ip=c_ip,
        C_ep=c_ep,
    )
    values.update(overrides)
    return base.model_copy(update=values)


# the reference rig's healthy values the knots are relative to (Table 1: K_sv omega^2 = 2.5,
# f_c = 5 N, B + f_v = 6025 N s/m, C_d W / sqrt(rho) = 6.07e-4, C_ip = 3e-11, C_ep = 0)
_REFERENCE = PlantParams()


def leak_scale(cdw_sqrt_rho: float, k_sv: float, p_s: float) -> float:
    """How much larger a leakage coefficient must be on this rig than on the reference rig to
    do the same harm [-]: the leakage flow at supply pressure against the valve's flow.

    A leakage C [m^3/(s Pa)] passes ~C p_s; the valve passes ~(C_d W / sqrt(rho)) K_sv u
    sqrt(p_s) for a drive u; the piston stops moving when the first is a fixed share of the
    second, so equal harm means C proportional to (C_d W / sqrt(rho)) K_sv / sqrt(p_s).
    ``cdw_sqrt_rho`` [m^2.5/kg^0.5], ``k_sv`` [m/V], ``p_s`` [Pa] of the rig; 1 for the reference.
    """
    ref = _REFERENCE.CdW_sqrt_rho * _REFERENCE.K_sv / math.sqrt(RigConfig().p_s)
    return cdw_sqrt_rho * k_sv / math.sqrt(p_s) / ref


def degrade_relative(severity: float, base: PlantParams, config: RigConfig | None = None) -> PlantParams:
    """``base`` (a rig's own healthy plant) degraded to ``severity`` in [0, 1] as the reference
    rig degrades from its own: each degrading parameter times its knot's ratio to the
    reference's healthy value (K_sv, f_c, C_d W / sqrt(rho); B + f_v through f_v), the leakages
    at the reference's fault values scaled by :func:`leak_scale` in the fault band.

    On the reference plant (Table 1) it gives :func:`degrade`'s plant, up to rounding.
    ``config`` gives the supply pressure for the leakage scale (default: the reference rig's).
    """
    _check(severity)
    config = config or RigConfig()
    ref = _REFERENCE
    ratio = lambda knots, value: float(np.interp(severity, KNOTS_S, knots)) / value  # noqa: E731
    b_fv = (base.B + base.f_v) * ratio(B_FV, ref.B + ref.f_v)
    cdw = base.CdW_sqrt_rho * ratio(CDW_SQRT_RHO, ref.CdW_sqrt_rho)
    if severity >= 0.8:
        scale = leak_scale(base.CdW_sqrt_rho, base.K_sv, config.p_s)
        c_ip, c_ep = LEAK_FAULT[0] * scale, LEAK_FAULT[1] * scale
    else:
        c_ip, c_ep = base.C_ip, base.C_ep
    return base.model_copy(update=dict(
        K_sv=base.K_sv * ratio(K_SV_OMEGA2 / ref.omega_sv**2, ref.K_sv),
        f_c=base.f_c * ratio(F_C, ref.f_c),
        f_v=b_fv - base.B,
        W=cdw * base.rho**0.5 / base.C_d,
        C_ip=c_ip,
        C_ep=c_ep,
    ))


def table4_group(group: int) -> PlantParams:
    """The plant of the paper's Table 4 group 1..5 (its estimates taken as the truth)."""
    rows = {
        1: (1.96, 5.51e-4, 14.64, 6098.00, 2.94e-11, 8.68e-13),
        2: (2.49, 5.70e-4, 4.67, 6021.31, 3.01e-11, 2.45e-13),
        3: (0.79, 3.74e-4, 99.48, 6496.67, 29.15e-11, 3010e-13),
        4: (1.6, 4.74e-4, 29.78, 6183.32, 2.99e-11, 2.06e-13),
        5: (1.19, 4.75e-4, 60.44, 6297.15, 3.03e-11, 3.20e-13),
    }
    if group not in rows:
        raise ValueError(f"Table 4 has groups 1..5, not {group!r}")
    k, cdw, fc, bfv, cip, cep = rows[group]
    base = PlantParams()
    return base.model_copy(update=dict(
        K_sv=k / base.omega_sv**2, W=cdw * base.rho**0.5 / base.C_d, f_c=fc,
        f_v=bfv - base.B, C_ip=cip, C_ep=cep,
    ))


TABLE4_PAPER_GRADES = {1: "sub-health", 2: "health", 3: "fault", 4: "average", 5: "deterioration"}
