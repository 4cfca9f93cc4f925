"""Rig constants, plant parameters and model effects: the one source of truth.

Everything is SI: m, m^2, m^3, Pa, N, kg, s, V. The defaults are the paper's
Table 1 (Lin et al. 2023) with A1 = 0.008 m^2 (the value consistent with the paper's other
constants and results) and f_v = 25 N s/m so that B + f_v = 6025, Table 2's true value.

The numerical core never sees these pydantic models: `plant_vector` flattens
them into one float64 array whose layout is given by the ``P_*`` indices, so a
fleet of rigs is a 2-D array ``(n_rigs, N_PARAMS)``.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from hydromon.contract.rig import RigConfig

__all__ = [
    "RigConfig",  # re-exported: the rig constants are the contract's
    "PlantParams",
    "Effects",
    "Controller",
    "plant_vector",
    "N_PARAMS",
    "EFFECT_NAMES",
]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PlantParams(_Model):
    """Physical parameters of the plant (the truth a simulation runs on).

    Attributes
    ----------
    m : float
        Moving mass [kg].
    B : float
        Viscous damping of piston and load [N s/m].
    K_t : float
        Load spring stiffness [N/m].
    beta_e : float
        Effective bulk modulus [Pa].
    rho : float
        Oil density [kg/m^3].
    C_d : float
        Orifice discharge coefficient [-].
    W : float
        Orifice area gradient [m].
    C_ip, C_ep : float
        Internal and external leakage coefficients [m^3/(s Pa)].
    K_sv : float
        Servo valve gain [m/V].
    omega_sv : float
        Servo valve natural frequency [rad/s].
    zeta_sv : float
        Servo valve damping ratio [-].
    f_c : float
        Coulomb friction [N].
    f_v : float
        Viscous friction [N s/m] (adds to B; the identifiable sum is B + f_v).
    """

    m: float = Field(120.0, gt=0)
    B: float = Field(6000.0, ge=0)
    K_t: float = Field(1e6, ge=0)
    beta_e: float = Field(7e8, gt=0)
    rho: float = Field(880.0, gt=0)
    C_d: float = Field(0.6, gt=0)
    W: float = Field(0.03, gt=0)
    C_ip: float = Field(3e-11, ge=0)
    C_ep: float = Field(0.0, ge=0)
    K_sv: float = Field(2.5e-4, gt=0)
    omega_sv: float = Field(100.0, gt=0)
    zeta_sv: float = Field(0.5, gt=0)
    f_c: float = Field(5.0, ge=0)
    f_v: float = Field(25.0, ge=0)

    @property
    def CdW_sqrt_rho(self) -> float:
        """The identified orifice parameter C_d W / sqrt(rho) [m^2.5/kg^0.5]."""
        return self.C_d * self.W / math.sqrt(self.rho)

    def identified(self) -> dict[str, float]:
        """The true values of the identified parameters, by their bus names (``contract.PARAM_NAMES``)."""
        w2 = self.omega_sv**2
        return {
            "m": self.m,
            "B_fv": self.B + self.f_v,
            "f_c": self.f_c,
            "K_t": self.K_t,
            "inv_beta_e": 1.0 / self.beta_e,
            "CdW_sqrt_rho": self.CdW_sqrt_rho,
            "C_ip": self.C_ip,
            "C_ep": self.C_ep,
            "two_zeta_omega": 2.0 * self.zeta_sv * self.omega_sv,
            "omega_sv2": w2,
            "K_sv_omega_sv2": self.K_sv * w2,
            "K_sv": self.K_sv,
        }


class Effects(_Model):
    """Physical effects beyond the paper's model; all off by default.

    Attributes
    ----------
    stribeck_F_s : float
        Stribeck peak above Coulomb friction [N]: F_f = sign(v)(f_c + F_s exp(-(v/v_s)^2)) + f_v v.
    stribeck_v_s : float
        Stribeck velocity [m/s].
    x_max : float
        Spool travel limit [m] (inf = none); the spool stops at +-x_max.
    dead_band : float
        Spool overlap [m]: no flow while |x_v| < dead_band.
    supply_sag : float
        Supply line resistance [Pa/(m^3/s)]: p_s,eff = p_s - R q_supply.
    air_fraction : float
        Entrained air volume fraction at atmospheric pressure [-]:
        1/beta_eff = 1/beta_e + eps p_atm / p^2 (isothermal air).
    load_offset : float
        Unknown constant external force beyond the configured F_L [N].
    sensor_delay : int
        Delay of the position measurement [samples].
    sensor_delay_in_loop : bool
        True: the controller's feedback sees the delayed position too (a slow sensor);
        False: only the recording is delayed (a logging/transport delay).
    seal_friction : float
        Pressure-loaded piston seal friction [m^2]: the differential pressure across the piston
        seal presses its lip on the bore, F_seal = c_p |p1 - p2| sign(v), c_p the lip's contact
        area times its friction coefficient (about 1e-4 m^2: 10 cm^2 at 0.1). Not one of the
        audit's named candidates (``EFFECT_NAMES``): an effect outside its library.
    """

    stribeck_F_s: float = Field(0.0, ge=0)
    stribeck_v_s: float = Field(0.01, gt=0)
    x_max: float = Field(math.inf, gt=0)
    dead_band: float = Field(0.0, ge=0)
    supply_sag: float = Field(0.0, ge=0)
    air_fraction: float = Field(0.0, ge=0, lt=1)
    load_offset: float = 0.0
    sensor_delay: int = Field(0, ge=0, le=1000)
    sensor_delay_in_loop: bool = False
    seal_friction: float = Field(0.0, ge=0)

    @model_validator(mode="after")
    def _finite(self) -> "Effects":
        for name in ("stribeck_F_s", "stribeck_v_s", "dead_band", "supply_sag", "load_offset", "seal_friction"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"effect {name} must be finite, got {getattr(self, name)!r}")
        return self


class Controller(_Model):
    """The rig's position controller, when it is not the proportional loop of the rig constants.

    ``RigConfig`` describes the loop a monitor assumes when a rig publishes no valve drive
    signal: ``u = K_p (ug - K_f x1)``, continuous. Real position loops are digital PI loops with
    feed-forward; with ``K_i`` or ``K_ff`` set the simulated rig runs one at its sample rate,
    its output held over each sample period (zero-order hold):

        e_k = ug_k - K_f y_k,   I_k = I_(k-1) + K_i h e_k,
        u_k = K_p (e_k + I_k) + K_ff (ug_k - ug_(k-1)) / h

    with y_k the fed-back position [m] and h the sample period [s]. Such a rig publishes its
    valve drive ``u`` [V] so that the monitor needs no model of its controller.

    Attributes
    ----------
    K_i : float
        Integral gain [1/s] (0: none).
    K_ff : float
        Feed-forward gain on the command's rate [s] (0: none).
    """

    K_i: float = Field(0.0, ge=0)
    K_ff: float = Field(0.0, ge=0)

    @property
    def digital(self) -> bool:
        """True when the loop is not the rig constants' continuous proportional one."""
        return self.K_i > 0.0 or self.K_ff > 0.0


