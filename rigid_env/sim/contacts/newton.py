"""Semi-smooth Newton polish of the contact problem (``solve``'s module docstring), batched.

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
polish whose next sweep changes more than the last one before it (``solve.converge``).
"""

from __future__ import annotations

import numpy as np

ARMIJO = 1e-4  # sufficient decrease of |F|² per unit step (Nocedal & Wright, 2006, §3.1)
# Line-search halvings before the step is called a stall. The short steps they allow (α down
# to 1e-9) do the work in the hardest solves: before the jumps below, with 10, the capped solves
# of BoxLanding's trained-policy states (150 × 512 × 8 cold single steps, 352,787 engaged) went
# from 1,660 to 3,458.
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
# "Matrix Computations", 2013, §7.6.1) from the ones vector. On the states of HALVINGS' note:
# capped solves 1,660 → 980, solves over 100 sweeps 1,375 → 66, and the physics 5.45–5.52 →
# 4.64–4.72 µs per element step (8-step warm calls, compiled, one run); under random actions
# (150 × 512 × 8, 462,961 engaged) capped 436 → 421. JUMPS 12 capped 1,041.
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
# Levenberg–Marquardt method", Computing Suppl. 15, 2001) capped more solves on the states of
# HALVINGS' note (1,855 against 1,660, before the jumps): what stopped Newton there was a
# mode it could not change, which the jumps handle.
RIDGE = 1e-14
# Newton stops when no contact's residual, in velocity units (|F| A_nn), exceeds this share of
# the solve's tolerance × scale: the closing Gauss–Seidel sweep then meets the tolerance.
MARGIN = 1e-2
# r = GAIN / A_nn: any r > 0 gives the same roots; 10 converged 148 of 153 capped BoxLanding
# cases against 146 for 1 (the rollout bench's cases, measured when the polish was written).
GAIN = 10.0


def residual(delassus, free, target, mu, extra, lam):
    """The Alart–Curnier function F (N, C, 3) at ``lam`` (N, C, 3) and what its Jacobian
    needs: (F, r (N, C), z_n (N, C), z_t (N, C, 2), ρ (N, C))."""
    size, c, _ = lam.shape
    a_nn = np.diagonal(delassus, axis1=-2, axis2=-1)[:, 0::3]
    r = GAIN / a_nn
    v = free + np.einsum("nij,nj->ni", delassus, lam.reshape(size, -1)).reshape(size, c, 3)
    with np.errstate(invalid="ignore"):  # a −∞ target (contact out of play): z_n = −∞
        z_n = lam[..., 0] - r * (v[..., 0] - target)
    p_n = np.maximum(z_n, 0.0)
    rho = mu * (p_n + extra)
    z_t = lam[..., 1:] - r[..., None] * v[..., 1:]
    norm = np.sqrt(np.sum(z_t * z_t, axis=-1))
    out = norm > rho
    p_t = np.where(out[..., None], z_t * (rho / np.where(out, norm, 1.0))[..., None], z_t)
    f = lam - np.concatenate((p_n[..., None], p_t), -1)
    return f, r, z_n, z_t, rho


def jacobian(delassus, mu, r, z_n, z_t, rho):
    """An element G (N, 3C, 3C) of the generalised Jacobian of ``residual``: G = I − ∂P ∂z/∂λ
    with ∂z/∂λ = I − R A (R: r of each contact on its three rows)."""
    size, c = r.shape
    n = 3 * c
    eye = np.eye(n)
    m = (eye - np.repeat(r, 3, axis=-1)[..., None] * delassus).reshape(size, c, 3, n)
    active = (z_n > 0)[..., None]
    dn = np.where(active, m[:, :, 0], 0.0)  # ∂ max(z_n, 0)
    norm = np.sqrt(np.sum(z_t * z_t, axis=-1))
    out = norm > rho
    unit = z_t / np.where(out, norm, 1.0)[..., None]
    shrink = rho / np.where(out, norm, 1.0)
    mt = m[:, :, 1:]  # (N, C, 2, n)
    tangent_proj = np.einsum("nci,ncj->ncij", unit, unit)
    proj = (np.eye(2) - tangent_proj) * shrink[..., None, None]
    dt_out = np.einsum("ncij,ncjk->ncik", proj, mt) + np.einsum(
        "nci,nck->ncik", unit * mu[:, None], dn
    )
    dt = np.where(out[..., None, None], dt_out, mt)
    dp = np.concatenate((dn[:, :, None], dt), 2).reshape(size, n, n)
    return eye - dp


