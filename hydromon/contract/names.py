"""The names hydromon computes and publishes in: parameters with their units, grades, channels.

``PARAM_UNITS`` is the one table of the identified parameters and their SI units; its order is
the order of every parameter vector of the monitor (estimates, standard errors, health
payloads). ``GRADES`` are the five health levels, 0 health .. 4 fault.
"""

from __future__ import annotations

__all__ = ["PARAM_UNITS", "PARAM_NAMES", "PARAM_WORDS", "GRADES", "UNKNOWN", "CHANNELS", "SENSORS"]

PARAM_UNITS = {
    "m": "kg",                          # moving mass
    "B_fv": "N s/m",                    # viscous damping B plus viscous friction f_v
    "f_c": "N",                         # Coulomb friction
    "K_t": "N/m",                       # load spring stiffness
    "inv_beta_e": "1/Pa",               # compressibility 1/beta_e
    "CdW_sqrt_rho": "m^2.5/kg^0.5",     # orifice coefficient C_d W / sqrt(rho)
    "C_ip": "m^3/(s Pa)",               # internal leakage coefficient
    "C_ep": "m^3/(s Pa)",               # external leakage coefficient
    "two_zeta_omega": "rad/s",          # valve: 2 zeta_sv omega_sv
    "omega_sv2": "rad^2/s^2",           # valve: omega_sv^2
    "K_sv_omega_sv2": "m/(V s^2)",      # valve: K_sv omega_sv^2
    "K_sv": "m/V",                      # valve static gain
}
PARAM_NAMES = tuple(PARAM_UNITS)

PARAM_WORDS = {
    "m": "moving mass",
    "B_fv": "viscous damping",
    "f_c": "Coulomb friction",
    "K_t": "load stiffness",
    "inv_beta_e": "oil compressibility",
    "CdW_sqrt_rho": "valve orifice coefficient",
    "C_ip": "internal leakage",
    "C_ep": "external leakage",
    "two_zeta_omega": "valve damping",
    "omega_sv2": "valve bandwidth",
    "K_sv_omega_sv2": "valve gain times bandwidth",
    "K_sv": "valve gain",
}
"""What each parameter is, in the words of a maintenance engineer."""

GRADES = ("health", "sub-health", "average", "deterioration", "fault")
UNKNOWN = "unknown"
"""The grade of a rig that cannot be placed (level -1)."""

CHANNELS = ("ug", "x1", "x3", "x4", "x5")
"""A sample's signals: command ug [V], piston position x1 [m], chamber pressures x3, x4 [Pa],
spool position x5 [m]."""
SENSORS = CHANNELS[1:]
"""The measured ones (sensor noise, the outlier gate, the audit's scores)."""
