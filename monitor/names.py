"""The names the core computes in: the identified parameters and the five grades.

``PARAM_NAMES`` orders every parameter vector of the monitor (estimates, standard errors,
health payloads): m [kg], B_fv = B + f_v [N s/m], f_c [N], K_t [N/m], inv_beta_e [1/Pa],
CdW_sqrt_rho [m^2.5/kg^0.5], C_ip and C_ep [m^3/(s Pa)], two_zeta_omega [rad/s],
omega_sv2 [rad^2/s^2], K_sv_omega_sv2 [m/(V s^2)], K_sv [m/V] (the bus contract's names,
DESIGN.md 3; ``hydromon.contract`` re-exports them). ``GRADES`` are the paper's five levels,
0 health .. 4 fault, as the degradation model defines them.
"""

from plant_sim.degradation import GRADES

PARAM_NAMES = (
    "m", "B_fv", "f_c", "K_t", "inv_beta_e", "CdW_sqrt_rho", "C_ip", "C_ep",
    "two_zeta_omega", "omega_sv2", "K_sv_omega_sv2", "K_sv",
)

__all__ = ["PARAM_NAMES", "GRADES"]
