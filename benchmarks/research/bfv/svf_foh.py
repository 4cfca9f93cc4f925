"""Research copy of monitor/svf.py at 1c54311 (first-order hold), the SVF the session-3 numbers in
results/final_foh.txt used; batch.force_rows(svf="foh") takes it to reproduce them. Not the package's.

State-variable filter (SVF): the same linear low-pass through every signal of an equation.

F(s) = a^3 / (s + a)^3 with state [y, y', y''] = [F u, s F u, s^2 F u]: one filter gives a
signal's filtered value and its first two filtered derivatives, with no differentiation
of raw (noisy) samples. Because F is linear, applying it to both sides of a linear-in-
parameters equation keeps the equation (e.g. ``F[m x1''] = m s^2 F[x1]``); the only
error left is the discretisation.

Discretisation: first-order hold (the input is taken as piecewise linear between samples;
scipy's ``cont2discrete(method="foh")`` formula), so the three outputs are the continuous
filter's exact states at the sample instants for such an input: y' and y'' are then the
exact derivatives of y, which a bilinear (Tustin) map only gives to O((a h)^2). Measured on
the paper's identification input, noise-free, 10 s, a_force = 80 rad/s: Tustin m -0.142 %,
B + f_v 0.019 %, f_c 0.38 %; first-order hold m -0.123 %, B + f_v 0.003 %, f_c 0.047 %.
(What is left on m grows as about a^4: 0.006 % at 40 rad/s, 0.9 % at 120, 3.2 % at 160; the
signals carry content near the 50 Hz Nyquist frequency that no hold reproduces.)

The discrete filter is x(k+1) = Ad x(k) + Bd u(k), y(k) = Cd x(k) + Dd u(k).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.linalg import expm

ORDER = 3


def svf_matrices(a: float, h: float) -> np.ndarray:
    """Discrete SVF of bandwidth a [rad/s] at sample period h [s].

    Returns
    -------
    array (4, 3, 3)
        Stacked ``Ad``, ``Bd`` (column 0), ``Cd``, ``Dd`` (column 0): the layout the kernels read.
    """
    if not (a > 0 and h > 0 and np.isfinite(a) and np.isfinite(h)):
        raise ValueError(f"SVF needs a > 0 [rad/s] and h > 0 [s], got a={a!r}, h={h!r}")
    n = ORDER
    coeffs = np.poly(-a * np.ones(n))  # s^3 + 3a s^2 + 3a^2 s + a^3
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -coeffs[1:][::-1]
    B = np.zeros(n)
    B[-1] = a**n
    # first-order hold (scipy.signal.cont2discrete's "foh"): one matrix exponential of
    # [[A h, B h, 0], [0, 0, 1], [0, 0, 0]] gives Phi = e^(A h) and the two hold integrals
    em = np.zeros((n + 2, n + 2))
    em[:n, :n] = A * h
    em[:n, n] = B * h
    em[n, n + 1] = 1.0
    ms = expm(em)
    phi, g1, g2 = ms[:n, :n], ms[:n, n], ms[:n, n + 1]
    Ad = phi
    Bd = g1 - g2 + phi @ g2
    Cd = np.eye(n)
    Dd = g2
    out = np.zeros((4, n, n))
    out[0] = Ad
    out[1][:, 0] = Bd
    out[2] = Cd
    out[3][:, 0] = Dd
    return out


@njit(cache=True, error_model="numpy")
def svf_init(m: np.ndarray, x: np.ndarray, u0: float) -> None:
    """Set the filter state ``x`` (3,) to the steady state of a constant input u0."""
    # steady state of x = Ad x + Bd u: solve (I - Ad) x = Bd u by hand (3x3, Cramer-free Gauss)
    a = np.empty((3, 4))
    for i in range(3):
        for j in range(3):
            a[i, j] = (1.0 if i == j else 0.0) - m[0, i, j]
        a[i, 3] = m[1, i, 0] * u0
    for c in range(3):
        piv = c
        for r in range(c + 1, 3):
            if abs(a[r, c]) > abs(a[piv, c]):
                piv = r
        for j in range(4):
            a[c, j], a[piv, j] = a[piv, j], a[c, j]
        for r in range(3):
            if r != c:
                f = a[r, c] / a[c, c]
                for j in range(4):
                    a[r, j] -= f * a[c, j]
    for i in range(3):
        x[i] = a[i, 3] / a[i, i]


@njit(cache=True, error_model="numpy")
def svf_step(m: np.ndarray, x: np.ndarray, u: float, y: np.ndarray) -> None:
    """Filter one sample u: write outputs [F u, sF u, s^2F u] into y (3,), advance state x (3,)."""
    for i in range(3):
        acc = m[3, i, 0] * u
        for j in range(3):
            acc += m[2, i, j] * x[j]
        y[i] = acc
    x0, x1, x2 = x[0], x[1], x[2]
    for i in range(3):
        x[i] = m[0, i, 0] * x0 + m[0, i, 1] * x1 + m[0, i, 2] * x2 + m[1, i, 0] * u


def impulse_response(m: np.ndarray, n: int = 0) -> np.ndarray:
    """(n, 3) impulse response of the three outputs (zero initial state); n defaults to 40/a-ish."""
    if n <= 0:
        n = 2000
    x = np.zeros(3)
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
    return g.T @ g
