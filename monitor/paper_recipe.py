"""The paper's literal identification recipe (section 3), kept to compare with ours.

T-D derivatives (``monitor.td``, Han's tracking differentiator, the paper's r = 100 and
h0 = 0.05 by default) feed the paper's regressors, eqs (24)-(42), and plain recursive
least squares (``monitor.rls.rls_step``, paper eqs 46-54 with Lambda = 1):

    (24) A1 x3 - A2 x4 - F_L = [x2', x2, sign(x2), x1] . [m, B + f_v, f_c, K_t]
    (38) -A1 x2 = [(V10 + A1 x1) x3', -x5 z1, x3 - x4, x3] . [1/beta_e, C_d W/sqrt(rho), C_ip, C_ep]
          A2 x2 = [(V20 - A2 x1) x4',  x5 z2, -(x3 - x4), x4] . (same)
    (39) -x6' = [x6, x5, -K_p (ug - K_f x1)] . [2 zeta omega, omega^2, K_sv omega^2]

with z1, z2 the orifice factors of ``plant_sim.model.orifice_z`` (the printed eqs 31 and
36 are garbled; ``plant_sim/model.py`` derives the flow law). The paper's form of the valve
equation, with the noisiest signal (a second T-D derivative of x5) as the target, is kept on
purpose.

What we changed, and why (documented departures, not new methods):

* **Scale per channel.** fhan is homogeneous, so the T-D runs on x / S (S = the sensor
  span, ``monitor.td.config_scales``): r = 100 tuned for signals of order 1 would freeze
  on pressures in Pa.
* **Delay alignment.** The paper pushes first derivatives back one sample and second
  ones two. The T-D's real lag is 2 h0/h - 1 = 9 samples for h0 = 0.05, h = 0.01
  (``monitor.td`` docstring), and its gain at 1 Hz is 0.92, so a raw signal next to a
  T-D derivative is both 9 samples early and 8 % too large: a bias of that order on every
  parameter. We therefore take every column of an equation from the SAME T-D chain: a
  first-order equation (the chambers) uses one T-D stage for every signal (its value
  output for x1, x3, x4, x5 z_i, its derivative for x2, x3', x4'), a second-order one
  (force, valve) two stages (value of value for positions, forces and du, value of the
  derivative for x2, x6, derivative of the derivative for x2', x6'). The gains then match
  and what is left is the relative lag of a derivative output to its value output:
  ``td_lag`` measures 0.5 samples per stage (value lag 9.0 vs derivative lag 8.5), so a
  first-derivative column is averaged over two adjacent samples (shift 1/2) and a second
  derivative is shifted one sample. sign(x2) is not linear, so it cannot share the
  chain: it is the sign of the one-stage velocity passed through two more stages, and the
  other force columns are delayed by the one-stage value lag (9 samples) to match. With
  sign(x2) of the two-stage velocity instead (the direct reading of eq 26) the noise-free
  Table 2 case gives B + f_v +3.2 % and f_c -83 %; with this, +0.01 % and +1.4 %.
* **Warm-up.** The start (x1 = 0 while the command asks for 0.05 m) is a jump that drives
  every T-D off its linear band; rows before 1 s are skipped (at 0.5 s the valve
  parameters are still -20 % off, the chain's double pole at 1/h0 = 20 rad/s has not
  forgotten the jump).
* **Scaled columns.** The regressors are divided by nominal magnitudes so every RLS
  parameter is O(1) (the parameters span 1e-11 .. 1e6); this is conditioning only.

Offline over an (N, 5) array; the chain is causal, so a streaming version would give the
same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from hydromon.contract import PARAM_NAMES
from plant_sim.model import orifice_z
from hydromon.contract import RigConfig

from .rls import rls_step
from .td import config_scales, td_filter, td_lag

__all__ = ["PaperRecipe", "PaperResult", "identify_paper", "paper_regressors"]

# nominal magnitudes: column j of an equation is phi_j * nom_j / y_nom (theta scaled to O(1))
_NOM_F = np.array([100.0, 1e4, 10.0, 1e6])
_YNOM_F = 1e4
_NOM_C = np.array([1e-9, 1e-3, 1e-11, 1e-11])
_YNOM_C = 1e-3
_NOM_V = np.array([100.0, 1e4, 1.0])
_YNOM_V = 1.0  # valve rows are first divided by the x5 span (identify_paper)
SIGN_SCALE = 100.0  # T-D scale of the sign column [-]: a jump of 2 is 0.02, linear


@dataclass(frozen=True)
class PaperRecipe:
    """Hyperparameters of the paper's recipe.

    Attributes
    ----------
    r : float
        T-D acceleration limit on x / scale [1/s^2] (paper: 100).
    h0 : float
        T-D filter factor [s] (paper: 0.05).
    warmup : float
        Time skipped at the start while the T-D chain settles [s].
    p0 : float
        Initial covariance P0 = p0 I of every RLS (scaled parameters).
    omega : float
        Fastest tracked motion [rad/s], sets the scale of the second-stage T-Ds
        (``monitor.td.config_scales``).
    du_scale : float or None
        T-D scale of the valve input K_p (ug - K_f x1) [V]; None: K_p K_f x1_span, the
        feedback voltage at full stroke (on the paper's input a scale of 1 V drives this
        T-D out of its linear band and biases the valve parameters by -90 %).
    """

    r: float = 100.0
    h0: float = 0.05
    warmup: float = 1.0
    p0: float = 1e8
    omega: float = 2.0 * np.pi * 2.5
    du_scale: float | None = None

    def __post_init__(self):
        for name in ("r", "h0", "p0", "omega", "du_scale"):
            v = getattr(self, name)
            if v is None and name == "du_scale":
                continue
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"PaperRecipe.{name} must be finite and > 0, got {v!r}")
        if not (np.isfinite(self.warmup) and self.warmup >= 0):
            raise ValueError(f"PaperRecipe.warmup must be >= 0 [s], got {self.warmup!r}")


@dataclass(frozen=True)
class PaperResult:
    """Estimates of the paper's recipe: ``params`` by PARAM_NAMES (SI) after the last row,
    and ``history`` (N, 12) of the estimates after each sample (NaN before the first row),
    for plots like the paper's Figs 10-12; ``shift`` the derivative-vs-value lag per T-D
    stage used for alignment [samples]."""

    params: dict
    history: np.ndarray
    shift: float


def _half(x: np.ndarray) -> np.ndarray:
    """Delay by half a sample: average of x[k-1] and x[k] (first sample repeated)."""
    out = np.empty_like(x)
    out[0] = x[0]
    out[1:] = 0.5 * (x[1:] + x[:-1])
    return out


def _one(x: np.ndarray) -> np.ndarray:
    """Delay by one sample (first sample repeated)."""
    out = np.empty_like(x)
    out[0] = x[0]
    out[1:] = x[:-1]
    return out


def _delay(x: np.ndarray, d: int) -> np.ndarray:
    """Delay by d >= 0 whole samples (first sample repeated)."""
    if d == 0:
        return x
    return np.concatenate([np.full(d, x[0]), x[:-d]])


def paper_regressors(samples: np.ndarray, config: RigConfig, recipe: PaperRecipe):
    """Targets and regressor rows of eqs (24), (38), (39), every column from the same T-D chain.

    Returns
    -------
    (yf (N,), Yf (N, 4), yc (N, 2), Yc (N, 2, 4), yv (N,), Yv (N, 3), shift)
        In SI (unscaled); ``shift`` the measured derivative-vs-value lag of one T-D stage [samples].
    """
    h = config.h
    r, h0 = recipe.r, recipe.h0
    lag = td_lag(r, h0, h, freq=0.2)
    shift = lag.value_lag - lag.derivative_lag
    if abs(shift - 0.5) > 0.05:
        raise ValueError(f"T-D r={r}, h0={h0}: derivative-vs-value lag {shift:.3f} samples, "
                         "expected 0.5 (the alignment below assumes it)")
    sc = config_scales(config, recipe.omega)
    ug, x1, x3, x4, x5 = (np.ascontiguousarray(samples[:, i]) for i in range(5))

    def td(x, s):
        return td_filter(np.ascontiguousarray(x, dtype=np.float64), r, h0, h, s)

    def two_stage(x, s1, s2):
        """(position, velocity, acceleration) of x through two T-D stages, aligned to the position."""
        a = td(x, s1)
        pos = td(a[:, 0], s1)[:, 0]
        b = td(a[:, 1], s2)
        return pos, _half(b[:, 0]), _one(b[:, 1])

    a1, a2 = config.A1, config.A2
    # force balance (24)-(27): two stages
    p1, v1, acc1 = two_stage(x1, sc["x1"], sc["x2"])
    q1 = a1 * x3 - a2 * x4 - config.F_L
    f_scale = a1 * config.p_span
    yf = td(td(q1, f_scale)[:, 0], f_scale)[:, 0]
    # sign(x2) is not linear, so it cannot share the chain exactly: take the sign of the
    # one-stage velocity (G x2, one value lag = d samples behind x2), pass it through two
    # stages (scale SIGN_SCALE keeps a +-1 jump on the linear band) and delay the other
    # columns by d to match.
    d = int(round(lag.value_lag))
    sgn = np.sign(_half(td(x1, sc["x1"])[:, 1]))
    sgn = td(td(sgn, SIGN_SCALE)[:, 0], SIGN_SCALE)[:, 0]
    Yf = np.column_stack([_delay(acc1, d), _delay(v1, d), sgn, _delay(p1, d)])
    yf = _delay(yf, d)
    # chambers (28)-(38): one stage
    t1, t3, t4 = td(x1, sc["x1"]), td(x3, sc["x3"]), td(x4, sc["x4"])
    vel = _half(t1[:, 1])
    dp3, dp4 = _half(t3[:, 1]), _half(t4[:, 1])
    z = np.array([orifice_z(xv, pa, pb, config.p_s) for xv, pa, pb in zip(x5, x3, x4)]).reshape(-1, 2)
    q_scale = config.x5_span * np.sqrt(2.0 * config.p_s)
    xz1 = td(x5 * z[:, 0], q_scale)[:, 0]
    xz2 = td(x5 * z[:, 1], q_scale)[:, 0]
    f1, f3, f4 = t1[:, 0], t3[:, 0], t4[:, 0]
    yc = np.column_stack([-a1 * vel, a2 * vel])
    Yc = np.stack([
        np.column_stack([(config.V10 + a1 * f1) * dp3, -xz1, f3 - f4, f3]),
        np.column_stack([(config.V20 - a2 * f1) * dp4, xz2, -(f3 - f4), f4]),
    ], axis=1)
    # servo valve (39)-(42), the paper's form -x6' = ...: two stages
    p5, v5, acc5 = two_stage(x5, sc["x5"], sc["x6"])
    du = config.K_p * (ug - config.K_f * x1)
    du_scale = recipe.du_scale or config.K_p * config.K_f * config.x1_span
    du2 = td(td(du, du_scale)[:, 0], du_scale)[:, 0]
    yv = -acc5
    Yv = np.column_stack([v5, p5, -du2])
    return yf, Yf, yc, Yc, yv, Yv, shift


@njit(cache=True)
def _rls_run(theta, P, Phi, Y, start, hist):
    """Plain RLS (lam = 1) over rows start.. of Phi (N, k, n) / Y (N, k); k rows per sample
    (the stacked eq 38 is k = 2 rows: sequential scalar updates equal the vector update 53)."""
    for i in range(start, Phi.shape[0]):
        for j in range(Phi.shape[1]):
            rls_step(theta, P, Phi[i, j], Y[i, j], 1.0, 1e300)
        hist[i] = theta


def _identify(y, Y, nom, ynom, start, p0):
    n = Y.shape[-1]
    Phi = np.ascontiguousarray((Y * nom / ynom).reshape(len(Y), -1, n))
    Yv = np.ascontiguousarray((y / ynom).reshape(len(y), -1))
    theta = np.zeros(n)
    P = np.eye(n) * p0
    hist = np.full((len(y), n), np.nan)
    _rls_run(theta, P, Phi, Yv, start, hist)
    return hist * nom


def identify_paper(samples: np.ndarray, config: RigConfig | None = None,
                   recipe: PaperRecipe | None = None, full: bool = False):
    """Identify the parameters (the paper's 11 and K_sv) with the paper's recipe (module docstring).

    Parameters
    ----------
    samples : array (N, 5)
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] at the rig's sample rate.
    config : RigConfig
        Rig constants (areas, volumes, p_s, F_L, gains, spans, sample rate).
    recipe : PaperRecipe
        T-D and RLS settings (default the paper's r = 100, h0 = 0.05).
    full : bool
        Return a :class:`PaperResult` (with the estimate history) instead of the dict.

    Returns
    -------
    dict
        Estimates by PARAM_NAMES [SI] (or a PaperResult if ``full``).
    """
    config = config or RigConfig()
    recipe = recipe or PaperRecipe()
    samples = np.asarray(samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != 5:
        raise ValueError(f"samples must be (N, 5): ug, x1, x3, x4, x5; got {samples.shape}")
    if not np.all(np.isfinite(samples)):
        bad = int(np.argwhere(~np.isfinite(samples))[0, 0])
        raise ValueError(f"non-finite value in sample {bad}")
    start = int(np.ceil(recipe.warmup / config.h))
    if len(samples) < start + 20:
        raise ValueError(f"{len(samples)} samples: the paper's recipe needs at least {start + 20}")
    yf, Yf, yc, Yc, yv, Yv, shift = paper_regressors(samples, config, recipe)
    hf = _identify(yf, Yf, _NOM_F, _YNOM_F, start, recipe.p0)
    hc = _identify(yc, Yc, _NOM_C, _YNOM_C, start, recipe.p0)
    x6n = config.x5_span  # valve rows in units of the spool span
    hv = _identify(yv / x6n, Yv / x6n, _NOM_V, _YNOM_V, start, recipe.p0)
    # valve: Psi4 = [2 zeta omega, omega^2, K_sv omega^2]; its du column was -du, so K_sv w^2 = +theta
    # the valve's static gain, which the paper does not report, as the ratio of its two
    with np.errstate(divide="ignore", invalid="ignore"):
        hist = np.column_stack([hf, hc, hv, hv[:, 2] / hv[:, 1]])
    params = dict(zip(PARAM_NAMES, map(float, hist[-1])))
    if full:
        return PaperResult(params=params, history=hist, shift=float(shift))
    return params