def mode(z_n, z_t, rho):
    """(N, 2C) bool: each contact's z_n > 0, then each contact's |z_t| > ρ."""
    return np.concatenate((z_n > 0, np.sqrt(np.sum(z_t * z_t, axis=-1)) > rho), -1)


def quadratic_roots(c0, c1, c2):
    """(..., 2) real roots of c0 + 2 c1 s + c2 s², NaN where there are fewer (a degenerate
    c2 = 0 equation, linear, has one): the root without cancellation, then the other by
    Vieta's product c0 / c2."""
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = c1 * c1 - c0 * c2
        q = -(c1 + np.copysign(np.sqrt(np.maximum(disc, 0.0)), c1))
        first = np.where(q != 0.0, q / c2, 0.0)
        second = np.where(q != 0.0, c0 / q, np.nan)
        none = disc < 0.0
        first = np.where(none, np.nan, first)
        second = np.where(none, np.nan, second)
        linear = np.where(c1 != 0.0, -c0 / (2.0 * c1), np.nan)
        flat = c2 == 0.0
        return np.stack((np.where(flat, linear, first), np.where(flat, np.nan, second)), -1)


def mode_events(delassus, mu, extra, z_n, z_t, x):
    """(N, 5C) lengths s at which a contact's mode changes along λ + s x (``jump``; NaN:
    none): z_n crossing 0, and |z_t| crossing ρ where z_n(s) > 0 and where it is not."""
    size, c = z_n.shape
    a_nn = np.diagonal(delassus, axis1=-2, axis2=-1)[:, 0::3]
    r = GAIN / a_nn
    ax = np.einsum("nij,nj->ni", delassus, x).reshape(size, c, 3)
    d = x.reshape(size, c, 3) - r[..., None] * ax
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.where(d[..., 0] != 0.0, -z_n / d[..., 0], np.nan)
    tt = np.sum(z_t * z_t, axis=-1)
    td = np.sum(z_t * d[..., 1:], axis=-1)
    dd = np.sum(d[..., 1:] * d[..., 1:], axis=-1)
    p = mu * (z_n + extra)
    q = mu * d[..., 0]
    active = quadratic_roots(tt - p * p, td - p * q, dd - q * q)
    active = np.where(z_n[..., None] + active * d[..., :1] > 0, active, np.nan)
    p = mu * extra
    inactive = quadratic_roots(tt - p * p, td, dd)
    inactive = np.where(z_n[..., None] + inactive * d[..., :1] > 0, np.nan, inactive)
    return np.concatenate((normal[..., None], active, inactive), -1).reshape(size, 5 * c)


def jump(delassus, free, target, mu, extra, lam, normal, phi, z_n, z_t, rho):
    """λ (N, C, 3) moved past the first change of contact mode along ± the null direction of G
    (module note at ``CRAWL_STEP``), ``normal`` (N, 3C, 3C) the step's regularised GᵀG, ``phi``
    (N,) |F|² at λ. Returns (moved λ, jumped (N,) bool); λ is unchanged where not jumped."""
    size = len(lam)
    x = np.ones(normal.shape[:-1])
    for _ in range(2):  # inverse iteration
        x = np.linalg.solve(normal, x[..., None])[..., 0]
        x /= np.sqrt(np.sum(x * x, axis=-1, keepdims=True))
    flat = lam.reshape(size, -1)
    floor = np.max(np.abs(flat), axis=-1) * JUMP_FLOOR
    events = mode_events(delassus, mu, extra, z_n, z_t, x)
    with np.errstate(invalid="ignore"):
        ahead = np.min(np.where(events > floor[:, None], events, np.inf), axis=-1)
        behind = np.max(np.where(events < -floor[:, None], events, -np.inf), axis=-1)
    base = mode(z_n, z_t, rho)
    best_phi = np.full(size, np.inf)
    best_s = np.zeros(size)
    for s in (ahead, behind):
        finite = np.isfinite(s)
        s = np.where(finite, s, 0.0) * (1.0 + JUMP_PAST)
        parts = residual(
            delassus, free, target, mu, extra, lam + s[:, None, None] * x.reshape(lam.shape)
        )
        phi_j = np.sum(parts[0] * parts[0], axis=(-1, -2))
        better = finite & (phi_j < best_phi) & np.any(mode(*parts[2:]) != base, axis=-1)
        best_phi = np.where(better, phi_j, best_phi)
        best_s = np.where(better, s, best_s)
    jumped = best_phi <= JUMP_GROWTH * phi
    moved = np.where(jumped[:, None], flat + best_s[:, None] * x, flat).reshape(lam.shape)
    return moved, jumped


