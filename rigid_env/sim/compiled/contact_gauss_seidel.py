"""Projected block Gauss–Seidel of one element, and its exact 2-D step over the friction disk
(``disk_step``); ``contact_solve`` states the problem, the stopping rule and the sources.

The tangent blocks A_tt (2×2, symmetric positive definite) are diagonalised by one Jacobi
rotation (``eig2``: Golub & Van Loan, "Matrix Computations", 4th ed. 2013, §8.5.2, the
symmetric Schur decomposition).
"""

from __future__ import annotations

import math

from .cache import njit

# scratch floats per contact: A_tt's eigen-decomposition, λ before a sweep (then the sweep's
# Δλ), λ before a Newton polish (``contact_newton.converge``)
WORK_PER_CONTACT = 12
DISK_NEWTON_STEPS = 8  # the secular equation's Newton iteration converges quadratically from γ = 0


@njit(cache=True, error_model="numpy")
def eig2(a, b, c):
    """Eigen-decomposition of [[a, b], [b, c]]: (e₀, e₁, q₀₀, q₀₁, q₁₀, q₁₁), the columns of
    Q = [[q₀₀, q₀₁], [q₁₀, q₁₁]] the unit eigenvectors of e₀ and e₁."""
    if b == 0.0:
        return a, c, 1.0, 0.0, 0.0, 1.0
    tau = (c - a) / (2.0 * b)
    # tan θ of the rotation that zeroes b: the smaller root of t² + 2τt − 1 = 0.
    root = math.hypot(1.0, tau)
    t = 1.0 / (tau + root) if tau >= 0 else -1.0 / (-tau + root)
    cs = 1.0 / math.sqrt(1.0 + t * t)
    sn = t * cs
    return a - t * b, c + t * b, cs, sn, -sn, cs


# Inlined (with ``velocity_scale``, Newton's ``residual``, ``jacobian``, ``least_squares_step``
# and ``cholesky``'s kernels) into the loops that call them: as calls, passing their arrays
# (reference counts) and arguments cost a few per cent of BoxLanding's physics.
@njit(cache=True, error_model="numpy", inline="always")
def disk_step(a00, a01, a11, e0, e1, q00, q01, q10, q11, l0, l1, v0, v1, cap):
    """the tangent impulse minimising the contact's
    kinetic energy over the disk |λ_t| ≤ cap (Moré & Sorensen's secular equation)."""
    r0 = (a00 * l0 + a01 * l1) - v0
    r1 = (a01 * l0 + a11 * l1) - v1
    p0 = q00 * r0 + q10 * r1  # Qᵀ rhs
    p1 = q01 * r0 + q11 * r1
    i0 = p0 / e0
    i1 = p1 / e1
    norm = math.sqrt(i0 * i0 + i1 * i1)
    if not norm > cap:
        return q00 * i0 + q01 * i1, q10 * i0 + q11 * i1
    if cap <= 1e-12 * norm:  # radial: the secular root would lie beyond floating range
        f = cap / (norm if norm > 0 else 1.0)
        d0, d1 = i0 * f, i1 * f
        return q00 * d0 + q01 * d1, q10 * d0 + q11 * d1
    gamma = 0.0
    p20 = p0 * p0
    p21 = p1 * p1
    inv_cap = 1.0 / (cap if cap > 0 else 1.0)
    for _ in range(DISK_NEWTON_STEPS):  # in reciprocals (3 divisions, not 6)
        r0 = 1.0 / (e0 + gamma)
        r1 = 1.0 / (e1 + gamma)
        s0 = p20 * (r0 * r0)
        s1 = p21 * (r1 * r1)
        f = s0 + s1
        fp = s0 * r0 + s1 * r1
        root = math.sqrt(f)
        step = f * (1.0 - root * inv_cap) / (fp if fp > 0 else 1.0)
        gamma = max(gamma - step, 0.0)
        if abs(step) <= 1e-15 * gamma:
            break
    d0 = p0 / (e0 + gamma)
    d1 = p1 / (e1 + gamma)
    size = math.sqrt(d0 * d0 + d1 * d1)
    f = cap / (size if size > 0 else 1.0)  # exactly on the circle
    d0 *= f
    d1 *= f
    return q00 * d0 + q01 * d1, q10 * d0 + q11 * d1


