"""Simulate rigs into sampled, measured runs: the pure entry point of plant_sim."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .integrate import DEFAULT_SUBSTEPS, run_fleet_drive
from .model import null_state
from .noise import NoiseModel, add_noise
from hydromon.contract import RigConfig
from .params import Controller, Effects, PlantParams, plant_vector
from .profiles import Profile

__all__ = ["Run", "simulate", "simulate_fleet", "command_grid"]


@dataclass(frozen=True)
class Run:
    """One simulated run sampled at the rig's rate.

    Attributes
    ----------
    t : array (N,)
        Sample times [s], t_k = k h.
    ug : array (N,)
        Command [V].
    states : array (N, 6)
        True states [m, m/s, Pa, Pa, m, m/s].
    measured : array (N, 4)
        What the sensors report: x1 [m], x3 [Pa], x4 [Pa], x5 [m] (noise, delay applied).
    u : array (N,)
        The controller's valve drive [V] at each sample (``plant_sim.integrate.sample_step``).
    """

    t: np.ndarray
    ug: np.ndarray
    states: np.ndarray
    measured: np.ndarray
    config: RigConfig
    params: PlantParams
    effects: Effects
    noise: NoiseModel
    seed: int
    u: np.ndarray | None = None
    controller: Controller = Controller()

    @property
    def samples(self) -> np.ndarray:
        """(N, 5) array of the bus channels ``ug, x1, x3, x4, x5`` (SI)."""
        return np.column_stack([self.ug, self.measured])


def command_grid(profile: Profile, n_samples: int, h: float, substeps: int) -> np.ndarray:
    """ug [V] at the 2*substeps+1 half-substep instants of each of n_samples-1 intervals."""
    frac = np.arange(2 * substeps + 1) / (2 * substeps)
    t = (np.arange(n_samples - 1)[:, None] + frac[None, :]) * h
    return np.asarray(profile(t), dtype=float)


def _measure(states: np.ndarray, effects: Effects, noise: NoiseModel, seed: int) -> np.ndarray:
    clean = states[:, [0, 2, 3, 4]].copy()
    d = effects.sensor_delay
    if d:
        clean[:, 0] = np.concatenate([np.full(d, states[0, 0]), states[:-d, 0]])[: len(states)]
    return add_noise(clean, noise, seed)


def simulate_fleet(
    config: RigConfig,
    params: list[PlantParams],
    profiles: list[Profile],
    duration: float,
    effects: list[Effects] | None = None,
    noise: NoiseModel | None = None,
    seeds: list[int] | None = None,
    substeps: int = DEFAULT_SUBSTEPS,
    controllers: list[Controller] | None = None,
) -> list[Run]:
    """Simulate several rigs of one config for ``duration`` [s]; one compiled loop for all."""
    n = len(params)
    if len(profiles) != n:
        raise ValueError("one profile per rig")
    effects = effects or [Effects()] * n
    seeds = seeds if seeds is not None else list(range(n))
    noise = noise or NoiseModel()
    if duration <= 0 or substeps < 1:
        raise ValueError("duration must be > 0 and substeps >= 1")
    h = config.h
    n_samples = int(round(duration / h))
    if n_samples < 2:
        raise ValueError(f"duration {duration} s gives fewer than 2 samples at {config.sample_rate} Hz")
    controllers = controllers or [Controller()] * n
    vec = np.stack([plant_vector(config, p, e, c) for p, e, c in zip(params, effects, controllers)])
    x0 = np.stack([null_state(v) for v in vec])
    # one interval more than the samples need, for the controller's drive at the last sample
    grid = np.stack([command_grid(pr, n_samples + 1, h, substeps) for pr in profiles])
    delay = np.array([e.sensor_delay if e.sensor_delay_in_loop else 0 for e in effects], dtype=np.int64)
    drive = np.empty((n, n_samples))
    states = run_fleet_drive(x0, vec, grid, h, delay, drive)[:, :n_samples]
    t = np.arange(n_samples) * h
    runs = []
    for i in range(n):
        ug = profiles[i](t)
        st = states[i]
        runs.append(Run(t=t, ug=ug, states=st, measured=_measure(st, effects[i], noise, seeds[i]),
                        config=config, params=params[i], effects=effects[i], noise=noise, seed=seeds[i],
                        u=drive[i], controller=controllers[i]))
    return runs


def simulate(
    profile: Profile,
    duration: float,
    params: PlantParams | None = None,
    config: RigConfig | None = None,
    effects: Effects | None = None,
    noise: NoiseModel | None = None,
    seed: int = 0,
    substeps: int = DEFAULT_SUBSTEPS,
    controller: Controller | None = None,
) -> Run:
    """Simulate one rig from the null state (``model.null_state``) for ``duration`` [s]."""
    return simulate_fleet(config or RigConfig(), [params or PlantParams()], [profile], duration,
                          [effects or Effects()], noise, [seed], substeps, [controller or Controller()])[0]
