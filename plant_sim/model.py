"""The valve-controlled asymmetric cylinder, paper eqs (1)-(22), as pure functions.

State ``x = [x1, x2, x3, x4, x5, x6] = [x_p [m], v_p [m/s], p_1 [Pa], p_2 [Pa], x_v [m], v_v [m/s]]``.
Parameters are the flat vector of :func:`plant_sim.params.plant_vector`.

Flow law (the paper's eqs 3-8, whose printed form is garbled)
--------------------------------------------------------------
A sharp-edged orifice of opening area ``W x_v`` passes the turbulent flow
``q = C_d W x_v sqrt(2 dp / rho)``. With ``theta = C_d W / sqrt(rho)`` (the parameter
the identification estimates, Table 2: 0.6 * 0.03 / sqrt(880) = 6.07e-4) this is
``q = theta x_v sqrt(2 dp)``: rho appears once, inside theta, and the square root
covers the whole pressure drop. For a spool moved right (x_v >= 0) the supply feeds
chamber 1 and chamber 2 drains to tank; moved left, the reverse:

    q1 = theta x_v z1,  z1 = sqrt(2 |p_s - p1|) sign(p_s - p1)   (x_v >= 0)
                           = sqrt(2 |p1|)                         (x_v < 0)
    q2 = theta x_v z2,  z2 = sqrt(2 |p2|)                         (x_v >= 0)
                           = sqrt(2 |p_s - p2|) sign(p_s - p2)   (x_v < 0)

q1 flows into chamber 1, q2 out of chamber 2 (both negative when x_v < 0). The
paper's ``sqrt((1 +- sign x_v)/rho)`` selects one branch and supplies the factor 2.

Effects (all off by default; see :class:`plant_sim.params.Effects`) enter as the
documented physical models: Stribeck friction, spool dead band (overlap), supply
pressure sag through a line resistance, entrained air lowering the bulk modulus at
low pressure, an unknown load offset, and a seal friction loaded by the differential
pressure. Spool saturation is a hard stop applied
by the integrator; sensor delay is a property of the measurement.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .params import (
    P_A1, P_A2, P_AIR, P_ATM, P_B, P_BETA, P_CDW_RHO, P_CEP, P_CIP, P_DB, P_FC, P_FL,
    P_FOFF, P_FS, P_FV, P_KF, P_KP, P_KSV, P_KT, P_M, P_PS, P_SAG, P_SEAL, P_V10, P_V20, P_VS,
    P_WSV, P_ZSV,
)

_P_MIN_AIR = 1e4  # [Pa] floor for the air term, which diverges at vacuum


@njit(cache=True)
def _sgn(v: float) -> float:
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@njit(cache=True)
def orifice_z(xv: float, p1: float, p2: float, ps: float) -> tuple:
    """Pressure factors ``(z1, z2)`` of the flow law [Pa^0.5]; ``q_i = theta x_v z_i``."""
    if xv >= 0.0:
        z1 = math.sqrt(2.0 * abs(ps - p1)) * _sgn(ps - p1)
        z2 = math.sqrt(2.0 * abs(p2))
    else:
        z1 = math.sqrt(2.0 * abs(p1))
        z2 = math.sqrt(2.0 * abs(ps - p2)) * _sgn(ps - p2)
    return z1, z2


@njit(cache=True)
def _sagged_supply_flow(a: float, dp: float, r: float) -> float:
    """Flow [m^3/s] through ``q = a sqrt(2 (dp - r q))``, the positive root."""
    a2 = a * a
    return -a2 * r + math.sqrt(a2 * a2 * r * r + 2.0 * a2 * dp)


@njit(cache=True)
def valve_flows(x5: float, x3: float, x4: float, p: np.ndarray) -> tuple:
    """Flows ``(q1 into chamber 1, q2 out of chamber 2)`` [m^3/s] for spool position x5 [m]."""
    theta = p[P_CDW_RHO]
    ps = p[P_PS]
    db = p[P_DB]
    xe = x5
    if db > 0.0:
        xe = _sgn(x5) * max(abs(x5) - db, 0.0)
    z1, z2 = orifice_z(xe, x3, x4, ps)
    q1 = theta * xe * z1
    q2 = theta * xe * z2
    r = p[P_SAG]
    if r > 0.0:
        # the supply-side orifice sees p_s - r q: solve the quadratic for q
        if xe > 0.0 and ps > x3:
            q1 = _sagged_supply_flow(theta * xe, ps - x3, r)
        elif xe < 0.0 and ps > x4:
            q2 = -_sagged_supply_flow(-theta * xe, ps - x4, r)
    return q1, q2


@njit(cache=True)
def inv_bulk_modulus(pressure: float, p: np.ndarray) -> float:
    """1/beta_eff [1/Pa]: oil plus isothermal entrained air, ``1/beta_e + eps p_atm / p^2``."""
    inv = 1.0 / p[P_BETA]
    eps = p[P_AIR]
    if eps > 0.0:
        pp = max(pressure, _P_MIN_AIR)
        inv += eps * P_ATM / (pp * pp)
    return inv


@njit(cache=True)
def friction(v: float, p: np.ndarray, dp: float = 0.0) -> float:
    """Friction force [N] at piston velocity v [m/s] (eq 15 with delta = 2, plus viscous f_v),
    plus the pressure-loaded seal friction c_p |dp| sign(v) for the differential pressure dp
    across the piston [Pa] (``Effects.seal_friction``)."""
    f = p[P_FV] * v + p[P_SEAL] * abs(dp) * _sgn(v)
    fs = p[P_FS]
    s = _sgn(v)
    if fs > 0.0:
        r = v / p[P_VS]
        return f + s * (p[P_FC] + fs * math.exp(-r * r))
    return f + s * p[P_FC]


@njit(cache=True)
def derivatives(x: np.ndarray, ug: float, x1_fb: float, p: np.ndarray, out: np.ndarray) -> None:
    """State derivative, paper eqs (16)-(21), written into ``out``.

    Parameters
    ----------
    x : array (6,)
        State [m, m/s, Pa, Pa, m, m/s].
    ug : float
        Command voltage [V].
    x1_fb : float
        Position the controller feeds back [m] (the state's own x1 unless the sensor lags).
    p : array (N_PARAMS,)
        Parameter vector (SI).
    """
    x1, x2, x3, x4, x5, x6 = x[0], x[1], x[2], x[3], x[4], x[5]
    a1, a2 = p[P_A1], p[P_A2]
    q1, q2 = valve_flows(x5, x3, x4, p)
    cip, cep = p[P_CIP], p[P_CEP]
    v1 = p[P_V10] + a1 * x1
    v2 = p[P_V20] - a2 * x1
    force = a1 * x3 - a2 * x4 - p[P_B] * x2 - p[P_KT] * x1 - friction(x2, p, x3 - x4) - p[P_FL] - p[P_FOFF]
    du = p[P_KP] * (ug - p[P_KF] * x1_fb)
    w = p[P_WSV]
    out[0] = x2
    out[1] = force / p[P_M]
    out[2] = (q1 - a1 * x2 - cip * (x3 - x4) - cep * x3) / (v1 * inv_bulk_modulus(x3, p))
    out[3] = (-q2 + a2 * x2 + cip * (x3 - x4) - cep * x4) / (v2 * inv_bulk_modulus(x4, p))
    out[4] = x6
    out[5] = -2.0 * p[P_ZSV] * w * x6 - w * w * x5 + p[P_KSV] * w * w * du


def null_state(p: np.ndarray, x1: float = 0.0) -> np.ndarray:
    """Initial state: piston at rest at x1 [m], spool centred, valve-null pressures.

    The pressures satisfy ``p1 + p2 = p_s`` (a critically lapped valve at null splits the
    supply) and ``A1 p1 - A2 p2 = F_L + K_t x1`` (force balance at rest). This is our
    documented choice; the paper gives no initial state.
    """
    a1, a2, ps = p[P_A1], p[P_A2], p[P_PS]
    load = p[P_FL] + p[P_FOFF] + p[P_KT] * x1
    p1 = (load + a2 * ps) / (a1 + a2)
    return np.array([x1, 0.0, p1, ps - p1, 0.0, 0.0])


def equilibrium_state(p: np.ndarray, x1: float = 0.0) -> np.ndarray:
    """A true equilibrium with centred spool at x1 [m], for a plant with C_ep = 0.

    With the valve closed, internal leakage equalises the chambers, so p1 = p2 = p and
    ``(A1 - A2) p = F_L + K_t x1``. The controller command that holds it is ``ug = K_f x1``.
    """
    if p[P_CEP] != 0.0:
        raise ValueError("equilibrium_state needs C_ep = 0 (external leakage drains the chambers)")
    pr = (p[P_FL] + p[P_FOFF] + p[P_KT] * x1) / (p[P_A1] - p[P_A2])
    return np.array([x1, 0.0, pr, pr, 0.0, 0.0])
