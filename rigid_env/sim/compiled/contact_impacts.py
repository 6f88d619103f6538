"""Impacts of one element in time order.

Restitution: impacts resolved one after another in time order within the step.

A semi-implicit step stores v₁ ≈ v(t₀ + Δt/2): velocities are step means, positions follow
x₁ = x₀ + Δt v₁. Impacts are resolved on those velocities before the inelastic solve
(``contact_solve``), each at the time its contact closes:

1. Per contact, its gap d (at the step's start, linearised: d + τ v_n later) closes after
   τ = d / (−v_n). The earliest closing among the *impact* contacts (ε > 0, impact speed above
   the material's threshold, not yet struck this step) is the next event; all impact contacts
   closing at that instant, and those of the same manifold (body on the ground, body pair)
   closing within one step of it (a box landing flat or nearly so: four corners), are struck
   together, each with its own closing time (at most the step's end).
   Supports: before the first event, the element's other contacts (no impact: ε = 0, or
   closing below the threshold) hold from the step's start, by one inelastic normal solve
   (``v_n ≥ −d/Δt``, ``v_n ≥ 0`` touching; the impact contacts out of play); its impulses
   count as the contacts' impulse (the friction budget of the inelastic solve). A box at rest
   on an edge whose far corners strike within the step pivots on the edge until they do,
   instead of sinking through it. The supports act over the whole step, as a force would, so
   the closing contacts' normal acceleration (``s`` below) is taken after them.
2. The struck contacts get Newton's law, v_n⁺ ≥ target, λ ≥ 0, complementarity (normal rows
   only), solved by Gauss–Seidel, together with the *loaded* supports (those that carried
   an impulse in step 1), which hold as they did: v_n⁺ ≥ 0 touching, ≥ −d/Δt at a gap d. A box
   dropped on a box resting on the ground meets a fixed support: it leaves with ε times its
   impact speed and the lower box stays, instead of being driven into the ground. The other
   contacts are free in the event: unloaded contacts pass an impulse on only by an impact of
   their own, in its order (the touching balls of a Newton's cradle in space). The bodies'
   velocities change, so later contacts close at other times (a Newton's cradle: the striker stops, the next ball
   moves, reaches the third, …) and the loop goes on until no impact falls within the step
   (or ``max_impacts``, reported).

Path. The bodies travel with the velocity of each interval: x = x₀ + Σ τₖ uₖ and
q = Π exp(τₖ ωₖ) q₀ up to the last event, then the rest of the step with the final velocity
(the position update adds the difference to x₀ + Δt v as its displacement, and
``limit_energy`` starts its rotation at exp(−elapsed ω) q so that it ends at
exp((Δt − elapsed) ω) q). A ball a Newton's cradle sets moving mid-step travels only the rest
of the step, and the inelastic solve keeps the gaps where the impacts left them, over the
remaining time. Impulses act where the bodies are at the event (``contact_assembly.assemble_pair``): a pair's
impulses at the features' midpoint there, so angular momentum is exact.

The edge freeze (fixed by the supports and the path's orientation): a box at rest tilted on an
edge a fraction of a millimetre from flat, at Δt = 0.01 s. Its far corners close within the
step above the threshold and are struck; without the supports the path before the event was
the free fall through the edge, and without the orientation the end pose lost the pivot's
turn toward flat, so the separation lifted the body back to its start height, the energy
guard (``limit_energy``) found no energy for any motion and zeroed the velocities: tilted and
at rest, the same every step.

Targets. Semi-implicit Euler under a constant non-contact acceleration a (gravity) stores
step-mean velocities: the instantaneous normal velocity at a time t into the step is
w = v_n + a (t − Δt/2). Newton's law acts on it at the closing, w⁺ = −ε w, and the stored
velocity after the event is the step-mean of the outgoing motion, v_n⁺ = −ε w + a (Δt/2 − t).
With the path above, the steps after a bounce sample the outgoing parabola to O(a Δt²):
apexes fall as ε²ᵏ h whatever the impact's phase within the step.

Energy. Each event's velocity change Δu is scaled by the largest α ∈ [0, 1] that keeps the
kinetic energy from growing (Newton's law at several simultaneous contacts can add energy: a
tumbling box with ε = 1); α = min(1, −2 z·dz / |dz|²) in z = M^(1/2) u coordinates. The step's
total energy is guarded after the solve (``contact_energy``).

Every contact of the element, on the ground and between bodies, takes part in every event.
The impact loop reads the normal velocities by the rows of the detection; each event's
impulses act through the pairs' rows moved to where the bodies are at its instant
(``contact_assembly.assemble_pair``), and a sphere pair's gap, normal velocity and closing time
come from its line of centres there (``round_closing``).

The path's translation accumulates in the step tuple's ``DISPLACEMENT`` (per body, zero at the
start); ``limit_energy`` turns it into the position update's displacement. The gaps where the
impacts left the contacts go to ``PATH_GAP``, the impulses to ``IMPULSE``, the time of the
last event to the report's ``ELAPSED``, each body's orientation along the path to its record's
``PATH_Q``.
"""