def newton(delassus, free, target, mu, lam, extra, budget, tolerance, scale):
    """Newton steps from ``lam`` (N, C, 3) on each element until its residual is below
    ``MARGIN`` × ``tolerance`` × its velocity scale, its line search stalls, or it has taken
    ``budget`` (N,) steps. Returns (lam, steps (N,)). ``delassus`` (N, 3C, 3C), ``free``
    (N, C, 3), ``target`` and ``extra`` (N, C), ``mu`` (C,); ``scale`` (N,) the stopping
    tests' velocity scale (``solve.contact_scales``)."""
    size, c, _ = free.shape
    lam = np.array(lam, dtype=float)
    steps = np.zeros(size, int)
    jumps = np.zeros(size, int)
    budget = np.broadcast_to(budget, (size,))
    if size == 0 or np.max(budget) <= 0:
        return lam, steps
    a_nn = np.diagonal(delassus, axis1=-2, axis2=-1)[:, 0::3]
    goal = MARGIN * tolerance * scale
    idx = np.arange(size)
    f, r, z_n, z_t, rho = residual(delassus, free, target, mu, extra, lam)
    for _ in range(int(np.max(budget))):
        done = np.max(np.abs(f) * a_nn[idx, :, None], axis=(-1, -2)) <= goal[idx]
        done |= steps[idx] >= budget[idx]
        if done.all():
            break
        keep = ~done
        idx, f, r, z_n, z_t, rho = idx[keep], f[keep], r[keep], z_n[keep], z_t[keep], rho[keep]
        a, b, t, x = delassus[idx], free[idx], target[idx], extra[idx]
        g = jacobian(a, mu, r, z_n, z_t, rho)
        normal = np.einsum("nki,nkj->nij", g, g)
        ridge = RIDGE * np.max(np.diagonal(normal, axis1=-2, axis2=-1), axis=-1)
        normal += ridge[:, None, None] * np.eye(g.shape[-1])
        rhs = np.einsum("nki,nk->ni", g, f.reshape(len(idx), -1))
        step = -np.linalg.solve(normal, rhs[..., None])[..., 0].reshape(f.shape)
        phi = np.sum(f * f, axis=(-1, -2))
        alpha = np.ones(len(idx))
        accepted = np.zeros(len(idx), bool)
        best: tuple[np.ndarray, ...] = (f, r, z_n, z_t, rho)
        trial_lam = lam[idx]
        for _ in range(HALVINGS):
            trial = lam[idx] + alpha[:, None, None] * step
            parts = residual(a, b, t, mu, x, trial)
            ok = ~accepted & (
                np.sum(parts[0] * parts[0], axis=(-1, -2)) <= (1.0 - 2.0 * ARMIJO * alpha) * phi
            )
            if ok.any():
                best = tuple(
                    np.where(_expand(ok, p), p, q) for p, q in zip(parts, best, strict=True)
                )
                trial_lam = np.where(ok[:, None, None], trial, trial_lam)
                accepted |= ok
            if accepted.all():
                break
            alpha = np.where(accepted, alpha, 0.5 * alpha)
        lam[idx] = trial_lam
        steps[idx] += accepted
        # A stall or a crawl: past a mode change along G's null direction (CRAWL_STEP's note).
        phi_now = np.where(accepted, np.sum(best[0] * best[0], axis=(-1, -2)), phi)
        crawl = accepted & (alpha < CRAWL_STEP) & (phi_now > CRAWL_DECREASE * phi)
        want = (crawl | ~accepted) & (steps[idx] < budget[idx]) & (jumps[idx] < JUMPS)
        jumped = np.zeros(len(idx), bool)
        if want.any():
            w = np.flatnonzero(want)
            moved, ok = jump(
                a[w],
                b[w],
                t[w],
                mu,
                x[w],
                lam[idx[w]],
                normal[w],
                phi_now[w],
                *(p[w] for p in best[2:]),
            )
            won = w[ok]
            if len(won):
                lam[idx[won]] = moved[ok]
                parts = residual(a[won], b[won], t[won], mu, x[won], moved[ok])
                best = tuple(np.array(p) for p in best)
                for p, q in zip(best, parts, strict=True):
                    p[won] = q
                steps[idx[won]] += 1
                jumps[idx[won]] += 1
                jumped[won] = True
        # A stall that did not jump ends that element's Newton; Gauss–Seidel goes on from λ.
        go_on = accepted | jumped
        idx = idx[go_on]
        f, r, z_n, z_t, rho = (p[go_on] for p in best)
        if len(idx) == 0:
            break
    return lam, steps


def _expand(mask, array):
    return mask.reshape((-1,) + (1,) * (array.ndim - 1))


__all__ = ["newton", "residual", "jacobian", "jump", "mode", "mode_events", "quadratic_roots"]
