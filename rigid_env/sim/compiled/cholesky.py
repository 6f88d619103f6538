"""Normal equations of small dense systems: the Gram matrix AᵀA and the in-place Cholesky
factorisation and solve of a symmetric positive definite matrix (Golub & Van Loan, "Matrix
Computations", 4th ed. 2013, Algorithm 4.2.1), for the Newton polish's regularised normal
equations and the minimum-norm start."""

from __future__ import annotations

import math

from .cache import njit


@njit(cache=True, error_model="numpy")
def gram(a, rows, cols, out):
    """The lower triangle of AᵀA (cols, cols) into ``out``, A the leading (rows, cols) block of
    ``a``."""
    for i in range(cols):
        for j in range(i + 1):
            acc = 0.0
            for m in range(rows):
                acc += a[m, i] * a[m, j]
            out[i, j] = acc


@njit(cache=True, error_model="numpy")
def factor(m, n):
    """M = L Lᵀ for the leading (n, n) block of ``m``, L written over its lower triangle. A
    pivot that is not positive (rounding of a matrix that is only semidefinite) becomes 1e-300,
    so the solve stays finite; both callers make M positive definite first."""
    for j in range(n):
        d = m[j, j]
        for k in range(j):
            d -= m[j, k] * m[j, k]
        d = math.sqrt(d) if d > 0 else 1e-300
        m[j, j] = d
        for i in range(j + 1, n):
            acc = m[i, j]
            for k in range(j):
                acc -= m[i, k] * m[j, k]
            m[i, j] = acc / d


@njit(cache=True, error_model="numpy")
def solve(m, y, n):
    """y ← (L Lᵀ)⁻¹ y in place, L from :func:`factor` (n entries)."""
    for i in range(n):  # L z = y
        acc = y[i]
        for k in range(i):
            acc -= m[i, k] * y[k]
        y[i] = acc / m[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = z
        acc = y[i]
        for k in range(i + 1, n):
            acc -= m[k, i] * y[k]
        y[i] = acc / m[i, i]