@njit(cache=True, error_model="numpy", inline="always")
def velocity_scale(free, target):
    """The element's velocity scale of the stopping tests: its largest free contact velocity or
    finite target (> 0)."""
    scale = 0.0
    for i in range(free.shape[0]):
        scale = max(scale, abs(free[i]))
    for i in range(target.shape[0]):
        if math.isfinite(target[i]):
            scale = max(scale, abs(target[i]))
    return max(scale, 1e-300)


@njit(cache=True, error_model="numpy")
def gauss_seidel(
    a, free, target, mu, lam, extra, r, max_iterations, tolerance, scale, work, decomposed=False
):
    """A (rC, rC), ``free`` (rC,), ``target`` (C,)
    (−∞: out of play), ``lam`` (rC,) the start, updated in place; ``extra`` (C,) the friction
    budget (r = 3); ``scale`` the stopping test's velocity scale (``velocity_scale``, or
    the solve's over the slots with a contact point); ``work`` scratch of ``WORK_PER_CONTACT`` C floats;
    ``decomposed``: its first 6C floats already hold this A's A_tt decompositions (an earlier
    call on the same A and ``work``). Returns (sweeps, converged)."""
    c = target.shape[0]
    size = r * c
    # work[6i : 6i + 6]: e₀, e₁, Q of contact i's A_tt; then λ before the sweep (indexed in
    # place: a view per call costs a reference count)
    if r == 3 and not decomposed:
        for i in range(c):
            j = 3 * i
            e0, e1, q00, q01, q10, q11 = eig2(a[j + 1, j + 1], a[j + 2, j + 1], a[j + 2, j + 2])
            work[6 * i], work[6 * i + 1], work[6 * i + 2] = e0, e1, q00
            work[6 * i + 3], work[6 * i + 4], work[6 * i + 5] = q01, q10, q11
    b0 = 6 * c
    for sweep in range(1, max_iterations + 1):
        for k in range(size):
            work[b0 + k] = lam[k]
        for i in range(c):
            j = r * i
            # The contact's velocities before its update (all its rows).
            # Three independent sums in one loop (each in the rows' order).
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            if r == 3:
                for k in range(size):
                    acc0 += a[j, k] * lam[k]
                    acc1 += a[j + 1, k] * lam[k]
                    acc2 += a[j + 2, k] * lam[k]
            else:
                for k in range(size):
                    acc0 += a[j, k] * lam[k]
            vn = free[j] + acc0
            ln_old = lam[j]
            ln = max(ln_old - (vn - target[i]) * (1.0 / a[j, j]), 0.0)
            lam[j] = ln
            if r == 3:
                dn = ln - ln_old
                vt1 = (free[j + 1] + acc1) + a[j + 1, j] * dn
                vt2 = (free[j + 2] + acc2) + a[j + 2, j] * dn
                lam[j + 1], lam[j + 2] = disk_step(
                    a[j + 1, j + 1],
                    a[j + 2, j + 1],
                    a[j + 2, j + 2],
                    work[6 * i + 0],
                    work[6 * i + 1],
                    work[6 * i + 2],
                    work[6 * i + 3],
                    work[6 * i + 4],
                    work[6 * i + 5],
                    lam[j + 1],
                    lam[j + 2],
                    vt1,
                    vt2,
                    mu[i] * (ln + extra[i]),
                )
        # The sweep's effect on the contact velocities, A Δλ, rows in pairs (two independent
        # sums, each in order), stopping at the first row over the tolerance.
        for k in range(size):
            work[b0 + k] = lam[k] - work[b0 + k]  # now Δλ
        limit = tolerance * scale
        converged = True
        i = 0
        while i < size and converged:
            if i + 1 < size:
                acc = 0.0
                acc1 = 0.0
                for k in range(size):
                    acc += a[i, k] * work[b0 + k]
                    acc1 += a[i + 1, k] * work[b0 + k]
                converged = abs(acc) <= limit and abs(acc1) <= limit
                i += 2
            else:
                acc = 0.0
                for k in range(size):
                    acc += a[i, k] * work[b0 + k]
                converged = abs(acc) <= limit
                i += 1
        if converged:
            return sweep, True
    return max_iterations, False


@njit(cache=True, error_model="numpy")
def sweep_change(a, work, size):
    """The last sweep's largest change of a contact velocity, max |A Δλ| (its Δλ left in
    ``work`` by ``gauss_seidel``, r = 3), each row summed in order."""
    b0 = 2 * size
    peak = 0.0
    for i in range(size):
        acc = 0.0
        for k in range(size):
            acc += a[i, k] * work[b0 + k]
        peak = max(peak, abs(acc))
    return peak
