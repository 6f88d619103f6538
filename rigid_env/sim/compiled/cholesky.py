"""Normal equations of small dense systems: the Gram matrix AᵀA and the in-place Cholesky
factorisation and solve of a symmetric positive definite matrix (Golub & Van Loan, "Matrix
Computations", 4th ed. 2013, Algorithm 4.2.1), for the Newton polish's regularised normal
equations and the minimum-norm start."""

from __future__ import annotations

import math

from .cache import njit


@njit(cache=True, error_model="numpy", inline="always")
def gram(a, rows, cols, out):
    """The lower triangle of AᵀA (cols, cols) into ``out``, A the leading (rows, cols) block of
    ``a``."""
    # Four entries of a row at a time: four independent sums, each over m in order (the
    # roundings of one sum at a time, a quarter of its latency).
    for i in range(cols):
        j = 0
        while j + 3 <= i:
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            acc3 = 0.0
            for m in range(rows):
                x = a[m, i]
                acc0 += x * a[m, j]
                acc1 += x * a[m, j + 1]
                acc2 += x * a[m, j + 2]
                acc3 += x * a[m, j + 3]
            out[i, j] = acc0
            out[i, j + 1] = acc1
            out[i, j + 2] = acc2
            out[i, j + 3] = acc3
            j += 4
        while j <= i:
            acc = 0.0
            for m in range(rows):
                acc += a[m, i] * a[m, j]
            out[i, j] = acc
            j += 1


@njit(cache=True, error_model="numpy", inline="always")
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
        i = j + 1
        while i + 1 < n:  # rows in pairs: two independent sums, each in order
            acc0 = m[i, j]
            acc1 = m[i + 1, j]
            for k in range(j):
                x = m[j, k]
                acc0 -= m[i, k] * x
                acc1 -= m[i + 1, k] * x
            m[i, j] = acc0 / d
            m[i + 1, j] = acc1 / d
            i += 2
        if i < n:
            acc = m[i, j]
            for k in range(j):
                acc -= m[i, k] * m[j, k]
            m[i, j] = acc / d


@njit(cache=True, error_model="numpy", inline="always")
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
