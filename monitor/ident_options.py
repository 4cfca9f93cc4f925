"""The identifier's options (``IdentOptions``) and the per-rig rows they set up: the fleet-wide
hyperparameter row (``Kernels``), a rig's constant row and a fresh state row (``monitor.layout``).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit
from pydantic import BaseModel, ConfigDict, Field

from hydromon.contract import RigConfig

from .layout import (
    C_A1,
    C_A2,
    C_FL,
    C_KF,
    C_KP,
    C_PS,
    C_V10,
    C_V20,
    H_BC,
    H_GATE2,
    H_GUARD,
    H_H,
    H_IV,
    H_IV_START,
    H_LAM,
    H_NOISE_N,
    H_OBS,
    H_P0,
    H_PMAX,
    H_STEP_TOL,
    H_VSTICK,
    H_WARM,
    H_WC,
    H_WC_DECAY,
    H_STEP_GUARD,
    H_REST,
    H_REST_DECAY,
    H_OBS_STEP,
    HYPER_SIZE,
    O_GATE_HAS,
    O_N,
    O_P_C,
    O_P_F,
    O_P_K,
    O_P_V,
    RIG_CONST_SIZE,
    STATE_SIZE,
)
from .force_observer import force_noise_gram, obs_matrices
from .svf import noise_gram, svf_matrices


# The static-gain rows' filter memory must hold no step in ug: the cubic through a step is not the
# step, and its transient ~ (a t)^2 e^(-a t) is 2 % at 0.1 s and 3e-5 at 0.2 s (a = 80 rad/s).
STEP_GUARD = 0.2  # [s]


class IdentOptions(BaseModel):
    """Hyperparameters of the identifier (shared by a fleet).

    Attributes
    ----------
    a_force, a_chamber : float
        SVF bandwidths [rad/s] of the force and chamber equations.
    lam : float
        Forgetting factor per sample (1 = growing window; 0.9995 ~ 20 s memory at 100 Hz).
    warmup : float
        Filter settling time before rows are used [s]. The filters start as if each signal
        had been constant forever; a rig already moving (or a kink in the first samples)
        leaves a transient ~ (a t)^2 e^(-a t) in the rows. Measured noise-free on the paper's
        input: chamber filters started 30 ms into the run left C_d W/sqrt(rho) -0.024 % off
        after 0.4 s (0.001 % after 0.8 s), but waiting 0.8 s costs a fifth of the accuracy
        under noise (the start from rest is the best-excited part of the run), so 0.4 s.
    step_tol : float
        |second difference of ug| [V] above which a valve row is skipped as a step.
    bias_compensation, instrumental_variables : bool
        Our noise fixes (off = plain least squares on the same filtered rows).
    iv_start : int
        Valve rows of plain least squares before the IV takes over (its auxiliary model needs
        a first estimate). Their x5-noise bias stays in the estimate: measured on 10 s that
        start mid-run (no start from rest to excite the spool; paper's input, realistic
        noise), 100 such rows gave K_sv omega^2 146 % off with the truth outside +-3 SE on
        every seed, 30 rows 93 % off with it inside on 9 of 10; from rest 0.27 -> 0.31 %.
    p0, p_max : float
        Initial covariance (a weak prior) and anti-windup trace bound, scaled units.
    noise_window : int
        Samples averaged by the online sensor-noise estimate.
    min_rows : int
        Rows every equation needs before the estimate counts as converged.
    v_stick : float
        Piston speed [m/s] below which it counts as near rest (a reversal or sticking), where
        the Coulomb term sign(x2) is not what the friction does; raised to 3 velocity-noise
        sigmas when the sensor is noisier.
    reversal_guard : float
        Time after a near-rest instant whose force rows are skipped [s] (the filter's memory).
    pressure_observer : bool
        Also identify the force balance with observed pressures (``monitor.force_observer``):
        the chamber equations predict the pressures' fast changes, the sensors their slow part;
        the read-out takes, per parameter of the force balance, whichever of the two estimates
        has the smaller standard error. Off: the force balance on the measured pressures only.
    rest_pause : float
        The chamber rows pause while the rig rests: the piston below the v_stick threshold (as
        for the force rows) for this long [s], and the filtered pressure rates sF x3, sF x4 no
        larger than their sensor noise makes them (their mean square over the same time under
        monitor.identify.REST_EXCITATION times the noise's); 0 = never. At rest the rows carry
        sensor noise and constants only, and errors in variables pull the estimates for as long
        as the rest lasts: measured (paper's input for 10 s, then ug held at 2 V for 1000 s,
        realistic noise, seed 1) without the pause 1/beta_e went 32 % low, C_d W/sqrt(rho) and
        C_ip 22 %, 78-89 standard errors; with it they stay where the moving part left them.
        The pressure condition keeps the rows of a piston that barely moves while its pressures
        swing (the fault-grade leakages of Table 4 at stress noise: a still piston alone paused
        37-54 % of their rows). On the five built-in profiles (20 s, 5 seeds, each noise model)
        and Table 4's groups it pauses no row.
    observer_step_guard : float
        Time [s] after a step in ug (its second difference above step_tol) whose rows the
        force balance on observed pressures skips (the start of the record is not a step):
        1 / observer_crossover, the memory of its slow pole, through which a step's fast
        pressure transient reaches the rows. Measured (`--profile steps`, healthy rig, realistic
        noise, 20 s, 10 seeds): without it B + f_v 2.7 % mean error, 9.1 % (6.7 SE) on seed 3,
        graded `fault`; with it 2.1 %, 10/10 inside +-3 SE, all `health`. The paper's, chirp and
        multisine inputs never step (unchanged); paper-var 1.83 -> 1.88 %.
    observer_crossover : float
        The observer's crossover w_c [rad/s]: below it the measured pressures count, above it
        the chamber model's. 2 rad/s is where the pressure noise (5 kPa) and the integrated
        spool-position noise (0.5 um) cost alike at realistic noise (docs/method.md).
    outlier_gate : float
        Sensor glitches: a sample of x1, x3, x4 or x5 that jumps away from both neighbours,
        with a centred second difference above outlier_gate times the channel's running rms
        of it, is replaced by its neighbours' mean and counted (0 = off); a burst of two on
        x1, x3 or x4 goes onto the line between its neighbours (see ``_gate``). Every sample
        waits two samples for its right neighbours. Measured (paper's input, realistic noise, 20 s):
        one x3 sample 30 MPa off left the chamber parameters 66-98 % off for good, and one
        x1 sample 5 cm off graded a healthy rig `fault`.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    a_force: float = Field(80.0, gt=0)
    a_chamber: float = Field(25.0, gt=0)
    lam: float = Field(1.0, gt=0, le=1)
    warmup: float = Field(0.4, ge=0)
    step_tol: float = Field(0.1, gt=0)
    bias_compensation: bool = True
    instrumental_variables: bool = True
    iv_start: int = Field(30, ge=10)
    p0: float = Field(1e9, gt=0)
    p_max: float = Field(1e13, gt=0)
    noise_window: int = Field(2000, ge=10)
    min_rows: int = Field(300, ge=1)
    v_stick: float = Field(2e-3, ge=0)
    reversal_guard: float = Field(0.1, ge=0)
    outlier_gate: float = Field(10.0, ge=0)
    pressure_observer: bool = True
    observer_crossover: float = Field(2.0, gt=0)
    rest_pause: float = Field(0.5, ge=0)
    observer_step_guard: float = Field(0.5, ge=0)

    def memory_s(self, sample_rate: float) -> float | None:
        """The estimators' memory [s] at ``sample_rate`` [Hz]: the S of ``lam = exp(-1 / (S rate))``
        (``--memory S``), to 6 significant digits (lam, a double near 1, holds S to about
        S rate 1e-16 relative: 1e-8 for a day at 1 kHz); None for lam = 1 (a growing window)."""
        if self.lam >= 1.0:
            return None
        return float(f"{-1.0 / (sample_rate * math.log(self.lam)):.6g}")


@functools.lru_cache(maxsize=16)
def _filters(options: IdentOptions, h: float) -> tuple:
    """The filter matrices and noise grams for these options at sample period h [s]: m_f, m_c, m_o,
    g_f (4, 4: [F, sF, s^2F] and the observer's sH), g_c. Pure, so cached: computed without BLAS
    (monitor.svf) they take ~45 ms, and every Fleet and Pipeline builds them (the bench's
    core_single builds one a pass: 116,000 -> 60,000 samples/s uncached)."""
    m_f = svf_matrices(options.a_force, h)
    m_c = svf_matrices(options.a_chamber, h)
    m_o = obs_matrices(options.a_force, options.observer_crossover, h)
    return m_f, m_c, m_o, force_noise_gram(m_f, m_o), noise_gram(m_c)


class Kernels:
    """Fleet-wide constant arrays derived from the options and sample period h [s]."""

    def __init__(self, options: IdentOptions, h: float):
        self.options = options
        self.h = h
        # copies: every fleet owns its arrays, though the kernels only read them
        self.m_f, self.m_c, self.m_o, self.g_f, self.g_c = (a.copy() for a in _filters(options, h))
        hy = np.zeros(HYPER_SIZE)
        hy[H_H] = h
        hy[H_LAM] = options.lam
        hy[H_WARM] = math.ceil(options.warmup / h)
        hy[H_STEP_TOL] = options.step_tol
        hy[H_BC] = 1.0 if options.bias_compensation else 0.0
        hy[H_IV] = 1.0 if options.instrumental_variables else 0.0
        hy[H_IV_START] = options.iv_start
        hy[H_P0] = options.p0
        hy[H_PMAX] = options.p_max
        hy[H_NOISE_N] = options.noise_window
        hy[H_VSTICK] = options.v_stick
        hy[H_GUARD] = math.ceil(options.reversal_guard / h)
        hy[H_GATE2] = options.outlier_gate ** 2
        hy[H_OBS] = 1.0 if options.pressure_observer else 0.0
        hy[H_WC] = options.observer_crossover
        hy[H_WC_DECAY] = math.exp(-options.observer_crossover * h)
        hy[H_STEP_GUARD] = math.ceil(STEP_GUARD / h)
        hy[H_REST] = math.ceil(options.rest_pause / h)
        hy[H_OBS_STEP] = math.ceil(options.observer_step_guard / h)
        hy[H_REST_DECAY] = math.exp(-h / options.rest_pause) if options.rest_pause > 0 else 0.0
        self.hyper = hy


def rig_constants(config: RigConfig) -> np.ndarray:
    """The per-rig constant row (SI) of ``monitor.layout``."""
    c = np.empty(RIG_CONST_SIZE)
    c[C_A1], c[C_A2], c[C_V10], c[C_V20] = config.A1, config.A2, config.V10, config.V20
    c[C_PS], c[C_FL], c[C_KP], c[C_KF] = config.p_s, config.F_L, config.K_p, config.K_f
    return c


def new_state(hyper: np.ndarray) -> np.ndarray:
    """A fresh rig state row: no samples, weak prior P0 = p0 I."""
    st = np.zeros(STATE_SIZE)
    reset_estimates(st, hyper)
    return st


@njit(cache=True, error_model="numpy")
def reset_estimates(st: np.ndarray, hyper: np.ndarray) -> None:
    """Forget all estimates (theta = 0, P = p0 I) and statistics; keeps nothing."""
    st[:] = 0.0
    p0 = hyper[H_P0]
    for i in range(5):
        st[O_P_F + 6 * i] = p0
    for i in range(4):
        st[O_P_C + 5 * i] = p0
    for i in range(5):
        st[O_P_V + 6 * i] = p0
    for i in range(3):
        st[O_P_K + 4 * i] = p0



@njit(cache=True, error_model="numpy")
def reset_signals(st: np.ndarray) -> None:
    """Restart the signal path (after a gap): filters re-initialise, estimates are kept.

    The samples the outlier gate holds are dropped: their right neighbours are on the far side
    of the gap.
    """
    st[O_N] = 0.0
    st[O_GATE_HAS] = 0.0
