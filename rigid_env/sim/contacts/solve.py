"""The contact solve: projected block Gauss–Seidel to a stated tolerance, per batch element.

Problem (one batch element, contacts i with rows n, t₁, t₂, Delassus A, free velocities b):
find impulses λ with v = b + A λ such that, per contact,

* normal: λ_n ≥ 0, v_n ≥ target, λ_n (v_n − target) = 0 (Signorini; the target is −gap/Δt for a
  speculative contact ahead, 0 for a touching one, or a bounce velocity);
* friction: |λ_t| ≤ μ (λ_n + extra) with λ_t = −μ (λ_n + extra) v_t / |v_t| when sliding, v_t = 0
  when sticking (Coulomb's law with the isotropic cone; ``extra`` is the impact impulse the
  contact already carried this step, see ``restitution.py``).

Gauss–Seidel visits the contacts in turn (Erleben, "Velocity-based shock propagation for
multibody dynamics animation", ACM TOG 2007; Catto's sequential impulses, GDC 2005): the normal
row by its exact 1-D solve, then the tangent pair by its exact 2-D solve over the friction disk
(``_disk_step``: the minimiser in the A_tt metric, not a radial projection, which would skew
the friction away from the sliding direction and turn a box sliding diagonally). Each sweep is a descent step of a convex quadratic over a
product of convex sets, so the iteration converges (Jourdan, Alart & Jean, 1998 for the
frictional case with fixed cone radii).

Newton polish (``converge``): an element still unconverged after a round of ``newton_after``
sweeps is handed to a semi-smooth Newton method on the Alart–Curnier function (``newton``),
and the next round of sweeps goes on from its answer (one sweep, when Newton found the root).
That first sweep judges the polish: if it changes the contact velocities more than the last
sweep before it, λ goes back to where the sweeps had it and the element is not polished again.
On BoxLanding's trained-policy states (150 × 512 × 8 steps, 352,786 with contacts) this took
the capped solves from 994 to 573 and the compiled physics from 3.96–3.99 to 3.62–3.70 µs per
element step; in the speed bench's landing batch (Δt = 0.01 s, 1024 boxes, 50 steps) the
capped solves from 170 to 56.

Stopping: a batch element has converged when a whole sweep changes no contact velocity (A Δλ
over the sweep) by more than ``tolerance`` times its velocity scale (the largest free contact
velocity or target of that element; a box–box slot with no contact point has a sentinel target
and counts in no scale, ``contact_scales``). Converged elements drop out; an element that
reaches ``max_iterations`` is reported (``Report``) and its impulse, if it would add kinetic
energy, is cut back along its own direction (``dissipative``).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from .assembly import FAR_GAP, scaled_velocity
from .newton import newton
from .warm_start import active_set_start, particle_start

MAX_ITERATIONS = 500
TOLERANCE = 1e-12
MAX_IMPACTS = 32
STARTS = ("active_set", "particle")
# Sweeps per round between Newton polishes. In the BoxLanding rollout (python -m
# rigid_env.bench.contact_solve --rollout boxlanding --episodes 20): 10 took 13.9 µs per physics
# step and capped 0.07 % of contact steps, 30 took 14.7 µs and capped 0.10 %.
NEWTON_AFTER = 10
NEWTON_STEPS = 50  # Newton steps at most per solve


@dataclass(frozen=True)
class SolverSettings:
    """Settings of the contact solve.

    Parameters
    ----------
    max_iterations : Gauss–Seidel sweeps at most per solve (≥ 1). A solve that stops here
        instead of at the tolerance is reported (``Scene``'s contact report and a
        :class:`ContactSolverWarning`).
    tolerance : relative stopping tolerance in (0, 1): a solve has converged when one sweep
        changes no contact velocity by more than ``tolerance`` × the element's largest free
        contact velocity (m/s). The default 1e-12 sits a few hundred roundings above machine
        precision.
    max_impacts : impacts resolved in time order within one step per batch element (≥ 1); a
        step with more (a long Newton's cradle at a large Δt) is reported like an iteration cap.
    start : ``"active_set"`` (default): when the particle start is not already the solution,
        Gauss–Seidel starts from the active-set direct solve (``warm_start``), which is exact
        for resting and sticking contacts; ``"particle"``: always from the particle start
        (Gauss–Seidel alone; slower to converge on an incline or a resting polyhedron, see
        ``python -m rigid_env.bench.contact_solve``).
    newton_after : Gauss–Seidel sweeps (≥ 1) per round: a solve not converged after a round
        is polished by semi-smooth Newton steps (``contacts.newton``) and the next round
        goes on from Newton's answer, up to ``max_iterations`` sweeps in all.
    newton_steps : Newton steps at most per solve, over all rounds (≥ 0; 0: Gauss–Seidel
        alone); a jump past a change of contact mode (``contacts.newton``) counts as one.
    warm_start : False (default): every step's solve starts as above. True: a step whose
        previous step converged with contacts engaged starts from that step's impulses
        instead (contact slots are fixed per vertex, so slot i is the same contact) and probes
        them with one sweep instead of the particle start; with the active-set start, a probe
        that fails goes on as a cold solve, so no more solves reach the cap (with
        ``"particle"`` it goes on from the probed impulses). The state a step returns carries
        the impulses (``State.contact_impulses``), so the next call starts warm too and k
        calls are bit for bit one call of k steps; a state that carries none (built by hand)
        starts cold. The answer meets the same tolerance as a cold start, not its bits (where
        the friction problem has several solutions, not even the same solution). On
        BoxLanding's rollout states (8 steps per call) it makes the physics ~1.4× cheaper:
        the previous step's impulses are mostly already the answer.
    """

    max_iterations: int = MAX_ITERATIONS
    tolerance: float = TOLERANCE
    max_impacts: int = MAX_IMPACTS
    start: str = "active_set"
    newton_after: int = NEWTON_AFTER
    newton_steps: int = NEWTON_STEPS
    warm_start: bool = False

    def __post_init__(self):
        if not isinstance(self.warm_start, (bool, np.bool_)):
            raise ValueError(f"warm_start must be True or False, got {self.warm_start!r}")
        object.__setattr__(self, "warm_start", bool(self.warm_start))
        for name, low in (
            ("max_iterations", 1),
            ("max_impacts", 1),
            ("newton_after", 1),
            ("newton_steps", 0),
        ):
            value = getattr(self, name)
            try:
                as_int = operator.index(value)
            except TypeError:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}") from None
            if isinstance(value, bool) or as_int < low:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
            object.__setattr__(self, name, int(as_int))
        try:
            tol = float(self.tolerance)
        except (TypeError, ValueError):
            raise ValueError(
                f"tolerance must be a number in (0, 1), got {self.tolerance!r}"
            ) from None
        if not 0 < tol < 1:
            raise ValueError(f"tolerance must be a number in (0, 1), got {self.tolerance!r}")
        object.__setattr__(self, "tolerance", tol)
        if self.start not in STARTS:
            raise ValueError(f"start must be one of {STARTS}, got {self.start!r}")


def gauss_seidel(delassus, free, target, mu, lam, settings, extra=None, changes=None, scale=None):
    """Solve the contact problem of the module docstring for every element of a batch.

    ``delassus`` (N, rC, rC) with r = 3 rows per contact (normal, t₁, t₂) or r = 1 (normal
    only: ``mu`` ignored); ``free`` (N, C, r) the velocities before the impulses, ``target``
    (N, C) the normal targets (−∞ where a contact is out of play), ``mu`` (C,), ``lam`` (N, C, r)
    the start, ``extra`` (N, C) normal impulse already carried (friction budget) or None.
    Returns ``(lam, sweeps, converged)``: sweeps (N,) used, converged (N,) bool; ``changes``
    (N,), when given, receives each element's last sweep change (max |A Δλ|); ``scale`` (N,)
    the stopping test's velocity scale (default ``velocity_scale(free, target)``).
    """
    size, c, r = free.shape
    lam = np.array(lam, dtype=float)
    sweeps = np.zeros(size, int)
    converged = np.zeros(size, bool)
    if size == 0:
        return lam, sweeps, converged
    scale = velocity_scale(free, target) if scale is None else scale
    diag = np.diagonal(delassus, axis1=-2, axis2=-1).reshape(size, c, r)
    inv_n = 1.0 / diag[..., 0]
    if r == 3:
        att = np.stack(
            [delassus[:, 3 * i + 1 : 3 * i + 3, 3 * i + 1 : 3 * i + 3] for i in range(c)], 1
        )
        eig, basis = np.linalg.eigh(att)  # A_tt = Q diag(e) Qᵀ per contact
        coupling = np.stack([delassus[:, 3 * i + 1 : 3 * i + 3, 3 * i] for i in range(c)], 1)
        budget = np.zeros((size, c)) if extra is None else extra
    idx = np.arange(size)
    data = [delassus, free, target, inv_n, scale]
    if r == 3:
        data += [att, eig, basis, coupling, budget]
    work = lam.copy()
    for sweep in range(1, settings.max_iterations + 1):
        a, b, t, i_n, sc = data[:5]
        flat = work.reshape(len(idx), -1)
        before = flat.copy()
        for i in range(c):
            rows = slice(r * i, r * i + r)
            v = b[:, i] + np.einsum("nrk,nk->nr", a[:, rows], flat)
            ln_old = flat[:, r * i]
            ln = np.maximum(ln_old - (v[:, 0] - t[:, i]) * i_n[:, i], 0.0)
            dn = ln - ln_old
            flat[:, r * i] = ln
            if r == 3:
                att_, eig_, q_, cp, bud = data[5:]
                vt = v[:, 1:] + cp[:, i] * dn[:, None]
                lt_old = flat[:, r * i + 1 : r * i + 3]
                lt = _disk_step(
                    att_[:, i], eig_[:, i], q_[:, i], lt_old, vt, mu[i] * (ln + bud[:, i])
                )
                flat[:, r * i + 1 : r * i + 3] = lt
        # The sweep's effect on the contact velocities, A Δλ: impulses that move only within
        # the null space of redundant contacts (four corners of a face) change no motion.
        change = np.max(np.abs(np.einsum("nij,nj->ni", a, flat - before)), axis=-1)
        done = change <= settings.tolerance * sc
        sweeps[idx] = sweep
        if changes is not None:
            changes[idx] = change
        if done.any():
            lam[idx[done]] = work[done]
            converged[idx[done]] = True
            keep = ~done
            if not keep.any():
                return lam, sweeps, converged
            idx = idx[keep]
            work = work[keep]
            data = [d[keep] for d in data]
    lam[idx] = work
    return lam, sweeps, converged


def velocity_scale(free, target):
    """The velocity scale (N,) of the stopping tests: the element's largest free contact
    velocity (``free`` (N, C, r)) or finite target (``target`` (N, C))."""
    size = len(free)
    finite = np.isfinite(target)
    scale = np.max(np.abs(free.reshape(size, -1)), axis=-1)
    scale = np.maximum(scale, np.max(np.where(finite, np.abs(target), 0.0), axis=-1))
    return np.maximum(scale, 1e-300)


def contact_scales(free, target, short, gap):
    """The stopping tests' velocity scale (N,) and the active-set start's shortfall scale (N,)
    (``warm_start.PUSH_TOLERANCE``), over the slots that hold a contact point.

    A box–box slot with no contact point (separated boxes whose faces do not overlap) has the
    sentinel gap ``box_box.FAR`` = 1e9 m, which keeps it out of every step's reach with finite
    arithmetic; its target −FAR/Δt (−2.4e11 m/s at Δt = 1/240 s) is no velocity of the
    problem. Counted in the scale, it made the stopping test accept any sweep that changed the
    contact velocities by less than 1e-12 × 2.4e11 = 0.24 m/s, six times a resting stack's free
    velocity g Δt = 0.041 m/s: a pyramid's particle start (each box stopped as a particle on the
    ground, nothing between the boxes) passed its probe sweep, so the boxes sank ~0.1 mm a step
    into each other and into the ground, and the separation stage lifted them back a little
    askew each time (~5 mm in 2 s), paying the lift out of the kinetic energy (v = 0 after
    every step). A tower or a 2-1 pyramid has no such slot (every pair's faces overlap in
    projection) and stayed at rest; a 3-2 pyramid has two (the outer bottom box and the far
    box above it) and moved too. Such a slot's target stays in the problem (it keeps the
    slot's impulse at 0); only the scales leave it out (``assembly.FAR_GAP``, as
    ``pair_apart`` tells those slots). Scenes without such slots are unchanged. The compiled
    solve applies the same rule (``compiled.contact_solve``)."""
    contact = gap < FAR_GAP
    scale = velocity_scale(free, np.where(contact, target, -np.inf))
    shortfall = np.max(np.abs(np.where(contact, short, 0.0)), axis=-1)
    return scale, shortfall


DISK_NEWTON_STEPS = 8  # the secular equation's Newton iteration converges quadratically from γ = 0


def _disk_step(att, eig, q, lt, vt, cap):
    """The tangent impulse (N, 2) that minimises the contact's kinetic energy over the friction
    disk |λ_t| ≤ cap: the sticking impulse λ_t − A_tt⁻¹ v_t if it lies inside, else the point
    of the circle (A_tt + γ I) λ = A_tt λ_t − v_t with γ ≥ 0 from the secular equation
    1/|λ(γ)| = 1/cap, solved by Newton's method (Moré & Sorensen, "Computing a trust region
    step", 1983). At that point the sliding velocity after the update is −γ λ: the impulse
    opposes the sliding exactly (Coulomb's maximal dissipation)."""
    rhs = np.einsum("nij,nj->ni", att, lt) - vt
    p = np.einsum("nji,nj->ni", q, rhs)  # Qᵀ rhs
    inside_l = p / eig
    norm = np.sqrt(np.sum(inside_l * inside_l, axis=-1))
    out = norm > cap
    if not out.any():
        return np.einsum("nij,nj->ni", q, inside_l)
    # A cap below rounding of the impulse: the radial point (the secular equation's root
    # would lie beyond floating range).
    radial = cap <= 1e-12 * norm
    gamma = np.zeros(len(p))
    p2 = p * p
    inv_cap = 1.0 / np.where(cap > 0, cap, 1.0)
    p2 = np.where(radial[:, None], 0.0, p2)
    done = np.zeros(len(p), bool)
    for _ in range(DISK_NEWTON_STEPS):
        # Newton on 1/|λ(γ)| − 1/cap: the step ψ/ψ' = f (1 − √f/cap) / f' with f = |λ(γ)|²,
        # f' = Σ pᵢ²/dᵢ³ (the derivative up to −2), in reciprocals: 3 divisions, not 6.
        r = 1.0 / (eig + gamma[:, None])
        q2 = p2 * (r * r)
        f = q2[:, 0] + q2[:, 1]
        fp = q2[:, 0] * r[:, 0] + q2[:, 1] * r[:, 1]
        root = np.sqrt(f)
        step = np.where(done, 0.0, f * (1.0 - root * inv_cap) / np.where(fp > 0, fp, 1.0))
        gamma = np.maximum(gamma - step, 0.0)
        # Converged entries stay put: an element's result does not depend on its batch.
        done |= np.abs(step) <= 1e-15 * gamma
        if done.all():
            break
    l_disk = p / (eig + gamma[:, None])
    size = np.sqrt(np.sum(l_disk * l_disk, axis=-1))
    l_disk *= (cap / np.where(size > 0, size, 1.0))[:, None]  # exactly on the circle
    l_disk = np.where(
        radial[:, None], inside_l * (cap / np.where(norm > 0, norm, 1.0))[:, None], l_disk
    )
    l_local = np.where(out[:, None], l_disk, inside_l)
    return np.einsum("nij,nj->ni", q, l_local)


def converge(delassus, free, target, mu, lam, settings, extra, scale=None):
    """Gauss–Seidel in rounds of ``newton_after`` sweeps, each unconverged element polished by
    Newton steps between rounds (``newton_steps`` in all per element), until it converges or
    has used ``max_iterations`` sweeps (arguments as :func:`gauss_seidel`, r = 3). A Newton
    polish that stalls (a local minimum of |F|² where the Jacobian is singular) is left by the
    next round of sweeps, from where Newton starts again. Rounds of sweeps from the same λ are
    the same sweeps as one run, so ``newton_steps`` = 0 is plain Gauss–Seidel.

    A polish is judged by the sweep after it: if that sweep changes the contact velocities
    more than the last sweep before it did, Newton has made things worse (it reduces |F|², not
    Gauss–Seidel's change, and can carry λ far along the null space of a face's redundant
    corners, where Gauss–Seidel then crawls), so λ goes back to where the sweeps had it and the
    element is not polished again. ``scale`` (N,): the stopping tests' velocity scale
    (default ``velocity_scale(free, target)``). Returns ``(lam, sweeps, converged,
    newton_steps)``."""
    size = len(free)
    scale = velocity_scale(free, target) if scale is None else scale
    lam = np.array(lam, dtype=float)
    sweeps = np.zeros(size, int)
    steps = np.zeros(size, int)
    converged = np.zeros(size, bool)
    polish = np.full(size, settings.newton_steps > 0)
    changes = np.zeros(size)
    idx = np.arange(size)
    used = 0  # every unconverged element has used the same sweeps

    def sweep(count):
        """``count`` sweeps of the unconverged elements; returns those still unconverged."""
        out = np.zeros(len(idx))
        lam[idx], more, done = gauss_seidel(
            delassus[idx],
            free[idx],
            target[idx],
            mu,
            lam[idx],
            SolverSettings(count, settings.tolerance),
            extra[idx],
            out,
            scale[idx],
        )
        changes[idx] = out
        sweeps[idx] += more
        converged[idx] = done
        return idx[~done]

    while len(idx) and used < settings.max_iterations:
        chunk = min(settings.newton_after, settings.max_iterations - used)
        idx = sweep(chunk)
        used += chunk
        budget = settings.newton_steps - steps[idx]
        go = idx[(budget > 0) & polish[idx]]
        if len(go) and used < settings.max_iterations:
            before, saved = changes[go], lam[go]
            lam[go], taken = newton(
                delassus[go],
                free[go],
                target[go],
                mu,
                lam[go],
                extra[go],
                settings.newton_steps - steps[go],
                settings.tolerance,
                scale[go],
            )
            steps[go] += taken
            idx = sweep(1)  # judges the polish (for the others, one more sweep)
            used += 1
            worse = ~converged[go] & (changes[go] > before)
            lam[go[worse]] = saved[worse]
            polish[go[worse]] = False
    return lam, sweeps, converged, steps


def solve_inelastic(layout, rows, u, impulse, dt, settings, gap=None, remaining=None, warm=None):
    """The step's inelastic solve for the engaged elements: velocities u (N, n, 6) after it,
    sweeps (N,), converged (N,), Newton steps (N,) and the impulses λ (N, C, 3). Targets
    ``v_n ≥ −d/Δt`` for a gap d > 0 (a speculative
    contact: the body may close the gap this step, no more — no tunnelling; Catto, "Contact
    Manifolds", 2014 / Box2D v3) and ``v_n ≥ 0`` for d ≤ 0; ``impulse`` (N, C) is the normal
    impulse of this step's impacts, which friction may also use; ``gap`` (N, C) and
    ``remaining`` (N,) the gaps and time left after the impacts (default: the step's);
    ``warm`` None or (λ (N, C, 3), usable (N,) bool): what the probe sweep starts from for the
    usable elements instead of the particle start (``SolverSettings.warm_start``)."""
    free = rows.velocity(u, layout)
    if gap is None:
        gap, remaining = rows.gap, np.full(len(u), dt)
    target = np.where(gap > 0, -gap / remaining[:, None], 0.0)
    short = target - free[..., 0]
    scale, shortfall = contact_scales(free, target, short, gap)
    # First the cheap particle start (exact for a box resting or landing flat): one sweep
    # tells whether it already is the solution.
    lam = np.zeros(free.shape)
    particle_start(layout, short, lam[..., 0])
    if warm is not None:
        lam[warm[1]] = warm[0][warm[1]]
    probe = SolverSettings(1, settings.tolerance, settings.max_impacts, settings.start)
    lam, sweeps, converged = gauss_seidel(
        rows.delassus, free, target, layout.mu, lam, probe, extra=impulse, scale=scale
    )
    steps = np.zeros(len(u), int)
    if not converged.all():
        rest = np.flatnonzero(~converged)
        # A warm start that fails its probe goes on as a cold solve (the same rounds from the
        # active-set start): warm-started solves are capped no more often than cold ones.
        if settings.start == "particle":
            start = lam[rest]
        else:
            sub = rows.take(rest)
            # Contacts that can carry load: the violated ones and those the step's largest
            # velocity correction could close (resting contacts whose v_n is rounding noise).
            reach = dt * np.max(np.maximum(short[rest], 0.0), axis=-1, keepdims=True)
            reachable = (short[rest] > 0) | (gap[rest] <= reach)
            start = active_set_start(
                layout,
                short[rest],
                sub.delassus,
                free[rest, :, 1:],
                reachable,
                impulse[rest],
                shortfall[rest],
            )
        lam[rest], more, converged[rest], steps[rest] = converge(
            rows.delassus[rest],
            free[rest],
            target[rest],
            layout.mu,
            start,
            settings,
            impulse[rest],
            scale[rest],
        )
        sweeps[rest] += more
    if not converged.all():
        bad = np.flatnonzero(~converged)
        sub = rows.take(bad)
        z = scaled_velocity(layout, u[bad], sub.scale)[..., 0]
        dz = (lam[bad].reshape(len(bad), 1, -1) @ sub.jt)[:, 0]
        lam[bad], _ = dissipative(lam[bad], dz, z)
    return u + rows.velocity_change(lam, layout), sweeps, converged, steps, lam


def dissipative(lam, dz, z):
    """Cut an unconverged impulse back so it adds no kinetic energy.

    In z = M^(1/2) u coordinates KE = ½|z|² and an impulse moves z by dz = J̃ᵀ λ, so
    ΔKE = z·dz + ½|dz|². At a solution every term of λᵀ v⁺ is ≤ 0 (λ_n > 0 only where v_n⁺ =
    target ≤ 0; friction opposes v_t⁺), so ΔKE = λᵀ v⁺ − ½ λᵀ A λ ≤ 0. An impulse that adds
    energy is no solution; it is scaled to the most dissipative point of its own ray,
    s = −z·dz / |dz|² clipped to [0, 1]. ``lam`` (N, …), ``dz`` and ``z`` (N, 6n)."""
    lin = np.sum(z * dz, axis=-1)
    quad = np.sum(dz * dz, axis=-1)
    gains = lin + 0.5 * quad > 1e-12 * np.sum(z * z, axis=-1)
    if not np.any(gains):
        return lam, dz
    s = np.where(gains, np.clip(-lin / np.where(quad > 0, quad, 1.0), 0.0, 1.0), 1.0)
    shape = (-1,) + (1,) * (lam.ndim - 1)
    return lam * s.reshape(shape), dz * s[:, None]


__all__ = [
    "SolverSettings",
    "contact_scales",
    "converge",
    "dissipative",
    "gauss_seidel",
    "solve_inelastic",
    "velocity_scale",
]
