"""The Newton polish of one element's contact solve and the rounds that call it, mirroring
``contacts.newton`` and ``contacts.solve.converge`` (see there for the Alart–Curnier function,
its generalised Jacobian, the line search and the sources). The regularised normal equations
are solved by a hand-written Cholesky factorisation (numpy: LAPACK's LU); the two backends
agree to rounding, not bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from ..contacts.newton import ARMIJO, GAIN, HALVINGS, MARGIN, RIDGE
from . import cholesky
from .cache import njit
from .contact_gauss_seidel import gauss_seidel, velocity_scale


@njit(cache=True, error_model="numpy")
def residual(a, free, target, mu, extra, lam, f, zn, zt, rho):
    """F (3C,) at ``lam`` (3C,) into ``f``; z_n (C,), z_t (C, 2), ρ (C,) into their arrays.
    Returns |F|²."""
    c = target.shape[0]
    size = 3 * c
    phi = 0.0
    for i in range(c):
        j = 3 * i
        r = GAIN / a[j, j]
        v0 = free[j]
        v1 = free[j + 1]
        v2 = free[j + 2]
        for k in range(size):
            v0 += a[j, k] * lam[k]
            v1 += a[j + 1, k] * lam[k]
            v2 += a[j + 2, k] * lam[k]
        z = lam[j] - r * (v0 - target[i])  # −∞ for a contact out of play
        zn[i] = z
        p_n = max(z, 0.0)
        rho[i] = mu[i] * (p_n + extra[i])
        t1 = lam[j + 1] - r * v1
        t2 = lam[j + 2] - r * v2
        zt[i, 0] = t1
        zt[i, 1] = t2
        norm = math.sqrt(t1 * t1 + t2 * t2)
        if norm > rho[i]:
            s = rho[i] / norm
            t1 *= s
            t2 *= s
        f[j] = lam[j] - p_n
        f[j + 1] = lam[j + 1] - t1
        f[j + 2] = lam[j + 2] - t2
        phi += f[j] * f[j] + f[j + 1] * f[j + 1] + f[j + 2] * f[j + 2]
    return phi


@njit(cache=True, error_model="numpy")
def jacobian(a, mu, zn, zt, rho, g):
    """G = I − ∂P (I − R A) into ``g`` (3C, 3C), as ``newton.jacobian``."""
    c = zn.shape[0]
    size = 3 * c
    for i in range(c):
        j = 3 * i
        r = GAIN / a[j, j]
        active = zn[i] > 0
        t1 = zt[i, 0]
        t2 = zt[i, 1]
        norm = math.sqrt(t1 * t1 + t2 * t2)
        out = norm > rho[i]
        u1 = t1 / norm if out else 0.0
        u2 = t2 / norm if out else 0.0
        s = rho[i] / norm if out else 0.0
        for k in range(size):
            # Rows of M = I − R A for this contact.
            m0 = (1.0 if k == j else 0.0) - r * a[j, k]
            m1 = (1.0 if k == j + 1 else 0.0) - r * a[j + 1, k]
            m2 = (1.0 if k == j + 2 else 0.0) - r * a[j + 2, k]
            dn = m0 if active else 0.0
            if out:
                # s (I − û ûᵀ) M_t + μ û ∂p_n
                d1 = s * ((1.0 - u1 * u1) * m1 - u1 * u2 * m2) + u1 * mu[i] * dn
                d2 = s * (-u2 * u1 * m1 + (1.0 - u2 * u2) * m2) + u2 * mu[i] * dn
            else:
                d1 = m1
                d2 = m2
            g[j, k] = (1.0 if k == j else 0.0) - dn
            g[j + 1, k] = (1.0 if k == j + 1 else 0.0) - d1
            g[j + 2, k] = (1.0 if k == j + 2 else 0.0) - d2


@njit(cache=True, error_model="numpy")
def least_squares_step(g, f, normal, step):
    """Δ = −(GᵀG + δ I)⁻¹ GᵀF into ``step`` (``newton.RIDGE``), by Cholesky (Golub & Van Loan,
    "Matrix Computations", 4th ed. 2013, Algorithm 4.2.1); ``normal`` (n, n) scratch."""
    n = f.shape[0]
    cholesky.gram(g, n, n, normal)
    peak = 0.0
    for i in range(n):
        peak = max(peak, normal[i, i])
    ridge = RIDGE * peak
    for i in range(n):
        normal[i, i] += ridge
        acc = 0.0
        for k in range(n):
            acc += g[k, i] * f[k]
        step[i] = -acc
    cholesky.factor(normal, n)
    cholesky.solve(normal, step, n)


@njit(cache=True, error_model="numpy")
def newton(a, free, target, mu, lam, extra, budget, tolerance):
    """``newton.newton`` for one element: at most ``budget`` steps from ``lam`` (3C,),
    updated in place. Returns the steps taken."""
    c = target.shape[0]
    size = 3 * c
    goal = MARGIN * tolerance * velocity_scale(free, target)
    # One scratch allocation carved into views (thirteen cost ~0.6 µs per call).
    buf = np.empty(2 * size * size + 4 * size + 8 * c)
    g = buf[: size * size].reshape((size, size))
    normal = buf[size * size : 2 * size * size].reshape((size, size))
    o = 2 * size * size
    f = buf[o : o + size]
    f2 = buf[o + size : o + 2 * size]
    step = buf[o + 2 * size : o + 3 * size]
    trial = buf[o + 3 * size : o + 4 * size]
    o += 4 * size
    zn = buf[o : o + c]
    rho = buf[o + c : o + 2 * c]
    zn2 = buf[o + 2 * c : o + 3 * c]
    rho2 = buf[o + 3 * c : o + 4 * c]
    zt = buf[o + 4 * c : o + 6 * c].reshape((c, 2))
    zt2 = buf[o + 6 * c : o + 8 * c].reshape((c, 2))
    phi = residual(a, free, target, mu, extra, lam, f, zn, zt, rho)
    steps = 0
    while steps < budget:
        worst = 0.0
        for i in range(c):
            d = a[3 * i, 3 * i]
            for r in range(3):
                worst = max(worst, abs(f[3 * i + r]) * d)
        if worst <= goal:
            break
        jacobian(a, mu, zn, zt, rho, g)
        least_squares_step(g, f, normal, step)
        alpha = 1.0
        accepted = False
        for _ in range(HALVINGS):
            for i in range(size):
                trial[i] = lam[i] + alpha * step[i]
            phi2 = residual(a, free, target, mu, extra, trial, f2, zn2, zt2, rho2)
            if phi2 <= (1.0 - 2.0 * ARMIJO * alpha) * phi:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break  # a stall: Gauss–Seidel goes on from λ
        lam[:] = trial
        f[:] = f2
        zn[:] = zn2
        zt[:, :] = zt2
        rho[:] = rho2
        phi = phi2
        steps += 1
    return steps


@njit(cache=True, error_model="numpy")
def converge(
    a,
    free,
    target,
    mu,
    lam,
    extra,
    max_iterations,
    tolerance,
    newton_after,
    newton_steps,
    work,
    decomposed=False,
):
    """``solve.converge`` for one element: rounds of ``newton_after`` Gauss–Seidel sweeps
    with Newton polishes between them (``decomposed`` as ``gauss_seidel``'s; the rounds after
    the first reuse the first's). Returns (sweeps, converged, Newton steps)."""
    sweeps = 0
    steps = 0
    while sweeps < max_iterations:
        chunk = min(newton_after, max_iterations - sweeps)
        more, done = gauss_seidel(
            a, free, target, mu, lam, extra, 3, chunk, tolerance, work, decomposed
        )
        decomposed = True
        sweeps += more
        if done:
            return sweeps, True, steps
        if steps < newton_steps and sweeps < max_iterations:
            steps += newton(a, free, target, mu, lam, extra, newton_steps - steps, tolerance)
    return sweeps, False, steps