EFFECT_NAMES = (
    "stribeck_friction",
    "valve_saturation",
    "valve_dead_band",
    "supply_pressure_sag",
    "entrained_air",
    "sensor_delay",
    "load_offset",
)

P_ATM = 101325.0  # [Pa]

# Layout of the flat parameter vector used by the numerical core.
(
    P_A1, P_A2, P_V10, P_V20, P_PS, P_FL, P_KP, P_KF,
    P_M, P_B, P_KT, P_BETA, P_CDW_RHO, P_CIP, P_CEP, P_KSV, P_WSV, P_ZSV, P_FC, P_FV,
    P_FS, P_VS, P_XMAX, P_DB, P_SAG, P_AIR, P_FOFF, P_KI, P_KFF, P_SEAL,
) = range(30)
N_PARAMS = 30


def plant_vector(config: RigConfig, params: PlantParams, effects: Effects | None = None,
                 controller: Controller | None = None) -> np.ndarray:
    """Flatten rig constants, plant parameters, effects and controller into the core's vector.

    Returns
    -------
    numpy.ndarray
        float64 array of length ``N_PARAMS``, indexed by the ``P_*`` constants (SI).
        The orifice enters as C_d W / sqrt(rho) [m^2.5/kg^0.5], the form the flow law uses.
    """
    e = effects or Effects()
    v = np.empty(N_PARAMS)
    v[P_A1], v[P_A2], v[P_V10], v[P_V20] = config.A1, config.A2, config.V10, config.V20
    v[P_PS], v[P_FL], v[P_KP], v[P_KF] = config.p_s, config.F_L, config.K_p, config.K_f
    v[P_M], v[P_B], v[P_KT], v[P_BETA] = params.m, params.B, params.K_t, params.beta_e
    v[P_CDW_RHO], v[P_CIP], v[P_CEP] = params.CdW_sqrt_rho, params.C_ip, params.C_ep
    v[P_KSV], v[P_WSV], v[P_ZSV] = params.K_sv, params.omega_sv, params.zeta_sv
    v[P_FC], v[P_FV] = params.f_c, params.f_v
    v[P_FS], v[P_VS], v[P_XMAX], v[P_DB] = e.stribeck_F_s, e.stribeck_v_s, e.x_max, e.dead_band
    v[P_SAG], v[P_AIR], v[P_FOFF], v[P_SEAL] = e.supply_sag, e.air_fraction, e.load_offset, e.seal_friction
    c = controller or Controller()
    v[P_KI], v[P_KFF] = c.K_i, c.K_ff
    return v
