"""The audit's answer in words: the cause with its size and what it does, or why there is none.

Pure functions of a finished ranking (``monitor.audit.audit``): which parameters of an
identification are impossible and in which equation, what an unexplained residual looks like,
and the sentence a person acts on ("valve dead band about 5 um: spool overlap or wear at the
null"). SI inside; the words use the unit a technician reads (um, N, mm/s, %).
"""

from __future__ import annotations

import math

import numpy as np

from .candidates import StribeckFriction

__all__ = ["POSITIVE_AUDIT", "EQUATION_OF", "impossible_params", "residual_shape", "cause_words",
           "param_shift_words", "twin_words", "passed_over_words", "share_words"]

# Positive on every rig and pinned by the chamber and valve equations (the force balance's m
# and B + f_v are left out: an unmodelled load offset, one of the effects the audit names, drives
# the nominal B + f_v negative; monitor.plausibility)
POSITIVE_AUDIT = ("inv_beta_e", "CdW_sqrt_rho", "K_sv")
EQUATION_OF = {"inv_beta_e": "chamber", "CdW_sqrt_rho": "chamber", "K_sv": "valve"}
READABLE = {"inv_beta_e": "1/beta_e", "CdW_sqrt_rho": "C_d W/sqrt(rho)", "K_sv": "K_sv", "m": "m",
            "B_fv": "B + f_v", "f_c": "f_c", "K_t": "K_t", "C_ip": "C_ip", "C_ep": "C_ep",
            "omega_sv2": "omega_sv^2", "two_zeta_omega": "2 zeta omega", "K_sv_omega_sv2": "K_sv omega^2"}


def impossible_params(params: dict) -> list[str]:
    """The POSITIVE_AUDIT parameters of an identification [SI] that are not positive."""
    return [k for k in POSITIVE_AUDIT if params.get(k, 1.0) <= 0]  # NaN: unidentified, not impossible


def residual_shape(residual: np.ndarray, probes: dict) -> tuple[str, float]:
    """What a block's residual [its unit] looks like: the probe signal (name -> array on the same
    rows, any unit) it is most correlated with, and that correlation [-]; odd probes are
    compared with sign-carrying and even versions both (|v| for a friction that grows with
    speed either way)."""
    best = ("nothing it was compared with", 0.0)
    r = residual - residual.mean()
    rn = float(np.sqrt(np.dot(r, r)))
    if rn == 0:
        return best
    for name, x in probes.items():
        for label, y in ((name, x), (f"|{name}|", np.abs(x))):
            y = y - y.mean()
            yn = float(np.sqrt(np.dot(y, y)))
            if yn == 0:
                continue
            c = float(np.dot(r, y) / (rn * yn))
            if abs(c) > abs(best[1]):
                best = (label, c)
    return best


def _um(x):
    return f"{x * 1e6:.3g} um"


def cause_words(name: str, effect: dict, shares: dict | None = None) -> str:
    """The named cause in words and units, with what physically causes it."""
    e = effect
    if name == "valve_dead_band":
        return f"valve dead band about {_um(e['dead_band'])}: spool overlap or wear at the null"
    if name == "valve_saturation":
        return f"spool stops at +-{_um(e['x_max'])}: the valve reaches its end stop (travel limit or a blocked spool)"
    if name == "stribeck_friction":
        return (f"breakaway friction about {e['stribeck_F_s']:.0f} N above Coulomb, fading over "
                f"{1e3 * e['stribeck_v_s']:.0f} mm/s: seal stiction (dry or worn seals, poor lubrication)")
    if name == "supply_pressure_sag":
        return (f"supply pressure sags under flow, line resistance about {e['supply_sag']:.2g} Pa/(m^3/s): "
                "an undersized supply line, a clogged filter or a weak accumulator")
    if name == "entrained_air":
        return (f"entrained air about {100 * e['air_fraction']:.2g} % by volume: the oil is soft at low "
                "pressure (aerated oil, a suction leak or poor bleeding)")
    if name == "sensor_delay":
        where = "inside the control loop (a slow position sensor)" if e.get("sensor_delay_in_loop") \
            else "in the recording only (logging or transport delay)"
        return f"position recorded {e['sensor_delay']} sample(s) late, {where}"
    if name == "load_offset":
        return (f"a constant external force of {e['load_offset']:+.0f} N the rig constants do not know: "
                "a load, a spring preload or a gravity share not in F_L, or a pressure sensor's zero offset, which "
                "the force balance reads the same way (both pressures 1 bar low, as gauge pressures logged for "
                "absolute ones are, show as -(A1 - A2) x 1 bar)")
    return name


def param_shift_words(p_nom: dict, p_ext: dict, top: int = 2) -> str:
    """The nominal parameters the extension moved most [relative, %], in words."""
    rel = []
    for k, v in p_nom.items():
        w = p_ext.get(k)
        if k in ("C_ep", "K_sv_omega_sv2") or w is None or not (math.isfinite(v) and math.isfinite(w)) or v == 0:
            continue
        rel.append((abs(w - v) / abs(v), k, v, w))
    rel.sort(reverse=True)
    return ", ".join(f"{READABLE.get(k, k)} {v:.3g} -> {w:.3g}" for _, k, v, w in rel[:top])


def twin_words(c) -> str:
    """A candidate whose equation score the nominal model's twin matches, in words."""
    return (f"{c.name} scores {c.score + c.twin:.2f} on the equations, but {c.twin:.2f} of it on the nominal model's "
            "twin as well (its free run with this record's noise, which holds no effect): what the equations make "
            "of this rig's motion at this sample rate, not evidence of it")


def passed_over_words(c) -> str:
    """Why a candidate that scored above its threshold was not named."""
    head = f"{c.name} scores {c.score:.2f}"
    if not c.plausible and c.effect.get("stribeck_v_s", 0.0) > StribeckFriction.V_S_MAX:
        return (f"{head}, but its simulated hump fades over {1e3 * c.effect['stribeck_v_s']:.0f} mm/s: a friction "
                f"level, not a breakaway hump (at most {1e3 * StribeckFriction.V_S_MAX:.0f} mm/s)")
    if not c.plausible and "stribeck_v_s" in c.effect:
        return (f"{head}, but its simulated hump ({c.effect['stribeck_F_s']:.0f} N fading over "
                f"{1e3 * c.effect['stribeck_v_s']:.1f} mm/s) is no breakaway hump (F_s > 0, v_s of at least "
                f"{1e3 * StribeckFriction.V_S_MIN:g} mm/s)")
    if not c.plausible:
        return f"{head}, but its simulated extension is not the effect it stands for"
    if c.gain == -math.inf:
        return f"{head}, but its free run diverges"
    if math.isnan(c.gain):  # the nominal free run's error is not finite (a channel that never moves)
        return f"{head}, but its free run cannot be compared with the nominal model's, whose error is not finite"
    # the one reason left outside an impossible nominal fit (which is answered before this)
    return f"{head}, but its free run errs {1.0 - c.gain:.1f} times as much as the nominal model's"


def share_words(share: float) -> str:
    """A residual share beyond noise of an equation's held-out left side [-], in words. Above 1
    the model predicts the equation worse than its left side's mean would (the nominal chamber
    equation of records with entrained air at realistic noise in the fault band: 8-54 times on
    the held-out air ladders of 12300000 and 12500000), which a percentage hides."""
    if share <= 1.0:
        return f"leaves {100 * share:.0f} % of its variance unexplained"
    return (f"leaves a held-out residual {share:.3g} times the variance of its left side (beyond the sensor "
            "noise): the model predicts it worse than the left side's mean would")
