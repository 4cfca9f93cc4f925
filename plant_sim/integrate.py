"""Classical RK4 (paper eq 56) with internal substeps, for one rig or a fleet.

Accuracy (measured against 200 substeps, re-checked by
``tests/plant_sim/test_plant.py::test_substep_error_table``; paper identification input, 10 s; max abs
error over the run):

    substeps  x1 [m]    x2 [m/s]  p1 [Pa]   p2 [Pa]   x5 [m]    x6 [m/s]
    1         1.6e-5    1.8e-3    1.1e3     1.1e3     3.8e-6    4.7e-4   (h = 10 ms)
    4         4.4e-7    5.8e-5    2.4e1     1.5e1     9.4e-9    1.1e-6
    10        2.2e-7    2.5e-5    1.1e1     6.9e0     1.5e-9    1.3e-7
    20        7.7e-8    1.1e-5    3.9e0     2.5e0     5.7e-10   5.2e-8

One RK4 step per sample puts the spool 3.8 um off (7.7 times the realistic sensor noise).
Past 4 substeps the error falls only as 1/n, not n^-4: the Coulomb term sign(x2) and the
flow law's branch at x_v = 0 are discontinuous.

The default, 10 substeps (1 ms), keeps every channel's integration error at most 4 %
of the realistic sensor noise (x1 5 um, p 5 kPa, x5 0.5 um; x5 is 300 times below it),
so the data are the model's, not the integrator's. ``DEFAULT_SUBSTEPS`` is that choice.

The command ug is sampled by the caller at the 2*substeps+1 half-substep instants of
each sample interval (``ug_sub``), so profiles stay vectorised numpy and the loops here
stay compiled.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .model import derivatives
from .params import P_KF, P_KFF, P_KI, P_KP, P_XMAX

DEFAULT_SUBSTEPS = 10


@njit(cache=True)
def _clamp_spool(x: np.ndarray, xmax: float) -> None:
    # the spool stops at its end stop: position clipped, velocity into the stop zeroed
    if x[4] > xmax:
        x[4] = xmax
        if x[5] > 0.0:
            x[5] = 0.0
    elif x[4] < -xmax:
        x[4] = -xmax
        if x[5] < 0.0:
            x[5] = 0.0


@njit(cache=True)
def advance(x: np.ndarray, p: np.ndarray, ug_sub: np.ndarray, x1_fb: float, h: float, work: np.ndarray) -> None:
    """Advance state ``x`` (in place) by one sample period h [s] with RK4 substeps.

    Parameters
    ----------
    x : array (6,)
        State, updated in place.
    p : array (N_PARAMS,)
        Parameter vector.
    ug_sub : array (2 n + 1,)
        Command [V] at t, t + hs/2, t + hs, ..., t + h, with hs = h / n.
    x1_fb : float
        Fed-back position [m] held over the interval; NaN feeds back the live x1.
    work : array (5, 6)
        Scratch space.
    """
    n = (ug_sub.shape[0] - 1) // 2
    hs = h / n
    k1, k2, k3, k4, xt = work[0], work[1], work[2], work[3], work[4]
    live = math.isnan(x1_fb)
    xmax = p[P_XMAX]
    for j in range(n):
        u0, um, u1 = ug_sub[2 * j], ug_sub[2 * j + 1], ug_sub[2 * j + 2]
        derivatives(x, u0, x[0] if live else x1_fb, p, k1)
        for i in range(6):
            xt[i] = x[i] + 0.5 * hs * k1[i]
        derivatives(xt, um, xt[0] if live else x1_fb, p, k2)
        for i in range(6):
            xt[i] = x[i] + 0.5 * hs * k2[i]
        derivatives(xt, um, xt[0] if live else x1_fb, p, k3)
        for i in range(6):
            xt[i] = x[i] + hs * k3[i]
        derivatives(xt, u1, xt[0] if live else x1_fb, p, k4)
        for i in range(6):
            x[i] += hs / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        if xmax < np.inf:
            _clamp_spool(x, xmax)


@njit(cache=True)
def sample_step(x: np.ndarray, p: np.ndarray, ug_sub: np.ndarray, y: float, fb: float, ctrl: np.ndarray, h: float,
                work: np.ndarray, held: np.ndarray) -> float:
    """Advance ``x`` by one sample period under the rig's controller; return its valve drive [V].

    The proportional loop of the rig constants (``P_KI`` and ``P_KFF`` zero) acts continuously
    on the command ``ug_sub`` and the fed-back position ``fb`` (NaN: the live x1); its drive is
    reported at the sample instant, ``K_p (ug - K_f y)``. A digital PI loop with feed-forward
    (``plant_sim.params.Controller``) computes ``u_k`` once from the command at the sample
    instant and the position ``y`` [m] it measures there, and holds it over the period: it is
    passed to :func:`advance` as the command ``u_k / K_p + K_f y`` with ``y`` fed back, which
    gives the spool ``K_p (ug - K_f y) = u_k``. ``ctrl`` (2,) is the loop's state, updated in
    place: the integral [V] and the previous command [V] (NaN before the first sample).
    ``held`` (2 n + 1,) is scratch space.
    """
    kp, kf, ki, kff = p[P_KP], p[P_KF], p[P_KI], p[P_KFF]
    ug = ug_sub[0]
    if ki == 0.0 and kff == 0.0:
        advance(x, p, ug_sub, fb, h, work)
        return kp * (ug - kf * y)
    e = ug - kf * y
    ctrl[0] += ki * h * e
    prev = ug if math.isnan(ctrl[1]) else ctrl[1]
    ctrl[1] = ug
    u = kp * (e + ctrl[0]) + kff * (ug - prev) / h
    held[:] = u / kp + kf * y
    advance(x, p, held, y, h, work)
    return u


@njit(cache=True)
def run_fleet_drive(x0: np.ndarray, p: np.ndarray, ug_sub: np.ndarray, h: float, loop_delay: np.ndarray,
                    drive: np.ndarray) -> np.ndarray:
    """:func:`run_fleet`, also writing each rig's valve drive [V] of every sample period into
    ``drive`` (n_rigs, n_samples) (:func:`sample_step`)."""
    n_rigs, n_samples = ug_sub.shape[0], ug_sub.shape[1]
    out = np.empty((n_rigs, n_samples + 1, 6))
    work = np.empty((5, 6))
    held = np.empty(ug_sub.shape[2])
    ctrl = np.empty(2)
    x = np.empty(6)
    for r in range(n_rigs):
        x[:] = x0[r]
        out[r, 0] = x
        ctrl[0], ctrl[1] = 0.0, np.nan
        d = loop_delay[r]
        for k in range(n_samples):
            fb = np.nan
            y = x[0]
            if d > 0:
                fb = out[r, max(k - d, 0), 0]
                y = fb
            drive[r, k] = sample_step(x, p[r], ug_sub[r, k], y, fb, ctrl, h, work, held)
            out[r, k + 1] = x
    return out


@njit(cache=True)
def run_fleet(x0: np.ndarray, p: np.ndarray, ug_sub: np.ndarray, h: float, loop_delay: np.ndarray) -> np.ndarray:
    """Simulate ``n_rigs`` rigs for ``n_samples`` sample periods.

    Parameters
    ----------
    x0 : array (n_rigs, 6)
        Initial states.
    p : array (n_rigs, N_PARAMS)
        Parameter vectors.
    ug_sub : array (n_rigs, n_samples, 2 n + 1)
        Command at the half-substep instants of every interval [V].
    h : float
        Sample period [s].
    loop_delay : int array (n_rigs,)
        Samples by which the controller's position feedback lags (0 = live feedback).

    Returns
    -------
    array (n_rigs, n_samples + 1, 6)
        States at the sample instants, the initial state first.
    """
    return run_fleet_drive(x0, p, ug_sub, h, loop_delay, np.empty((ug_sub.shape[0], ug_sub.shape[1])))
