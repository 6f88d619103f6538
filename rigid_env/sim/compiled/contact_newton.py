"""The Newton polish of one element's contact solve and the rounds that call it
(``converge``); the regularised normal equations are solved by a hand-written Cholesky
factorisation (``cholesky``).

Semi-smooth Newton polish of the contact problem (``solve``'s module docstring), batched.

Gauss–Seidel crawls on a few cases (several contacts of one face sticking or sliding at tiny
speeds under a torque: thousands of sweeps). Those are solved as a root of the Alart–Curnier
function (Alart & Curnier, "A mixed formulation for frictional contact problems prone to
Newton like solution methods", CMAME 92, 1991), per contact i with r = ``GAIN``/A_nn of that
contact, v = b + A λ:

    z_n = λ_n − r (v_n − target),     F_n = λ_n − max(z_n, 0)
    z_t = λ_t − r v_t,               F_t = λ_t − P_ρ(z_t),   ρ = μ (max(z_n, 0) + extra)

where P_ρ projects onto the disk |·| ≤ ρ. F = 0 exactly at the Signorini–Coulomb conditions of
``solve`` (F_n = 0 ⇔ λ_n ≥ 0, v_n ≥ target, complementarity; F_t = 0 ⇔ |λ_t| ≤ ρ and v_t = 0
inside, v_t = −s λ_t with s ≥ 0 on the circle), so a root is also a fixed point of
Gauss–Seidel. The step solves G Δ = −F with G an element of the generalised Jacobian (the
per-contact blocks with the disk projection's derivative ρ/|z_t| (I − ẑ ẑᵀ) and its radius'
μ ẑ ∂z_n: Bertails-Descoteaux et al., "A nonsmooth Newton solver for capturing exact Coulomb
friction in fiber assemblies", ACM TOG 2011, §4) by a least-squares solution (a face's four
corners make A, hence G, singular: the regularised normal equations, ``RIDGE``), and a
backtracking (Armijo) line search on |F|² picks the step length. Where that stalls or crawls,
``jump`` moves λ past a change of contact mode along G's null direction (note at
``CRAWL_STEP``). The caller finishes with Gauss–Seidel, whose sweep test decides convergence:
"converged" keeps the one meaning ``SolverSettings.tolerance`` states; the caller also undoes a
polish whose next sweep changes more than the last one before it (``converge``).
"""

from __future__ import annotations

import math

import numpy as np

from . import cholesky
from .cache import njit
from .contact_gauss_seidel import gauss_seidel, sweep_change

ARMIJO = 1e-4  # sufficient decrease of |F|² per unit step (Nocedal & Wright, 2006, §3.1)
# Line-search halvings before the step is called a stall. The short steps they allow (α down
# to 1e-9) do the work in the hardest solves (with 10, twice as many were capped:
# ``docs/performance.md``, as for the other constants here).
HALVINGS = 30
# A Newton step that stalls (no step length decreases |F|²) or crawls (accepted shorter than
# CRAWL_STEP, lowering |F|² by less than 1 − CRAWL_DECREASE) has met a direction G cannot
# see: in a null direction of G, F is constant to first order, so no Newton step moves along
# it, yet the root may lie along it past a change of contact mode. The case met in BoxLanding:
# two sticking corners on a nearly level diagonal (G's smallest singular value ~3e-11), where
# an internal tangential impulse between them barely changes a velocity, and the residual asks
# for one far outside the friction cone, i.e. for one corner to slide. ``jump``
# moves λ along ± that direction to just past (JUMP_PAST, relative) the first change of mode
# on each side (z_n or |z_t| − ρ changing sign, both linear or quadratic in the length: roots
# in closed form; changes closer than JUMP_FLOOR × max|λ| are the current kink, skipped) and
# takes the side with the smaller |F|², if that is at most JUMP_GROWTH × |F|²; Newton goes on
# from there in the new mode. A jump counts as a Newton step; at most JUMPS per polish. The
# direction: two steps of inverse iteration on the step's regularised GᵀG (Golub & Van Loan,
# "Matrix Computations", 2013, §7.6.1) from the ones vector.
CRAWL_STEP = 1.0 / 16.0
CRAWL_DECREASE = 0.9
JUMP_FLOOR = 2.0**-40
JUMP_PAST = 2.0**-30
JUMP_GROWTH = 10.0
JUMPS = 4
# The least-squares step solves the regularised normal equations (GᵀG + δ I) Δ = −GᵀF (a
# Levenberg–Marquardt step with a tiny δ: Nocedal & Wright, "Numerical Optimization", 2006,
# §10.3) by Cholesky: 20× cheaper than an SVD pseudo-inverse for 3C ≤ 24 and the same step
# along the singular directions σ² ≫ δ. δ = RIDGE × max diag(GᵀG): above the rounding of GᵀG's
# entries (3C ε ‖G‖² ≤ 24 ε ≈ 5e-15 relative), so the matrix is positive definite in floating
# point, and G's null space (a face's redundant corners) gets no step. A ridge growing with the
# residual, δ = max(this, |F|²) (Yamashita & Fukushima, "On the rate of convergence of the
# Levenberg–Marquardt method", Computing Suppl. 15, 2001) capped more solves: what stopped
# Newton there was a mode it could not change, which the jumps handle.
RIDGE = 1e-14
# Newton stops when no contact's residual, in velocity units (|F| A_nn), exceeds this share of
# the solve's tolerance × scale: the closing Gauss–Seidel sweep then meets the tolerance.
MARGIN = 1e-2
# r = GAIN / A_nn: any r > 0 gives the same roots; 10 converged a few more capped cases than 1.
GAIN = 10.0