from __future__ import annotations

import math

import numpy as np

from .cache import njit
from .contact_assembly import (
    F_DT,
    F_TOLERANCE,
    I_C,
    I_GROUND,
    I_K,
    I_MAX_IMPACTS,
    I_MAX_ITERATIONS,
    O_EPS,
    O_OWNER,
    O_RECORD,
    O_ROUND,
    O_THRESHOLD,
    add_impulses,
    assemble_pair,
    block,
    contact_data,
    contact_velocity,
    delassus,
    detected_velocity,
    load_velocities,
    norm,
    offsets,
    scaled_velocity,
    store_velocities,
    unpack,
)
from .contact_gauss_seidel import WORK_PER_CONTACT, gauss_seidel, velocity_scale
from .layout import (
    ARM,
    CAPPED,
    CONTACT,
    DETECTED_A,
    DETECTED_B,
    DETECTED_NORMAL,
    DISPLACEMENT,
    ELAPSED,
    ENGAGED,
    GAP,
    IMPACTS,
    IMPULSE,
    PATH_GAP,
    PATH_Q,
    REPORT,
    V0,
    W0,
    Q,
    V,
    W,
)
from .registry import Kernel, register
from .rotation import cross, quat_exp, quat_multiply


@njit(cache=True, error_model="numpy")
def restitute(e, st, d):
    """The ``restitute`` stage for one engaged element."""
    impacts(e, st, d, d[2])


