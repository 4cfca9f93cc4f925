"""Free-run re-simulation of an identified model from the measured command, and its scores.

The identified parameters (bus names, ``hydromon.contract.PARAM_NAMES``) become a
``plant_sim`` plant: m, B = B_fv with f_v = 0, f_c, K_t, beta_e = 1/inv_beta_e,
C_d W/sqrt(rho) (C_d = 0.6, rho = 880 chosen, W solved), C_ip, C_ep,
omega_sv = sqrt(omega_sv2), zeta_sv = two_zeta_omega / (2 omega_sv),
K_sv (K_sv_omega_sv2 / omega_sv2 where it is missing). A value outside the physical domain (an
unidentifiable parameter, e.g. the mass of a piston that barely moves, estimated <= 0) takes the
fallback model's value when that one is valid, else the domain's edge; a mass below the smallest
one the integrator's step resolves (``stable_mass``) takes that one (each listed in
``FreeRun.clamped``). The run starts from the measured first sample and is driven by the
measured ug (linearly interpolated inside sample periods); nothing measured after t_0 enters it
except ug.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from plant_sim.integrate import DEFAULT_SUBSTEPS, run_fleet
from hydromon.contract import SENSORS
from hydromon.contract import RigConfig
from plant_sim.params import Effects, PlantParams, plant_vector
from plant_sim.profiles import FromFile
from plant_sim.simulate import command_grid

__all__ = ["FreeRun", "AT_FLOOR", "plant_from_params", "free_run", "channel_scores", "mean_nrmse", "free_run_gain",
           "output_error_fit", "stable_mass", "SENSORS"]

_RHO, _CD = 880.0, 0.6

AT_FLOOR = ("C_ip", "C_ep")
"""Parameters whose value below the domain's floor takes the floor, never the fallback's: a
leakage [m^3/(s Pa)] estimated a little below zero is no leakage read with noise, not a
parameter the record cannot identify. An extension's fit of a rig without external leakage
puts C_ep on either side of zero; where it fell below, the nominal model's C_ep
(raised by the very effect the extension explains: 2.8e-14 beside 4 % air and an 800 N load
offset) drained both chambers of the extension's free run, and the pair that fits that record
(C_ip 3.007e-11, true 3e-11) simulated its held-out part worse than the load offset alone
(mean NRMSE 0.076 against 0.049; 0.045 with C_ep = 0)."""


def plant_from_params(params: dict, fallback: dict | None = None) -> tuple[PlantParams, list[str]]:
    """PlantParams from identified parameters (SI, bus names); also the names clamped.

    An invalid value takes ``fallback[name]`` when that is valid (the nominal model's value for
    an extension's fit: a 1 kg floor for a mass estimated <= 0 made the free run so stiff that
    it diverged), else the domain's floor; a leakage (``AT_FLOOR``) always takes the floor.
    """
    clamped = []

    def pos(name, value, floor):
        if not (math.isfinite(value) and value >= floor):
            clamped.append(name)
            alt = None if fallback is None or name in AT_FLOOR else fallback.get(name)
            if alt is not None and math.isfinite(alt) and alt >= floor:
                return alt
            return floor
        return value

    w2 = pos("omega_sv2", params["omega_sv2"], 1.0)
    w = math.sqrt(w2)
    theta = pos("CdW_sqrt_rho", params["CdW_sqrt_rho"], 1e-6)
    p = PlantParams(
        m=pos("m", params["m"], 1.0),
        B=pos("B_fv", params["B_fv"], 0.0),
        f_v=0.0,
        f_c=pos("f_c", params["f_c"], 0.0),
        K_t=pos("K_t", params["K_t"], 0.0),
        beta_e=1.0 / pos("inv_beta_e", params["inv_beta_e"], 1e-11),
        rho=_RHO, C_d=_CD, W=theta * math.sqrt(_RHO) / _CD,
        C_ip=pos("C_ip", params["C_ip"], 0.0),
        C_ep=pos("C_ep", params["C_ep"], 0.0),
        omega_sv=w,
        zeta_sv=pos("two_zeta_omega", params["two_zeta_omega"], 1e-3 * w) / (2.0 * w),
        # the static gain where it was read out on its own (it stays right without excitation
        # at the valve's bandwidth, where K_sv omega^2 and omega^2 are off by the same factor)
        K_sv=pos("K_sv", params["K_sv"], 1e-13) if "K_sv" in params
        else pos("K_sv_omega_sv2", params["K_sv_omega_sv2"], 1e-9) / w2,
    )
    return p, clamped


# RK4's stability limits for a real pole (h lambda >= -2.785) and an undamped mode (h omega <= 2.828)
_RK4_REAL, _RK4_IMAG = 2.785, 2.828


def stable_mass(plant: PlantParams, config: RigConfig, dt: float) -> float:
    """The smallest moving mass [kg] whose mechanical poles an RK4 step of ``dt`` [s] integrates
    stably, with a margin of 2 on each: the viscous pole -(B + f_v)/m and the stiffest spring's
    frequency sqrt((K_oil + K_t)/m), K_oil = beta_e (A1^2/V10 + A2^2/V20) [N/m].

    A mass the identification cannot resolve (estimated <= 0 at fault-grade health, where the
    piston barely accelerates) gets a floor; 1 kg against 5700 N s/m of damping put the viscous
    pole at -5.7 per 1 ms step, and the free run of a right model diverged.
    """
    k = plant.beta_e * (config.A1 ** 2 / config.V10 + config.A2 ** 2 / config.V20) + plant.K_t
    return max(2.0 * (plant.B + plant.f_v) * dt / _RK4_REAL, k * (2.0 * dt / _RK4_IMAG) ** 2)


@dataclass(frozen=True)
class FreeRun:
    """A free-run simulation aligned with the record.

    ``measured`` is what the sensors would report (x1 [m], x3 [Pa], x4 [Pa], x5 [m]), with
    the recording delay of the effects applied to x1; ``clamped`` lists parameters that
    were outside their physical domain; ``diverged`` is True when the simulation left every
    physical range (then ``measured`` is clipped to it and means nothing).
    """

    measured: np.ndarray
    clamped: tuple
    diverged: bool


def free_run(samples: np.ndarray, config: RigConfig, params: dict, effects: Effects | None = None,
             v0: float = 0.0, substeps: int = DEFAULT_SUBSTEPS, fallback: dict | None = None) -> FreeRun:
    """Simulate the identified plant from the first measured sample, driven by the measured ug.

    Parameters
    ----------
    samples : array (N, 5)
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m].
    params : dict
        Identified parameters by bus name (SI).
    effects : Effects
        Model extension to simulate (default none).
    v0 : float
        Initial piston velocity [m/s].
    fallback : dict or None
        Parameters (bus names) replacing invalid ones, see :func:`plant_from_params`.
    """
    s = np.asarray(samples, dtype=float)
    n = len(s)
    plant, clamped = plant_from_params(params, fallback)
    m_min = stable_mass(plant, config, config.h / substeps)
    if plant.m < m_min:
        plant = plant.model_copy(update={"m": m_min})
        if "m" not in clamped:
            clamped.append("m")
    eff = effects or Effects()
    vec = plant_vector(config, plant, eff)
    h = config.h
    t = np.arange(n) * h
    grid = command_grid(FromFile(path="", t_data=t, u_data=s[:, 0]), n, h, substeps)
    x0 = np.array([s[0, 1], v0, s[0, 2], s[0, 3], s[0, 4], 0.0])
    delay = np.array([eff.sensor_delay if eff.sensor_delay_in_loop else 0], dtype=np.int64)
    with np.errstate(all="ignore"):
        st = run_fleet(x0[None, :], vec[None, :], grid[None], h, delay)[0][:n]
    out = st[:, [0, 2, 3, 4]].copy()
    d = eff.sensor_delay
    if d:
        out[:, 0] = np.concatenate([np.full(d, st[0, 0]), st[:-d, 0]])[:n]
    # diverged: non-finite, or beyond any physical range (1 m stroke, 1 GPa, 1 cm spool)
    limit = np.array([1.0, 1e9, 1e9, 1e-2])
    bad = not (np.all(np.isfinite(out)) and np.all(np.abs(out) <= limit))
    if bad:
        out = np.clip(np.where(np.isfinite(out), out, 0.0), -limit, limit)
    return FreeRun(measured=out, clamped=tuple(clamped), diverged=bad)


def channel_scores(measured: np.ndarray, simulated: np.ndarray, rows: slice | np.ndarray) -> dict:
    """Per channel over ``rows``: NRMSE (rms error / std of the measurement) and
    fit % = 100 (1 - ||e|| / ||y - mean y||)."""
    out = {}
    for i, name in enumerate(SENSORS):
        y = measured[rows, i]
        e = y - simulated[rows, i]
        sd = float(np.std(y))
        nrmse = float(np.sqrt(np.mean(e * e)) / sd) if sd > 0 else math.inf
        out[name] = {"nrmse": nrmse, "fit": 100.0 * (1.0 - nrmse)}
    return out


def mean_nrmse(scores: dict) -> float:
    """The channels' mean NRMSE [-] of ``channel_scores``."""
    return float(np.mean([scores[c]["nrmse"] for c in SENSORS]))