@njit(cache=True, error_model="numpy", inline="always")
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


@njit(cache=True, error_model="numpy", inline="always")
def jacobian(a, mu, zn, zt, rho, g):
    """G = I − ∂P (I − R A) into ``g`` (3C, 3C)."""
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


@njit(cache=True, error_model="numpy", inline="always")
def least_squares_step(g, f, normal, step):
    """Δ = −(GᵀG + δ I)⁻¹ GᵀF into ``step`` (``RIDGE``), by Cholesky (Golub & Van Loan,
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
def mode_changed(zn, zt, rho, zn0, zt0, rho0):
    """Whether any contact's mode (z_n > 0; |z_t| > ρ) differs between the two points."""
    for i in range(zn.shape[0]):
        if (zn[i] > 0) != (zn0[i] > 0):
            return True
        out = math.sqrt(zt[i, 0] * zt[i, 0] + zt[i, 1] * zt[i, 1]) > rho[i]
        out0 = math.sqrt(zt0[i, 0] * zt0[i, 0] + zt0[i, 1] * zt0[i, 1]) > rho0[i]
        if out != out0:
            return True
    return False


@njit(cache=True, error_model="numpy")
def quadratic_roots(c0, c1, c2, out, n):
    """The real roots of c0 + 2 c1 s + c2 s² appended to ``out`` from index n; returns the new
    count (a root of a degenerate c2 = 0 equation, linear, counts once)."""
    if c2 == 0.0:
        if c1 != 0.0:
            out[n] = -c0 / (2.0 * c1)
            n += 1
        return n
    disc = c1 * c1 - c0 * c2
    if disc < 0.0:
        return n
    # The root without cancellation first, the other from the product c0 / c2 (Vieta).
    q = -(c1 + math.copysign(math.sqrt(disc), c1))
    if q != 0.0:
        out[n] = q / c2
        out[n + 1] = c0 / q
        return n + 2
    out[n] = 0.0
    return n + 1


@njit(cache=True, error_model="numpy")
def mode_events(a, mu, extra, zn, zt, rho, x, events):
    """The lengths s at which a contact's mode changes along λ + s x (``jump``): z_n
    crossing 0 and |z_t| crossing ρ on either side of it. Returns their count."""
    c = zn.shape[0]
    size = x.shape[0]
    n = 0
    for i in range(c):
        j = 3 * i
        r = GAIN / a[j, j]
        # dz/ds = x − r A x on the contact's three rows.
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for m in range(size):
            a0 += a[j, m] * x[m]
            a1 += a[j + 1, m] * x[m]
            a2 += a[j + 2, m] * x[m]
        d0 = x[j] - r * a0
        d1 = x[j + 1] - r * a1
        d2 = x[j + 2] - r * a2
        if d0 != 0.0:
            events[n] = -zn[i] / d0
            n += 1
        t1, t2 = zt[i, 0], zt[i, 1]
        tt = t1 * t1 + t2 * t2
        td = t1 * d1 + t2 * d2
        dd = d1 * d1 + d2 * d2
        # ρ(s) = μ (z_n + s d_n + extra) where z_n(s) > 0, μ extra elsewhere.
        p = mu[i] * (zn[i] + extra[i])
        q = mu[i] * d0
        first = n
        n = quadratic_roots(tt - p * p, td - p * q, dd - q * q, events, n)
        for e in range(first, n):  # keep the roots on the active side
            if not zn[i] + events[e] * d0 > 0:
                events[e] = math.nan
        p = mu[i] * extra[i]
        first = n
        n = quadratic_roots(tt - p * p, td, dd, events, n)
        for e in range(first, n):
            if zn[i] + events[e] * d0 > 0:
                events[e] = math.nan
    return n