@njit(cache=True, error_model="numpy")
def impacts(e, st, d, pairs):
    """``restitute``, with its data's ``pairs`` as an argument (``contact_assembly.PAIRS``):
    in a scene with body–body contacts, rows that move with the impacts."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        return
    if not (_may_strike(e, st, d) if pairs is None else _may_strike_pairs(e, st, d)):
        return
    views = unpack(d)
    ints, floats, mu, eps, thr, owner, shaped, mass, rim, lflat, linv = views[:11]
    owner_b = views[15]
    c = owner.shape[0]
    dt = floats[F_DT]
    cs = st[CONTACT][e]
    max_impacts = ints[I_MAX_IMPACTS]
    disp = st[DISPLACEMENT]
    q = st[Q]
    n = st[0].shape[1]
    # One scratch allocation of floats and one of flags, carved into views.
    buf = np.empty(30 * n + 7 * c + c * c + WORK_PER_CONTACT * c)
    u = block(buf, 0, n, 6)
    u0 = block(buf, 6 * n, n, 6)
    z = block(buf, 12 * n, n, 6)
    dz = block(buf, 18 * n, n, 6)
    du = block(buf, 24 * n, n, 6)
    o = 30 * n
    half = buf[o : o + c]
    vn = buf[o + c : o + 2 * c]
    tau = buf[o + 2 * c : o + 3 * c]
    goal = buf[o + 3 * c : o + 4 * c]
    lam = buf[o + 4 * c : o + 5 * c]
    none = buf[o + 5 * c : o + 6 * c]
    gaps = buf[o + 6 * c : o + 7 * c]  # each pass's gaps (a sphere pair's: ``round_closing``)
    o += 7 * c
    o_round, o_record = offsets(ints)[O_ROUND], offsets(ints)[O_RECORD]
    a_nn = block(buf, o, c, c)
    work = buf[o + c * c :]
    flags = np.zeros(4 * c, np.bool_)
    struck, eligible, hit = flags[:c], flags[c : 2 * c], flags[2 * c : 3 * c]
    loaded = flags[3 * c :]  # the supports that carried a load before the events
    none[:] = 0.0
    for b in range(n):
        for j in range(3):
            u0[b, j] = st[V0][e, b, j]
            u0[b, 3 + j] = st[W0][e, b, j]
    load_velocities(st, e, u)
    for i in range(c):  # s: the normal part of half the step's non-contact velocity change
        vn0 = normal_speed(cs, i, owner[i], owner_b[i], u0)
        vn1 = normal_speed(cs, i, owner[i], owner_b[i], u)
        half[i] = 0.5 * (vn1 - vn0)
    k = ints[I_K]
    record = ints[o_record : o_record + n]  # each body's record row (``O_RECORD``)
    for b in range(n):  # the path's orientation starts at the working q
        if record[b] >= 0:
            for j in range(4):
                cs[record[b], PATH_Q + j] = q[e, b, j]
    elapsed = 0.0
    events = 0
    held = False  # the supports' pass (the module docstring) ran
    for _ in range(max_impacts + 2):
        first = math.inf
        for i in range(c):
            round_pair = pairs is not None and ints[o_round + i] != 0
            g, vn[i], close = closing(cs, i, owner[i], owner_b[i], u, disp, e, round_pair)
            gaps[i] = g
            at = min(elapsed + close, dt)
            speed, goal[i] = impact_target(vn[i], half[i], at, eps[i], dt)
            eligible[i] = eps[i] > 0 and vn[i] < 0 and speed > thr[i] and not struck[i]
            tau[i] = close if eligible[i] else math.inf
            first = min(first, tau[i])
        if not first < dt - elapsed:
            break
        supports = not held  # this pass solves the supports, the later ones the events
        if supports:
            # The supports: the contacts that are no impact hold from the step's start.
            for i in range(c):
                g = gaps[i]
                goal[i] = -math.inf if eligible[i] else (-g / dt if g > 0 else 0.0)
            delassus(cs, owner, owner_b, owner[:0], c, 1, a_nn)  # every slot, detected rows
            held = True
        elif events >= max_impacts:
            report[e, CAPPED] = 1.0
            break
        else:
            for i in range(c):
                cs[i, PATH_GAP] = cs[i, PATH_GAP] + first * vn[i]
            elapsed += first
            for b in range(n):
                for j in range(3):
                    disp[e, b, j] += first * u[b, j]
            # The orientation follows the path too in a body's record
            # ``PATH_Q`` (a body without contacts keeps its ω: ``limit_energy`` turns it at once).
            for b in range(n):
                if record[b] < 0:
                    continue
                turn = quat_exp((first * u[b, 3], first * u[b, 4], first * u[b, 5]))
                p = cs[record[b], PATH_Q : PATH_Q + 4]
                qb = quat_multiply(turn, (p[0], p[1], p[2], p[3]))
                for j in range(4):
                    p[j] = qb[j]
            if pairs is not None:
                # A sphere pair's gap, normal velocity and target at the touch, exactly; then
                # every pair's rows where the bodies are now (``contact_assembly.assemble_pair``).
                for i in range(c):
                    if ints[o_round + i] != 0:
                        g, vn[i], close = round_closing(cs, i, owner[i], owner_b[i], u, disp, e)
                        cs[i, PATH_GAP] = g
                        goal[i] = impact_target(
                            vn[i], half[i], min(elapsed + close, dt), eps[i], dt
                        )[1]
                for i in range(ints[I_GROUND] * k, c):
                    round_pair = ints[o_round + i] != 0
                    assemble_pair(
                        e, st, floats, offsets(ints), i, owner[i], owner_b[i], u, True, round_pair
                    )
                delassus(cs, owner, owner_b, owner[:0], c, 1, a_nn)  # every slot
            # Contacts closing together, and the other contacts of their manifolds (a body on the
            # ground, a pair of bodies) closing within one step of the event, are struck together.
            for i in range(c):
                hit[i] = eligible[i] and tau[i] <= first * (1 + 1e-9) + 1e-15
            for i in range(c):
                if hit[i] or not eligible[i] or not tau[i] < first + dt:
                    continue
                for j in range(c):
                    if hit[j] and owner[j] == owner[i] and owner_b[j] == owner_b[i]:
                        hit[i] = True
                        break
            for i in range(c):
                struck[i] = struck[i] or hit[i]
                if not hit[i]:
                    g = cs[i, PATH_GAP]
                    goal[i] = (-g / dt if g > 0 else 0.0) if loaded[i] else -math.inf
                lam[i] = 0.0
            events += 1
        views = (owner, owner_b, lflat, rim, mass, linv, mu)
        scratch = (u, z, dz, du, work)
        if not _event(st, e, cs, views, a_nn, vn, goal, lam, none, scratch, ints, floats):
            report[e, CAPPED] = 1.0
        if supports:
            # The loaded supports hold through every event; the closing contacts' normal
            # acceleration is the one the supports leave (the module docstring).
            for i in range(c):
                loaded[i] = cs[i, IMPULSE] > 0.0 and not eligible[i]
                vn1 = normal_speed(cs, i, owner[i], owner_b[i], u)
                half[i] = 0.5 * (vn1 - normal_speed(cs, i, owner[i], owner_b[i], u0))
    report[e, IMPACTS] = events
    report[e, ELAPSED] = elapsed
    if held:
        store_velocities(st, e, u)


@njit(cache=True, error_model="numpy", inline="always")
def impact_target(vn, half, at, eps, dt):
    """the instantaneous normal velocity at the closing time
    ``at`` (the step-mean v_n plus the normal acceleration 2·half/Δt from the step's middle)
    and Newton's law on it; returns (impact speed, the step-mean target)."""
    rate = 2.0 * half / dt
    w = vn + rate * (at - 0.5 * dt)
    speed = max(-w, 0.0)
    return speed, eps * speed + rate * (0.5 * dt - at)


@njit(cache=True, error_model="numpy", inline="always")
def normal_speed(cs, i, a, b, u):
    """Row 0 of J u at slot i by the detection's rows (the impact loop reads them, also after
    the rows moved to an event)."""
    if b < 0:
        return contact_velocity(cs, i, a, b, u, 0)
    return detected_velocity(cs, i, a, b, u)


@njit(cache=True, error_model="numpy", inline="always")
def closing(cs, i, a, b, u, disp, e, round_pair):
    """(gap, normal velocity, time to close) of slot i at velocities u along the path."""
    if round_pair:
        return round_closing(cs, i, a, b, u, disp, e)
    vn = normal_speed(cs, i, a, b, u)
    g = cs[i, PATH_GAP]
    return g, vn, max(g, 0.0) / (-vn if vn < 0 else 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def round_closing(cs, i, a, b, u, disp, e):
    """Sphere pair slot i at an event: the centres' offset
    d = (ra + rb + gap₀) n₀ + Δshift moves at the centres' relative velocity w, and the spheres
    touch when |d + τ w| = ra + rb (the smaller root, in the form without cancellation).
    Returns (gap, normal velocity, time to close; ∞ for a miss or moving apart)."""
    n0 = (cs[i, DETECTED_NORMAL], cs[i, DETECTED_NORMAL + 1], cs[i, DETECTED_NORMAL + 2])
    ra = norm((cs[i, DETECTED_A], cs[i, DETECTED_A + 1], cs[i, DETECTED_A + 2]))
    rb = norm((cs[i, DETECTED_B], cs[i, DETECTED_B + 1], cs[i, DETECTED_B + 2]))
    radius = ra + rb
    reach = radius + cs[i, GAP]
    d = (
        (reach * n0[0] + disp[e, a, 0]) - disp[e, b, 0],
        (reach * n0[1] + disp[e, a, 1]) - disp[e, b, 1],
        (reach * n0[2] + disp[e, a, 2]) - disp[e, b, 2],
    )
    w = (u[a, 0] - u[b, 0], u[a, 1] - u[b, 1], u[a, 2] - u[b, 2])
    dist = norm(d)
    gap = dist - radius
    dw = d[0] * w[0] + d[1] * w[1] + d[2] * w[2]
    vn = dw / (dist if dist > 1e-12 else 1.0)
    qa = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    qb = 2.0 * dw
    qc = dist * dist - radius * radius
    disc = qb * qb - 4.0 * qa * qc
    if not (qb < 0 and disc >= 0):  # moving apart, or the line passes beyond the radii
        return gap, vn, math.inf
    root = 2.0 * max(qc, 0.0) / (-qb + np.sqrt(max(disc, 0.0)))
    return gap, vn, root if gap > 0 else 0.0


@njit(cache=True, error_model="numpy")
def _may_strike_pairs(e, st, d):
    """``_may_strike`` of a scene with body–body contacts: the loop's first pass, on the
    velocities loaded as the loop loads them."""
    views = unpack(d)
    ints, floats, eps, thr, owner = views[0], views[1], views[3], views[4], views[5]
    owner_b = views[15]
    o_round = offsets(ints)[O_ROUND]
    dt = floats[F_DT]
    cs = st[CONTACT][e]
    n = st[0].shape[1]
    u0, u = np.empty((n, 6)), np.empty((n, 6))
    for b in range(n):
        for j in range(3):
            u0[b, j] = st[V0][e, b, j]
            u0[b, 3 + j] = st[W0][e, b, j]
    load_velocities(st, e, u)
    disp = st[DISPLACEMENT]
    for i in range(owner.shape[0]):
        a, b = owner[i], owner_b[i]
        half = 0.5 * (normal_speed(cs, i, a, b, u) - normal_speed(cs, i, a, b, u0))
        g, vn, close = closing(cs, i, a, b, u, disp, e, ints[o_round + i] != 0)
        speed = impact_target(vn, half, min(close, dt), eps[i], dt)[0]
        if eps[i] > 0 and vn < 0 and speed > thr[i] and not close >= dt:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _may_strike(e, st, d):
    """False when the impact loop's first pass (``restitute``: elapsed 0, nothing struck)
    would find no impact within the step: every contact is no impact contact (ε = 0, not
    closing, or its impact speed not above the threshold) or closes at or after Δt. Then the
    loop breaks at once and changes nothing but ``PATH_Q`` (read only after an event) and the
    report's zeros, so the kernel returns before its scratch and views. The same operations in
    the same order as the loop, on the arrays in place: its verdict, bit for bit."""
    ints, floats = d[0], d[1]
    o = offsets(ints)
    dt = floats[F_DT]
    contact = st[CONTACT]
    v0, w0, v1, w1 = st[V0], st[W0], st[V], st[W]  # (once: each takes a reference count)
    elapsed = 0.0
    for i in range(ints[I_C]):
        b = ints[o[O_OWNER] + i]
        vn0 = _normal_velocity(contact, v0, w0, e, i, b)
        vn = _normal_velocity(contact, v1, w1, e, i, b)
        half = 0.5 * (vn - vn0)
        g = contact[e, i, PATH_GAP]
        close = max(g, 0.0) / (-vn if vn < 0 else 1.0)
        at = min(elapsed + close, dt)
        rate = 2.0 * half / dt
        w = vn + rate * (at - 0.5 * dt)
        speed = max(-w, 0.0)
        eps = floats[o[O_EPS] + i]
        eligible = eps > 0 and vn < 0 and speed > floats[o[O_THRESHOLD] + i]
        # (not close >= Δt rather than close < Δt: a NaN goes the loop's way.)
        if eligible and not close >= dt - elapsed:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _normal_velocity(contact, v, w, e, i, b):
    """``contact_velocity(contact[e], i, b, u, 0)`` with u = (v, ω)[e, b]: the same operations."""
    basis = (0.0, 0.0, 1.0)
    arm = (contact[e, i, ARM], contact[e, i, ARM + 1], contact[e, i, ARM + 2])
    rxb = cross(arm, basis)
    return (basis[0] * v[e, b, 0] + basis[1] * v[e, b, 1] + basis[2] * v[e, b, 2]) + (
        rxb[0] * w[e, b, 0] + rxb[1] * w[e, b, 1] + rxb[2] * w[e, b, 2]
    )


@njit(cache=True, error_model="numpy")
def _event(st, e, cs, views, a_nn, vn, goal, lam, none, scratch, ints, floats):
    """Newton's law ``v_n ≥ goal`` (−∞: out of play) by Gauss–Seidel
    from zero, the impulses scaled by the largest α ∈ [0, 1] that adds no kinetic energy, added
    to u and to the contacts' ``IMPULSE``. ``views``: (owner, owner b, L, 1/√m, mass, L⁻¹, μ)
    of ``unpack``; ``scratch``: (u, z, dz, du, work). Returns whether the solve converged."""
    owner, owner_b, lflat, rim, mass, linv, mu = views
    u, z, dz, du, work = scratch
    max_iterations, tolerance = ints[I_MAX_ITERATIONS], floats[F_TOLERANCE]
    n = u.shape[0]
    c = lam.shape[0]
    for i in range(c):
        lam[i] = 0.0
    scale = velocity_scale(vn, goal)
    _, converged = gauss_seidel(
        a_nn, vn, goal, mu, lam, none, 1, max_iterations, tolerance, scale, work, np.bool_(False)
    )
    du[:] = 0.0
    add_impulses(st, e, cs, owner, owner_b, lflat, rim, lam, 1, du, 1.0)
    scaled_velocity(st, e, mass, linv, u, z)
    scaled_velocity(st, e, mass, linv, du, dz)
    # The largest α ∈ [0, 1] with |z + α dz| ≤ |z|: the event adds no kinetic energy.
    quad = 0.0
    lin = 0.0
    for b in range(n):
        for j in range(6):
            quad += dz[b, j] * dz[b, j]
            lin += z[b, j] * dz[b, j]
    alpha = -2.0 * lin / quad if quad > 0 else 1.0
    alpha = min(max(alpha, 0.0), 1.0)
    for b in range(n):
        for j in range(6):
            u[b, j] = u[b, j] + alpha * du[b, j]
    for i in range(c):
        cs[i, IMPULSE] += alpha * lam[i]
    return converged


@register("restitute")
def _restitute(scene):
    data = contact_data(scene)
    if data is None:
        return None
    return Kernel(__name__, "restitute", data)
