"""State-variable filter (SVF): the same linear low-pass through every signal of an equation.

F(s) = a^3 / (s + a)^3 with state [y, y', y''] = [F u, s F u, s^2 F u]: one filter gives a
signal's filtered value and its first two filtered derivatives, with no differentiation
of raw (noisy) samples. Because F is linear, applying it to both sides of a linear-in-
parameters equation keeps the equation (e.g. ``F[m x1''] = m s^2 F[x1]``); the only
error left is the discretisation.

Discretisation: cubic hold. Between samples k and k+1 the input is taken as the Catmull-Rom
cubic through samples k-1 .. k+2, and the filter's state advances exactly for that input:

    x(k+1) = Phi x(k) + G0 u(k-1) + G1 u(k) + G2 u(k+1) + G3 u(k+2),   Phi = e^(A h),
    Gj = integral_0^h e^(A (h - s)) B w_j(s / h) ds   (w_j the Catmull-Rom weights),

so the outputs are the continuous filter's states, and y', y'' exact derivatives of y, for
that input. It needs u(k+2) to reach x(k+1): the outputs lag the input by one sample (every
signal of an equation alike, so the equation's rows stay aligned). Why cubic, measured on the
paper's identification input, noise-free, 10 s, a_force = 80 rad/s (batch replica of the force
regression): a first-order hold (piecewise-linear input) left m 0.121 % off, this 0.001 %;
B + f_v 0.0035 -> 0.0012 %, f_c 0.044 -> 0.007 %. The linear hold misses the piston's ~19 Hz
hydraulic resonance (5 samples a period) by about (w h)^2/12; sampled at 400 Hz both agree
(0.0015 and 0.0011 %). Tustin: m 0.142 %.

Per signal the state is [x (3), u(k-1), u(k), u(k+1)] (``layout.SVF_STATE`` = 6); a step takes
u(k+2) and outputs x(k+1).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import SVF_STATE

ORDER = 3


_CATMULL_ROM = np.array([  # w_j(tau) = sum_p C[j, p] tau^p, for u(k-1), u(k), u(k+1), u(k+2)
    [0.0, -0.5, 1.0, -0.5],
    [1.0, 0.0, -2.5, 1.5],
    [0.0, 0.5, 2.0, -1.5],
    [0.0, 0.0, -0.5, 0.5],
])


def _matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b with every element an exactly rounded sum (math.fsum) of its products.

    The filter matrices must not depend on the machine: numpy's ``@`` goes to OpenBLAS, which
    picks its kernel by CPU (SkylakeX on an AVX-512 machine, Haswell elsewhere) and rounds
    differently; scipy's expm built on it gives matrices 1 ulp apart, which the early,
    ill-conditioned estimates amplify to 1e-9 relative: enough to change the health bytes the
    golden recordings pin. Pure Python floats are IEEE doubles everywhere, and fsum's result
    does not depend on the order of its terms.
    """
    n, m = a.shape[0], b.shape[1]
    out = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            out[i, j] = math.fsum(float(a[i, k]) * float(b[k, j]) for k in range(a.shape[1]))
    return out


def expm_det(m: np.ndarray) -> np.ndarray:
    """e^m of a small square matrix, the same bits on every machine (see ``_matmul``).

    Balancing by powers of 2 (exact: e^m = D e^(D^-1 m D) D^-1), then scaling and squaring:
    the Taylor series of e^(b / 2^s) with ||b / 2^s||_1 <= 1/2 to 24 terms (truncation below
    0.5^25 / 25!, far under one ulp), then s squarings. The filters' matrices mix entries of
    1 and a^3 h (5120 at 80 rad/s), so without the balancing 14 squarings amplified rounding
    to 4e-13; with it, against a 50-digit reference (mpmath), the SVF's matrices at 25, 80
    and 300 rad/s (h = 0.01 s) are within 4e-16, 1.5e-15 and 3.5e-15 relative (scipy.linalg.expm:
    1.3e-15, 5.1e-15 and 2.1e-12).
    """
    m = np.asarray(m, dtype=float)
    d = _balance(m)
    m = m * (d[None, :] / d[:, None])
    norm = max(math.fsum(abs(float(v)) for v in m[:, j]) for j in range(m.shape[1]))
    s = max(0, math.ceil(math.log2(norm)) + 1) if norm > 0 else 0
    x = m / 2.0 ** s
    out = np.eye(m.shape[0])
    term = np.eye(m.shape[0])
    for k in range(1, 25):
        term = _matmul(term, x) / k
        out = out + term
    for _ in range(s):
        out = _matmul(out, out)
    return out * (d[:, None] / d[None, :])