@njit(cache=True, error_model="numpy")
def jump(a, free, target, mu, extra, lam, factor, phi, zn, zt, rho, trial, f2, zn2, zt2, rho2):
    """λ (updated in place when it jumps) along ± the null
    direction of G, ``factor`` the Cholesky factor of the step's regularised GᵀG. Returns
    whether it jumped."""
    size = lam.shape[0]
    x = np.ones(size)
    for _ in range(2):
        cholesky.solve(factor, x, size)
        norm = 0.0
        for i in range(size):
            norm += x[i] * x[i]
        norm = math.sqrt(norm)
        for i in range(size):
            x[i] /= norm
    length = 0.0
    for i in range(size):
        length = max(length, abs(lam[i]))
    floor = length * JUMP_FLOOR
    events = np.empty(5 * zn.shape[0])
    count = mode_events(a, mu, extra, zn, zt, rho, x, events)
    ahead = math.inf  # the first event on each side beyond the floor
    behind = -math.inf
    for e in range(count):
        s = events[e]
        if s > floor and s < ahead:
            ahead = s
        elif s < -floor and s > behind:
            behind = s
    best_phi = math.inf
    best_s = 0.0
    for s in (ahead, behind):
        if not math.isfinite(s):
            continue
        s *= 1.0 + JUMP_PAST  # just past the change
        for i in range(size):
            trial[i] = lam[i] + s * x[i]
        phi_j = residual(a, free, target, mu, extra, trial, f2, zn2, zt2, rho2)
        if phi_j < best_phi and mode_changed(zn2, zt2, rho2, zn, zt, rho):
            best_phi = phi_j
            best_s = s
    if not best_phi <= JUMP_GROWTH * phi:
        return False
    for i in range(size):
        lam[i] += best_s * x[i]
    return True


@njit(cache=True, error_model="numpy")
def newton(a, free, target, mu, lam, extra, budget, tolerance, scale):
    """at most ``budget`` steps from ``lam`` (3C,),
    updated in place. Returns the steps taken."""
    c = target.shape[0]
    size = 3 * c
    goal = MARGIN * tolerance * scale
    # One scratch allocation carved into views, not thirteen allocations.
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
    scratch = (trial, f2, zn2, zt2, rho2)
    steps = 0
    jumps = 0
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
        crawl = False
        if accepted:
            crawl = alpha < CRAWL_STEP and phi2 > CRAWL_DECREASE * phi
            # Entry by entry: a slice assignment would compile numpy's broadcast check and
            # the formatting of its error message into the cold start.
            for i in range(size):
                lam[i] = trial[i]
                f[i] = f2[i]
            for i in range(c):
                zn[i] = zn2[i]
                zt[i, 0] = zt2[i, 0]
                zt[i, 1] = zt2[i, 1]
                rho[i] = rho2[i]
            phi = phi2
            steps += 1
        # A stall or a crawl: past a mode change along G's null direction (``newton``).
        if (
            (crawl or not accepted)
            and steps < budget
            and jumps < JUMPS
            and jump(a, free, target, mu, extra, lam, normal, phi, zn, zt, rho, *scratch)
        ):
            phi = residual(a, free, target, mu, extra, lam, f, zn, zt, rho)
            steps += 1
            jumps += 1
            continue
        if not accepted:
            break  # a stall: Gauss–Seidel goes on from λ
    return steps


@njit(cache=True, error_model="numpy")
def converge(
    a, free, target, mu, lam, extra, max_iterations, tolerance, scale, newton_after,
    newton_steps, work, decomposed=False,
):  # fmt: skip
    """rounds of ``newton_after`` Gauss–Seidel sweeps
    with Newton polishes between them, each judged by the sweep after it (undone, with no
    more polishes, if that sweep changes more than the last one before it; λ before the polish
    is kept in ``work``'s last 3C floats) (``decomposed`` as ``gauss_seidel``'s; the rounds
    after the first reuse the first's). Returns (sweeps, converged, Newton steps)."""
    sweeps = 0
    steps = 0
    size = lam.shape[0]
    saved = 3 * size  # work[3 size : 4 size]: λ before the polish
    polish = newton_steps > 0
    while sweeps < max_iterations:
        chunk = min(newton_after, max_iterations - sweeps)
        more, done = gauss_seidel(
            a, free, target, mu, lam, extra, 3, chunk, tolerance, scale, work, decomposed
        )
        decomposed = True
        sweeps += more
        if done:
            return sweeps, True, steps
        if polish and steps < newton_steps and sweeps < max_iterations:
            before = sweep_change(a, work, size)
            for k in range(size):
                work[saved + k] = lam[k]
            steps += newton(a, free, target, mu, lam, extra, newton_steps - steps, tolerance, scale)
            more, done = gauss_seidel(
                a, free, target, mu, lam, extra, 3, np.int64(1), tolerance, scale, work, decomposed
            )
            sweeps += more
            if done:
                return sweeps, True, steps
            if sweep_change(a, work, size) > before:
                for k in range(size):
                    lam[k] = work[saved + k]
                polish = False
    return sweeps, False, steps
