"""Rigs that are not the reference rig: seeded draws of a rig's own constants and healthy plant,
for the commissioning tests and sweeps.

Every quantity is drawn around the reference rig's (Table 1) by a factor or a range that covers
industrial servo cylinders of the same kind: piston area 0.4-2.5x (A1 0.0032-0.02 m^2, area ratio
1.4-2.5), chamber volumes with the area, supply 8-21 MPa, load 2-8 % of A1 p_s, mass 40-600 kg,
viscous damping 2,000-20,000 N s/m, load stiffness 0.3-3 MN/m, bulk modulus 0.5-1.2 GPa, valve
gain, bandwidth and damping, orifice gradient, friction and leakage each by its own factor. The
controller gain is then chosen so the position loop's velocity gain K_p K_f K_sv K_q / A1 lies in
1.5-4 1/s (the reference rig's is 2.6 1/s), so every rig follows its command as a tuned rig
does; a rig whose loop gain were left to chance would either barely move or oscillate.
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import RigConfig

from .params import PlantParams

__all__ = ["random_rig"]


def _loop_gain(config: RigConfig, plant: PlantParams, k_p: float = 1.0) -> float:
    """The position loop's velocity gain [1/s] at valve opening flow gain for half the supply."""
    k_q = plant.CdW_sqrt_rho * math.sqrt(config.p_s)  # [m^2/s per m of spool]
    return k_p * config.K_f * plant.K_sv * k_q / config.A1


def random_rig(rng: np.random.Generator) -> tuple[RigConfig, PlantParams]:
    """A rig's constants and its healthy plant, drawn with ``rng`` (module docstring)."""
    ref_c, ref_p = RigConfig(), PlantParams()
    area = ref_c.A1 * rng.uniform(0.4, 2.5)
    ratio = rng.uniform(1.4, 2.5)
    p_s = rng.uniform(8e6, 21e6)
    config = RigConfig(
        A1=area, A2=area / ratio,
        V10=ref_c.V10 * area / ref_c.A1 * rng.uniform(0.7, 1.3),
        V20=ref_c.V20 * area / ref_c.A1 / ratio * 2.0 * rng.uniform(0.7, 1.3),
        p_s=p_s, F_L=area * p_s * rng.uniform(0.02, 0.08),
        p_span=p_s,
    )
    plant = PlantParams(
        m=rng.uniform(40.0, 600.0),
        B=rng.uniform(2000.0, 20000.0),
        K_t=math.exp(rng.uniform(math.log(3e5), math.log(3e6))),
        beta_e=rng.uniform(5e8, 1.2e9),
        W=ref_p.W * rng.uniform(0.5, 2.0),
        C_ip=ref_p.C_ip * rng.uniform(0.3, 1.5),
        K_sv=ref_p.K_sv * rng.uniform(0.4, 1.6),
        omega_sv=rng.uniform(60.0, 160.0),
        zeta_sv=rng.uniform(0.4, 0.8),
        f_c=ref_p.f_c * rng.uniform(0.5, 6.0),
        f_v=ref_p.f_v * rng.uniform(0.5, 4.0),
    )
    k_p = rng.uniform(1.5, 4.0) / _loop_gain(config, plant)
    return config.model_copy(update={"K_p": k_p}), plant
