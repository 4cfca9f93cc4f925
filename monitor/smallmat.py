"""Small dense linear algebra in plain loops, for the compiled read-out (no BLAS: the same bits
on every machine, and no allocation beyond the result)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def inv_small(A: np.ndarray) -> np.ndarray:
    """Inverse of a small square matrix by Gauss-Jordan with partial pivoting (NaN if singular)."""
    n = A.shape[0]
    a = np.empty((n, 2 * n))
    for i in range(n):
        for j in range(n):
            a[i, j] = A[i, j]
            a[i, n + j] = 1.0 if i == j else 0.0
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(a[r, c]) > abs(a[piv, c]):
                piv = r
        if a[piv, c] == 0.0:
            a[:, n:] = np.nan
            break
        if piv != c:
            for j in range(2 * n):
                a[c, j], a[piv, j] = a[piv, j], a[c, j]
        f = 1.0 / a[c, c]
        for j in range(2 * n):
            a[c, j] *= f
        for r in range(n):
            if r != c and a[r, c] != 0.0:
                g = a[r, c]
                for j in range(2 * n):
                    a[r, j] -= g * a[c, j]
    return a[:, n:].copy()


@njit(cache=True, error_model="numpy")
def cholesky(A: np.ndarray, L: np.ndarray) -> bool:
    """Lower-triangular L with L L' = A (n, n), written into L, except that its diagonal holds the
    reciprocals 1 / L_ii (the solves then multiply instead of divide); False if A is not positive
    definite."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = 1.0 / np.sqrt(acc)
            else:
                L[i, j] = acc * L[j, j]
    return True


@njit(cache=True, error_model="numpy")
def cholesky_solve(L: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:
    """x = (L L')^-1 b for the factor of ``cholesky`` (x may be b)."""
    n = L.shape[0]
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc -= L[i, k] * x[k]
        x[i] = acc * L[i, i]
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for k in range(i + 1, n):
            acc -= L[k, i] * x[k]
        x[i] = acc * L[i, i]
