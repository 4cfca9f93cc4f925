"""A fleet of simulated rigs stepped forward in blocks of samples, for live publishing.

``PlantFleet.step(k)`` returns the next k samples of every rig. Stepping in blocks of any
sizes gives, bit for bit, the samples of one :func:`plant_sim.simulate.simulate_fleet`
call with the same rigs and seeds (``tests/plant_sim/test_live.py`` pins it):

- the integrator is :func:`plant_sim.integrate.sample_step`, called per sample by
  :func:`step_fleet` exactly as :func:`plant_sim.integrate.run_fleet` calls it; the
  fed-back and the measured position come from a ring buffer of past x1 instead of the
  whole state history, so the sensor delay (in the loop or in the recording only) acts
  as in ``simulate.py``;
- the command is sampled at the same half-substep instants ``(k + j/(2n)) h`` as
  :func:`plant_sim.simulate.command_grid`;
- the noise of each rig comes from one ``numpy.random.Generator`` seeded with the rig's
  seed and consumed in sample order through :func:`plant_sim.noise.add_noise` (which
  accepts a Generator: ``default_rng(g)`` returns ``g``), so blocks of any size draw
  the same numbers as one draw of the whole run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .integrate import DEFAULT_SUBSTEPS, sample_step
from .model import null_state
from .noise import NoiseModel, add_noise
from hydromon.contract import RigConfig
from .params import Controller, Effects, PlantParams, plant_vector
from .profiles import Profile

__all__ = ["PlantFleet", "Block", "step_fleet", "command_block"]


@njit(cache=True, nogil=True)
def step_fleet(x, p, ug_sub, h, k0, loop_delay, meas_delay, hist, x1_0, clean, states, ctrl, drive):
    """Emit samples k0 .. k0+k-1 of every rig and advance past them (``x``, ``hist`` in place).

    Parameters
    ----------
    x : array (n_rigs, 6)
        State at sample k0 [m, m/s, Pa, Pa, m, m/s]; on return, the state at k0 + k.
    p : array (n_rigs, N_PARAMS)
        Parameter vectors.
    ug_sub : array (n_rigs, k, 2 n + 1)
        Command [V] at the half-substep instants of intervals k0 .. k0+k-1.
    h : float
        Sample period [s].
    k0 : int
        Index of the first sample of the block.
    loop_delay, meas_delay : int arrays (n_rigs,)
        Samples by which the fed-back / the measured position lag (0 = none).
    hist : array (n_rigs, L)
        Ring of past x1 [m], sample s at ``s % L``; L > every delay.
    x1_0 : array (n_rigs,)
        x1 at sample 0 [m], what a delayed sensor shows before the delay has elapsed.
    clean : array (n_rigs, k, 4)
        Out: noise-free measured x1 [m], x3 [Pa], x4 [Pa], x5 [m] of each sample.
    states : array (n_rigs, k, 6)
        Out: true state at each sample.
    ctrl : array (n_rigs, 2)
        Each rig's controller state (``plant_sim.integrate.sample_step``), updated in place.
    drive : array (n_rigs, k)
        Out: the controller's valve drive [V] at each sample.
    """
    n, k = ug_sub.shape[0], ug_sub.shape[1]
    L = hist.shape[1]
    work = np.empty((5, 6))
    held = np.empty(ug_sub.shape[2])
    xr = np.empty(6)
    for r in range(n):
        xr[:] = x[r]
        dl, dm = loop_delay[r], meas_delay[r]
        for j in range(k):
            s = k0 + j
            hist[r, s % L] = xr[0]
            states[r, j] = xr
            src = s - dm
            clean[r, j, 0] = hist[r, src % L] if src >= 0 else x1_0[r]
            clean[r, j, 1] = xr[2]
            clean[r, j, 2] = xr[3]
            clean[r, j, 3] = xr[4]
            fb = np.nan  # live feedback, as run_fleet with delay 0
            y = xr[0]
            if dl > 0:
                src = s - dl
                fb = hist[r, src % L] if src >= 0 else x1_0[r]
                y = fb
            drive[r, j] = sample_step(xr, p[r], ug_sub[r, j], y, fb, ctrl[r], h, work, held)
        x[r] = xr


def command_block(profile: Profile, k0: int, k: int, h: float, substeps: int) -> np.ndarray:
    """ug [V] at the 2*substeps+1 half-substep instants of intervals k0 .. k0+k-1.

    The same instants, computed the same way, as :func:`plant_sim.simulate.command_grid`
    (which is this with k0 = 0).
    """
    frac = np.arange(2 * substeps + 1) / (2 * substeps)
    t = (np.arange(k0, k0 + k)[:, None] + frac[None, :]) * h
    return np.asarray(profile(t), dtype=float)


@dataclass(frozen=True)
class Block:
    """k consecutive samples of every rig of a fleet.

    Attributes
    ----------
    seq : int array (k,)
        Sample indices (from 0 at the start of the run).
    t : array (k,)
        Sample times [s], t = seq h.
    samples : array (n_rigs, k, 5)
        Bus channels ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] as measured (noise, delay).
    states : array (n_rigs, k, 6)
        True states [m, m/s, Pa, Pa, m, m/s].
    u : array (n_rigs, k)
        The controllers' valve drive [V] at each sample.
    """

    seq: np.ndarray
    t: np.ndarray
    samples: np.ndarray
    states: np.ndarray
    u: np.ndarray


def _per_rig(value, n: int, name: str) -> list:
    if isinstance(value, (list, tuple)):
        if len(value) != n:
            raise ValueError(f"{name}: {len(value)} given for {n} rigs")
        return list(value)
    return [value] * n


class PlantFleet:
    """N simulated rigs sharing one sample clock, stepped together.

    Parameters
    ----------
    config : RigConfig or list of RigConfig
        Rig constants, one for all or one per rig (all with the same sample_rate [Hz]).
    params_list : list of PlantParams
        The plant of each rig.
    profiles : list of Profile
        Command ug(t) [V] of each rig.
    effects_list : list of Effects, optional
        Effects of each rig (default none).
    noise : NoiseModel or list of NoiseModel, optional
        Measurement noise, one for all or one per rig (default none).
    seeds : list of int, optional
        Noise seed of each rig (default 0, 1, ..., as ``simulate_fleet``).
    substeps : int
        RK4 substeps per sample period.
    controllers : Controller or list of Controller, optional
        Each rig's position controller (default: the rig constants' proportional loop).
    """

    def __init__(self, config, params_list, profiles, effects_list=None, noise=None,
                 seeds=None, substeps: int = DEFAULT_SUBSTEPS, controllers=None):
        n = len(params_list)
        if n < 1:
            raise ValueError("a fleet needs at least one rig")
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps!r}")
        self.configs: list[RigConfig] = _per_rig(config, n, "config")
        rates = {c.sample_rate for c in self.configs}
        if len(rates) != 1:
            raise ValueError(f"rigs of one fleet share a sample rate, got {sorted(rates)} Hz")
        self.params: list[PlantParams] = list(params_list)
        self.profiles: list[Profile] = _per_rig(profiles, n, "profiles")
        self.effects: list[Effects] = _per_rig(effects_list if effects_list is not None else Effects(), n, "effects")
        self.noise: list[NoiseModel] = _per_rig(noise if noise is not None else NoiseModel(), n, "noise")
        self.seeds: list[int] = list(seeds) if seeds is not None else list(range(n))
        if len(self.seeds) != n:
            raise ValueError(f"seeds: {len(self.seeds)} given for {n} rigs")
        self.controllers: list[Controller] = _per_rig(controllers if controllers is not None else Controller(), n,
                                                      "controllers")
        self.substeps = int(substeps)
        self.h = self.configs[0].h
        self.vec = np.stack([plant_vector(c, p, e, k) for c, p, e, k in
                             zip(self.configs, self.params, self.effects, self.controllers)])
        self.ctrl = np.zeros((n, 2))
        self.ctrl[:, 1] = np.nan  # no command seen yet
        self.x = np.stack([null_state(v) for v in self.vec])
        self.x1_0 = self.x[:, 0].copy()
        self._set_delays()
        self.hist = np.zeros((n, self._ring_len()))
        self.rngs = [np.random.default_rng(s) for s in self.seeds]
        self.k = 0  # index of the next sample
        self._groups = None  # rigs grouped by equal profile, built on first step
        self._noise_ids: list[int] | None = None  # the noise models _noise_rows was built for
        self.config_rev = np.zeros(n, dtype=np.int64)  # bumped when a rig's config changes

    @property
    def n_rigs(self) -> int:
        return len(self.params)

    @property
    def t(self) -> float:
        """Time of the next sample [s]."""
        return self.k * self.h

    def _set_delays(self) -> None:
        self.meas_delay = np.array([e.sensor_delay for e in self.effects], dtype=np.int64)
        self.loop_delay = np.array([e.sensor_delay if e.sensor_delay_in_loop else 0 for e in self.effects],
                                   dtype=np.int64)

    def _ring_len(self) -> int:
        return int(self.meas_delay.max()) + 1

    def _profile_groups(self) -> list[tuple[Profile, np.ndarray]]:
        if self._groups is None:
            groups: dict = {}
            for i, pr in enumerate(self.profiles):
                try:
                    key = (type(pr), hash(pr), pr)
                except TypeError:  # an unhashable profile is its own group
                    key = ("id", id(pr))
                groups.setdefault(key, (pr, []))[1].append(i)
            self._groups = [(pr, np.array(idx)) for pr, idx in groups.values()]
        return self._groups

    def _noise_rows(self) -> tuple[np.ndarray, list[int]]:
        """(rows whose noise model is zero, rows with noise), rebuilt when ``self.noise`` changes
        (its models are frozen, so the same objects have the same ``is_zero``)."""
        ids = list(map(id, self.noise))
        if ids != self._noise_ids:
            zero = np.array([m.is_zero for m in self.noise], dtype=np.bool_)
            self._zero_rows, self._noisy_rows = np.flatnonzero(zero), np.flatnonzero(~zero).tolist()
            self._noise_ids = ids
        return self._zero_rows, self._noisy_rows

    def step(self, k: int) -> Block:
        """The next ``k`` samples of every rig (and advance the fleet past them)."""
        k = int(k)
        if k < 1:
            raise ValueError(f"step needs k >= 1 samples, got {k!r}")
        n, h, k0 = self.n_rigs, self.h, self.k
        seq = np.arange(k0, k0 + k)
        t = seq * h
        ug_sub = np.empty((n, k, 2 * self.substeps + 1))
        samples = np.empty((n, k, 5))
        for profile, rigs in self._profile_groups():  # each distinct profile evaluated once
            ug_sub[rigs] = command_block(profile, k0, k, h, self.substeps)
            samples[rigs, :, 0] = profile(t)
        clean = np.empty((n, k, 4))
        states = np.empty((n, k, 6))
        drive = np.empty((n, k))
        step_fleet(self.x, self.vec, ug_sub, h, k0, self.loop_delay, self.meas_delay, self.hist,
                   self.x1_0, clean, states, self.ctrl, drive)
        # rigs without noise at once: add_noise would return their clean rows and draw nothing
        # (one call per rig per block was about half of this method's time at 800 rigs)
        zero, noisy = self._noise_rows()
        if len(zero):
            samples[zero, :, 1:] = clean[zero]
        for r in noisy:
            samples[r, :, 1:] = add_noise(clean[r], self.noise[r], self.rngs[r])
        self.k = k0 + k
        return Block(seq=seq, t=t, samples=samples, states=states, u=drive)

    def set_rig(self, i: int, *, config: RigConfig | None = None, params: PlantParams | None = None,
                effects: Effects | None = None, profile: Profile | None = None) -> None:
        """Change rig ``i`` from the next sample on (a new plant, effects, constants or command).

        The state carries over; a new config bumps ``config_rev[i]`` so publishers resend it.
        """
        if not 0 <= i < self.n_rigs:
            raise ValueError(f"rig index {i!r} outside 0..{self.n_rigs - 1}")
        if config is not None:
            if config.sample_rate != self.configs[i].sample_rate:
                raise ValueError(f"config sample_rate {config.sample_rate} Hz differs from the fleet's "
                                 f"{self.configs[i].sample_rate} Hz")
            if config != self.configs[i]:
                self.config_rev[i] += 1
            self.configs[i] = config
        if params is not None:
            self.params[i] = params
        if profile is not None:
            self.profiles[i] = profile
            self._groups = None
        if effects is not None:
            self.effects[i] = effects
            old_len = self.hist.shape[1]
            self._set_delays()
            new_len = self._ring_len()
            if new_len > old_len:
                # re-lay the ring (sample s moves from s % old to s % new); positions older
                # than the old ring held repeat the oldest one kept
                hist = np.zeros((self.n_rigs, new_len))
                oldest = max(0, self.k - old_len)
                for s in range(max(0, self.k - new_len), self.k):
                    hist[:, s % new_len] = self.hist[:, max(s, oldest) % old_len]
                self.hist = hist
        self.vec[i] = plant_vector(self.configs[i], self.params[i], self.effects[i], self.controllers[i])