def _balance(m: np.ndarray) -> np.ndarray:
    """Powers of 2 d (exact to scale by) making D^-1 m D's rows and columns alike in size
    (Parlett and Reinsch, as LAPACK's gebal)."""
    n = m.shape[0]
    d = np.ones(n)
    b = m.copy()
    for _ in range(100):
        done = True
        for i in range(n):
            c = math.fsum(abs(float(b[j, i])) for j in range(n) if j != i)
            r = math.fsum(abs(float(b[i, j])) for j in range(n) if j != i)
            if c == 0.0 or r == 0.0:
                continue
            f = 1.0
            while c < r / 2.0:
                c, r, f = c * 2.0, r / 2.0, f * 2.0
            while c >= r * 2.0:
                c, r, f = c / 2.0, r * 2.0, f / 2.0
            if f != 1.0:
                done = False
                d[i] *= f
                b[:, i] *= f
                b[i, :] /= f
        if done:
            break
    return d


def cubic_hold_matrices(A: np.ndarray, B: np.ndarray, h: float) -> np.ndarray:
    """Exact discretisation of x' = A x + B u for an input that is the Catmull-Rom cubic
    through u(k-1) .. u(k+2) between samples k and k+1, at sample period h [s].

    Returns
    -------
    array (n, n + 4)
        ``[Phi | G0 G1 G2 G3]``: x(k+1) = Phi x(k) + G0 u(k-1) + G1 u(k) + G2 u(k+1) + G3 u(k+2).
    """
    n = A.shape[0]
    # M_p = integral_0^h e^(A (h - s)) B (s/h)^p ds, p = 0..3, from one matrix exponential: the
    # input's polynomial basis is the nilpotent chain appended to the state (Van Loan)
    em = np.zeros((n + 4, n + 4))
    em[:n, :n] = A * h
    em[:n, n] = B * h
    for p in range(3):
        em[n + p, n + p + 1] = 1.0
    ms = expm_det(em)
    # the chain's state p after t = tau h is tau^(p) / p!: convert to the powers tau^p
    fact = np.array([1.0, 1.0, 2.0, 6.0])
    M = ms[:n, n:n + 4] * fact  # column p: integral of e^(A(h-s)) B (s/h)^p ds
    out = np.zeros((n, n + 4))
    out[:, :n] = ms[:n, :n]
    out[:, n:] = _matmul(M, _CATMULL_ROM.T)
    return out