def free_run_gain(run: FreeRun, scores: dict, nominal_scores: dict) -> float:
    """Free-run gain [-]: 1 - the mean NRMSE of ``run`` (its ``scores``) over the nominal
    model's (``nominal_scores``); -inf when the run diverged."""
    return -math.inf if run.diverged else 1.0 - mean_nrmse(scores) / mean_nrmse(nominal_scores)


def output_error_fit(starts, to_model, samples: np.ndarray, config: RigConfig, rows: slice, v0: float,
                     fallback: dict | None = None, max_runs: int = 120):
    """The model whose free run errs least over ``rows`` of ``samples``: Nelder-Mead from each
    of ``starts`` (each evaluation one free run, ~6 ms for 30 s of record).

    ``to_model(x) -> (params, effects)`` maps a point of the search (e.g. logs of the refined
    parameters) to identified parameters (bus names, SI) and ``Effects`` fields; the run starts
    at the first sample with velocity ``v0`` [m/s]. Returns the best (params, effects, error):
    its mean NRMSE over ``rows`` [-] (1e3 when its run diverged).
    """
    measured = np.asarray(samples, dtype=float)[:, 1:]

    def cost(x):
        p_m, e_m = to_model(x)
        run = free_run(samples, config, p_m, Effects(**e_m), v0=v0, fallback=fallback)
        # a diverged run costs more than any run that stays in range (NRMSE ~ 0.01-1), finitely:
        # Nelder-Mead's simplex arithmetic needs finite values
        return 1e3 if run.diverged else mean_nrmse(channel_scores(measured, run.measured, rows))

    best = min((minimize(cost, x0, method="Nelder-Mead", options={"maxfev": max_runs, "xatol": 1e-3,
                                                                   "fatol": 1e-6}) for x0 in starts),
               key=lambda r: r.fun)
    return (*to_model(best.x), float(best.fun))
