"""The minimum-norm solution x = A⁺ b of a small square system, for the active-set start.

The active set's equations are rank-deficient by construction (a face's four corners give four
normal rows of rank three; a body has six degrees of freedom however many rows its contacts
add), and the start wants their minimum-norm solution, ``pinv``'s (redundant supports share the
load equally). This is an order of magnitude cheaper than LAPACK's SVD behind numba's
``pinv`` for a 12×12 system:

* A symmetric positive semidefinite (the Delassus matrix's live block, no contact at its cone's
  boundary): pivoted Cholesky A = L̃ L̃ᵀ stopped at the numerical rank r (Higham, "Accuracy and
  Stability of Numerical Algorithms", 2nd ed., 2002, §10.3), L̃ (k×r) of full column rank, and
  A⁺ = L̃ (L̃ᵀL̃)⁻² L̃ᵀ: with the thin SVD L̃ = U S Vᵀ both sides are U S⁻² Uᵀ.
* any other A: A⁺ b = (AᵀA)⁺ Aᵀ b (Penrose's identity A⁺ = (AᵀA)⁺ Aᵀ), the same on AᵀA.

Rank: the factorisation stops when no remaining diagonal exceeds ``RANK_TOLERANCE`` (``pinv``'s
``rcond``) times the largest diagonal of A. An exactly dependent row leaves a
diagonal of rounding size, ~k ε of the largest (LAPACK's ``dpstrf`` stops at k ε; here k ≤ 3C),
so 1e-12 keeps a margin of a few hundred over it. Through AᵀA the threshold is on squared
singular values: a direction of A weaker than 1e-6 of the largest is left out there, which only
moves the start that Gauss–Seidel polishes (a boundary contact's system has none in practice).
"""

from __future__ import annotations

import math

from . import cholesky
from .cache import njit

# Singular values below this share of the largest are rounding, not a direction of the system:
# the active set's equations are rank-deficient by construction (a face's four corners give four
# normal rows of rank three), and pinv's default (1e-15) keeps an exactly dependent row's
# rounding-size singular value and with it an impulse of ~1e15 its size. ``compiled.min_norm``
# stops its pivoted Cholesky at the same share of the largest diagonal.
RANK_TOLERANCE = 1e-12


@njit(cache=True, error_model="numpy")
def psd_min_norm(s, b, x, work):
    """x ← S⁺ b for S (k, k) symmetric positive semidefinite (read only); ``work`` scratch of
    2k² + 2k floats. Returns the rank used."""
    k = s.shape[0]
    factor = work[: k * k].reshape((k, k))
    gram = work[k * k : 2 * k * k].reshape((k, k))
    remaining = work[2 * k * k : 2 * k * k + k]
    y = work[2 * k * k + k : 2 * k * k + 2 * k]
    top = 0.0
    for i in range(k):
        remaining[i] = s[i, i]
        top = max(top, s[i, i])
    # Pivoted Cholesky, outer-product form, rows kept in place: column j of L̃ is zero on the
    # rows pivoted before it, which are marked by a remaining diagonal of −∞.
    rank = 0
    for j in range(k):
        p = -1
        best = RANK_TOLERANCE * top
        for i in range(k):
            if remaining[i] > best:
                best = remaining[i]
                p = i
        if p < 0:
            break
        root = math.sqrt(remaining[p])
        remaining[p] = -math.inf
        # The rows still to pivot, in pairs: two independent sums, each in order.
        held = -1
        for i in range(k + 1):
            if i < k and remaining[i] == -math.inf:
                factor[i, j] = 0.0
            elif i < k and held < 0:
                held = i
            elif i < k:
                acc0 = s[held, p]
                acc1 = s[i, p]
                for m in range(j):
                    fp = factor[p, m]
                    acc0 -= factor[held, m] * fp
                    acc1 -= factor[i, m] * fp
                factor[held, j] = acc0 / root
                factor[i, j] = acc1 / root
                held = -1
            elif held >= 0:
                acc0 = s[held, p]
                for m in range(j):
                    acc0 -= factor[held, m] * factor[p, m]
                factor[held, j] = acc0 / root
        factor[p, j] = root
        for i in range(k):
            if remaining[i] != -math.inf:
                remaining[i] -= factor[i, j] * factor[i, j]
        rank += 1
    r = rank
    # H = L̃ᵀ L̃ (r, r): positive definite, as L̃'s columns are independent (each pivot was
    # above the rank tolerance).
    cholesky.gram(factor, k, r, gram)
    cholesky.factor(gram, r)
    # x = L̃ H⁻¹ H⁻¹ L̃ᵀ b.
    for i in range(r):
        acc = 0.0
        for m in range(k):
            acc += factor[m, i] * b[m]
        y[i] = acc
    for _ in range(2):
        cholesky.solve(gram, y, r)
    for m in range(k):
        acc = 0.0
        for i in range(r):
            acc += factor[m, i] * y[i]
        x[m] = acc
    return rank


@njit(cache=True, error_model="numpy")
def min_norm(a, b, x, symmetric, work):
    """x ← A⁺ b for A (k, k); ``symmetric``: A is symmetric positive semidefinite; ``work``
    scratch of at least 3k(k + 1) floats. Returns the rank used."""
    if symmetric:
        return psd_min_norm(a, b, x, work)
    k = a.shape[0]
    o = 2 * k * k + 2 * k  # past psd_min_norm's scratch
    normal = work[o : o + k * k].reshape((k, k))
    rhs = work[o + k * k : o + k * k + k]
    cholesky.gram(a, k, k, normal)
    for i in range(k):
        acc = 0.0
        for m in range(k):
            acc += a[m, i] * b[m]
        rhs[i] = acc
        for j in range(i):
            normal[j, i] = normal[i, j]  # psd_min_norm reads both triangles
    return psd_min_norm(normal, rhs, x, work)