def lowpass_companion(poles: list[float], gain: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of gain / prod(s + p_i) in companion form, state [y, y', ..., y^(n-1)]."""
    coeffs = np.array([1.0])
    for p in poles:
        coeffs = np.convolve(coeffs, [1.0, p])  # exact for the small integers and reals used here
    n = len(poles)
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -coeffs[1:][::-1]
    B = np.zeros(n)
    B[-1] = gain
    return A, B


def svf_matrices(a: float, h: float) -> np.ndarray:
    """Discrete SVF of bandwidth a [rad/s] at sample period h [s], cubic hold.

    Returns
    -------
    array (3, 7)
        ``[Phi | G0 G1 G2 G3]``: the layout the kernels read.
    """
    if not (a > 0 and h > 0 and np.isfinite(a) and np.isfinite(h)):
        raise ValueError(f"SVF needs a > 0 [rad/s] and h > 0 [s], got a={a!r}, h={h!r}")
    A, B = lowpass_companion([a] * ORDER, a ** ORDER)  # s^3 + 3a s^2 + 3a^2 s + a^3
    return cubic_hold_matrices(A, B, h)


@njit(cache=True, error_model="numpy")
def svf_init(m: np.ndarray, x: np.ndarray, u0: float) -> None:
    """Set a signal's state ``x`` (SVF_STATE,) to rest on a constant input u0 (DC gain 1:
    the filter's value u0, its derivatives 0; the input history u0)."""
    x[0] = u0
    x[1] = 0.0
    x[2] = 0.0
    x[3] = u0
    x[4] = u0
    x[5] = u0


@njit(cache=True, error_model="numpy")
def svf_step(m: np.ndarray, x: np.ndarray, u: float, y: np.ndarray) -> None:
    """Take input u = u(k+2): write [F u, sF u, s^2F u] at instant k+1 into y (3,) and advance
    the state x (SVF_STATE,) = [x(k), u(k-1), u(k), u(k+1)] to [x(k+1), u(k), u(k+1), u(k+2)]."""
    x0, x1, x2, um1, u0, u1 = x[0], x[1], x[2], x[3], x[4], x[5]
    for i in range(3):
        y[i] = m[i, 0] * x0 + m[i, 1] * x1 + m[i, 2] * x2 + m[i, 3] * um1 + m[i, 4] * u0 + m[i, 5] * u1 + m[i, 6] * u
    x[0], x[1], x[2] = y[0], y[1], y[2]
    x[3], x[4], x[5] = u0, u1, u


@njit(cache=True, error_model="numpy")
def svf_bank_step(m: np.ndarray, st: np.ndarray, base: int, u: np.ndarray, y: np.ndarray) -> None:
    """``svf_step`` for len(u) signals of one filter whose states lie one after another in
    ``st`` from ``base`` (SVF_STATE each); y (len(u), 3). The same arithmetic, with the matrix
    read once and no per-signal views: the identifier's per-sample hot loop."""
    m00, m01, m02, m03, m04, m05, m06 = m[0, 0], m[0, 1], m[0, 2], m[0, 3], m[0, 4], m[0, 5], m[0, 6]
    m10, m11, m12, m13, m14, m15, m16 = m[1, 0], m[1, 1], m[1, 2], m[1, 3], m[1, 4], m[1, 5], m[1, 6]
    m20, m21, m22, m23, m24, m25, m26 = m[2, 0], m[2, 1], m[2, 2], m[2, 3], m[2, 4], m[2, 5], m[2, 6]
    for i in range(u.shape[0]):
        o = base + SVF_STATE * i
        x0, x1, x2, um1, u0, u1 = st[o], st[o + 1], st[o + 2], st[o + 3], st[o + 4], st[o + 5]
        ui = u[i]
        y0 = m00 * x0 + m01 * x1 + m02 * x2 + m03 * um1 + m04 * u0 + m05 * u1 + m06 * ui
        y1 = m10 * x0 + m11 * x1 + m12 * x2 + m13 * um1 + m14 * u0 + m15 * u1 + m16 * ui
        y2 = m20 * x0 + m21 * x1 + m22 * x2 + m23 * um1 + m24 * u0 + m25 * u1 + m26 * ui
        y[i, 0], y[i, 1], y[i, 2] = y0, y1, y2
        st[o], st[o + 1], st[o + 2] = y0, y1, y2
        st[o + 3], st[o + 4], st[o + 5] = u0, u1, ui


@njit(cache=True, error_model="numpy")
def svf_bank_init(st: np.ndarray, base: int, u: np.ndarray) -> None:
    """``svf_init`` for len(u) consecutive signal states from ``base``."""
    for i in range(u.shape[0]):
        o = base + SVF_STATE * i
        st[o], st[o + 1], st[o + 2] = u[i], 0.0, 0.0
        st[o + 3], st[o + 4], st[o + 5] = u[i], u[i], u[i]


def impulse_response(m: np.ndarray, n: int = 0) -> np.ndarray:
    """(n, 3) impulse response of the three outputs (zero initial state); n defaults to 40/a-ish."""
    if n <= 0:
        n = 2000
    x = np.zeros(SVF_STATE)
    y = np.zeros(3)
    out = np.empty((n, 3))
    for k in range(n):
        svf_step(m, x, 1.0 if k == 0 else 0.0, y)
        out[k] = y
    return out


def noise_gram(m: np.ndarray) -> np.ndarray:
    """(3, 3) Gram matrix G[i, j] = sum_k g_i(k) g_j(k) of the outputs' impulse responses.

    White noise of variance s^2 on the input gives filtered outputs of covariance s^2 G:
    what the bias compensation subtracts.
    """
    g = impulse_response(m)
    return _matmul(g.T, g)
