"""The energy guard (``limit_energy``) and the separation (``separate_contacts``) of one element.

Energy guard of a contact step: the contacts add no energy, the loads do their full work.

The invariant. Per batch element, with E = KE + PE_gravity (a spring's potential is not
counted; its force is one of the loads below), u₀ the velocities the step starts with, u₁ those
after the velocity update (the step without contacts), u those the step ends with and

    W(u) = Δt Σ_b (F_b · v_b + τ_b · ω_b),

the work along the step's displacement Δt u of the velocity-independent loads other than
gravity (applied forces, world torques, body torques turned into the world at q₀, springs at
the start pose), the guard enforces

    E_end − W(u) ≤ max(E_start, E_free − W(u₁)),            (1)

E_free the energy of the step without contacts (positions x₀ + Δt u₁). In words: the step ends
with no more energy than it started with plus what the loads put in along the motion it
actually made; the contacts add none. Without loads W = 0 and (1) is E_end ≤ max(E_start,
E_free): no contact response gains energy (any ε ≤ 1, any Δt up to 1 s). The maximum keeps what
the contact-free step itself gains (an integrator's own error), not what it loses: a resting
body's free step falls and loses ½ m g² Δt² (semi-implicit Euler), which must not bound the
work of a push that stays below it.

Why W at the end velocities: semi-implicit Euler moves the bodies by Δt u, so W(u) is a
constant load's exact work along the step's discrete displacement, and the velocity update's
own kinetic energy change from a load F is F·Δt (v₀ + v₁)/2 = W − ½ F² Δt²/m: (1) holds with a
margin of ½ F² Δt²/m per pushed body, so rounding never scales a push away.

How: before the position update, if (1) fails, the element's velocities are scaled by the
largest f ∈ [0, 1] that keeps it: E(f) − W(f u) = PE(x₀) + f² KE + f (lin − W(u)) is a
quadratic in f (``scale_to``), and E(0) = PE(x₀) ≤ E_start. Scaling keeps every contact
constraint v_n ≥ −d/Δt. Sources of such a gain: the linearised solve at a large ω Δt, and a
bounce, which moves the body up with its new velocity for the whole step. (1) is checked with
the end positions separated from the ground (the overlap the rotation over the step leaves);
the separation after the position update (``SeparateContacts``) then lifts the bodies and pays
the lift's potential energy out of the kinetic energy, keeping E − W unchanged (``pay``), so
the step ends at or below the bound; what cannot be paid is reported
(``ContactReport.unpaid_energy``).

Price: the stored velocities of semi-implicit Euler are step means, so even an exact elastic
bounce ends its step with E above E_start by m g Δt v⁺ (repaid during the flight up); the guard
takes that out, and a ball with ε = 1 loses at most Δt v⁺ of height per bounce — first order in
Δt (``restitution`` alone keeps the modified energy exactly).

What the contacts removed (``ContactReport.energy_removed``, per element): the work of the
contact impulses against the bodies at the step's mean velocity (the trapezoid rule), less the
potential energy the separation's lift added,

    removed = −Σ_b (u_b − u₁_b)ᵀ M_b (u₀_b + u_b) / 2 − ΔPE_separation,

M_b = diag(m_b I, R₀ M0_b R₀ᵀ). It is exact bookkeeping: ½ uᵀMu − ½ u₀ᵀMu₀ = (u₁ − u₀)ᵀ M
(u₀ + u)/2 − removed − ΔPE_separation. It is 0 for a body at rest, pushed on frictionless
ground, or in flight; the friction work for a sliding body; the kinetic energy lost in an
inelastic impact; and the guard's price above.

Both run for every engaged element, a resting box included, so they keep no scratch arrays
and few views (an allocation, and a view's reference counting, cost per element):
per-body quantities (u₁, the path's orientation, the base position, the separated end
position) are recomputed where they are used, by the same operations, and the data arrays are
indexed in place (``contact_assembly.offsets``).
"""

from __future__ import annotations

import math

import numpy as np

from ..contacts.stages import MAX_HALVINGS
from .bodies import BODY_WIDTH, DIAGONAL, INERTIA, inertia_times
from .cache import njit
from .contact_assembly import (
    F_DT,
    F_GRAVITY,
    I_GRAVITY,
    I_GROUND,
    I_N,
    I_SPRINGS,
    I_V,
    O_BODY,
    O_FOOT,
    O_MASS,
    O_POINTS,
    O_RECORD,
    O_SHAPED,
    O_SPRINGS,
    contact_data,
    offsets,
    tuple9,
)
from .contact_pairs import pair_pushes
from .forces import S_ANCHOR, S_ATTACH, S_BODY, S_K, S_REST, SPRING_WIDTH
from .layout import (
    CONTACT,
    DISPLACEMENT,
    ELAPSED,
    ENERGY_REMOVED,
    ENGAGED,
    FORCE,
    LOADED,
    PATH_Q,
    Q0,
    REPORT,
    TORQUE,
    U1,
    UNPAID_ENERGY,
    UPDATE_DOT,
    V0,
    W0,
    X0,
    Q,
    V,
    W,
    X,
)
from .registry import Kernel, register
from .rotation import (
    cross,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    quat_to_matrix,
)
from .steps import BODY_TORQUE


@njit(cache=True, error_model="numpy", inline="always")
def kinetic_term(floats, at, q, v, w):
    """A body's term of the kinetic energy at orientation q of velocities v, ω (tuples), its
    ``bodies`` row starting at ``floats[at]`` (indexed in place: no view)."""
    rot = quat_to_matrix(q)
    m0 = tuple9(floats, at + INERTIA)
    spin = inertia_times(floats[at + DIAGONAL] != 0.0, m0, rot, w)
    lin = 0.5 * floats[at] * (v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    return lin + 0.5 * (w[0] * spin[0] + w[1] * spin[1] + w[2] * spin[2])


@njit(cache=True, error_model="numpy", inline="always")
def potential_term(floats, o, b, x):
    """Body b's m (x · g) (the potential energy is −Σ of these), gravity ``floats[F_GRAVITY:]``."""
    m = floats[o[O_MASS] + b]
    g = F_GRAVITY
    return m * (x[0] * floats[g] + x[1] * floats[g + 1] + x[2] * floats[g + 2])


@njit(cache=True, error_model="numpy", inline="always")
def potential_end(has_gravity, total):
    """The potential energy from the sum of ``potential_term``: 0 without gravity."""
    return -total if has_gravity else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def slot_of(ints, o, b):
    """The shaped index g of body b (its contacts' slots start at g·K), or −1."""
    for g in range(ints[I_GROUND]):
        if ints[o[O_SHAPED] + g] == b:
            return g
    return -1


@njit(cache=True, error_model="numpy", inline="always")
def record_of(ints, o, b):
    """The contact row that holds body b's record (``U1``, ``PATH_Q``), or −1 (no contact)."""
    return ints[o[O_RECORD] + b]


@njit(cache=True, error_model="numpy", inline="always")
def depth(floats, o, ints, g, q, z):
    """The separation (ground) of shaped body g at orientation q and height z: its
    deepest overlap, 0 if none. The deepest of its K lowest points is its deepest."""
    points = o[O_POINTS] + 3 * ints[I_V] * g
    foot = floats[o[O_FOOT] + g]
    deepest = 0.0
    for i in range(ints[I_V]):
        p = points + 3 * i
        arm = quat_rotate(q, (floats[p], floats[p + 1], floats[p + 2]))
        gap = z + (arm[2] + foot)
        deepest = max(deepest, -gap)
    return deepest


@njit(cache=True, error_model="numpy", inline="always")
def vec3(a, e, b):
    return (a[e, b, 0], a[e, b, 1], a[e, b, 2])


@njit(cache=True, error_model="numpy", inline="always")
def vec4(a, e, b):
    return (a[e, b, 0], a[e, b, 1], a[e, b, 2], a[e, b, 3])


@njit(cache=True, error_model="numpy", inline="always")
def velocity_after_update(contact, v, w, e, b, s):
    """u₁ of body b: its (v, ω) after the velocity update, kept by ``assemble`` in its record
    row s (``U1``, ``record_of``); a body without contacts (s < 0): unchanged since then."""
    if s < 0:
        return vec3(v, e, b), vec3(w, e, b)
    return (
        (contact[e, s, U1], contact[e, s, U1 + 1], contact[e, s, U1 + 2]),
        (contact[e, s, U1 + 3], contact[e, s, U1 + 4], contact[e, s, U1 + 5]),
    )


@njit(cache=True, error_model="numpy", inline="always")
def path_orientation(st, e, b, s, elapsed):
    """q_path of body b (``LimitEnergy``): q₀ when no event moved the element, else the
    restitution's ``PATH_Q``, or for a body without contacts its working q turned by
    elapsed ω at once."""
    if not elapsed > 0:
        return vec4(st[Q0], e, b)
    if s >= 0:  # its record row (``record_of``)
        c = st[CONTACT]
        return (c[e, s, PATH_Q], c[e, s, PATH_Q + 1], c[e, s, PATH_Q + 2], c[e, s, PATH_Q + 3])
    w = st[W]
    turn = quat_exp((elapsed * w[e, b, 0], elapsed * w[e, b, 1], elapsed * w[e, b, 2]))
    return quat_multiply(turn, vec4(st[Q], e, b))


@njit(cache=True, error_model="numpy", inline="always")
def base_position(st, e, b, elapsed):
    """x₀ + translation (the path's) of body b: x_end = base + f (Δt − elapsed) v."""
    x0, disp, v = st[X0], st[DISPLACEMENT], st[V]
    return (
        (x0[e, b, 0] + (disp[e, b, 0] - elapsed * v[e, b, 0])) + elapsed * v[e, b, 0],
        (x0[e, b, 1] + (disp[e, b, 1] - elapsed * v[e, b, 1])) + elapsed * v[e, b, 1],
        (x0[e, b, 2] + (disp[e, b, 2] - elapsed * v[e, b, 2])) + elapsed * v[e, b, 2],
    )


@njit(cache=True, error_model="numpy", inline="always")
def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy", inline="always")
def applied_rate(st, e, b, v, w):
    """Body b's applied loads' power F·v + τ·ω (the world force and
    torque and the body torque turned at q₀), at velocities v, ω."""
    fa, ta, tb = st[FORCE], st[TORQUE], st[BODY_TORQUE]
    turned = quat_rotate(vec4(st[Q0], e, b), vec3(tb, e, b))
    t = (ta[e, b, 0] + turned[0], ta[e, b, 1] + turned[1], ta[e, b, 2] + turned[2])
    return dot3(vec3(fa, e, b), v) + dot3(t, w)


@njit(cache=True, error_model="numpy", inline="always")
def has_load(st, e, b):
    """Whether body b carries an applied force, torque or body torque (
    is None without any)."""
    fa, ta, tb = st[FORCE], st[TORQUE], st[BODY_TORQUE]
    found = False
    for i in range(3):
        found = found or fa[e, b, i] != 0.0 or ta[e, b, i] != 0.0 or tb[e, b, i] != 0.0
    return found


@njit(cache=True, error_model="numpy", inline="always")
def spring_rate(floats, o, s, st, e, v, w):
    """Spring s's elastic force's power on its body (``spring_body``) at that body's velocities
    v, ω (``forces.Springs.wrench`` at zero velocity, the start pose: its damping left out, as
    the table read in place."""
    at = o[O_SPRINGS] + SPRING_WIDTH * s
    b = int(floats[at + S_BODY])
    k, rest = floats[at + S_K], floats[at + S_REST]
    arm = quat_rotate(
        vec4(st[Q0], e, b),
        (floats[at + S_ATTACH], floats[at + S_ATTACH + 1], floats[at + S_ATTACH + 2]),
    )
    x0 = st[X0]
    d = (
        x0[e, b, 0] + arm[0] - floats[at + S_ANCHOR],
        x0[e, b, 1] + arm[1] - floats[at + S_ANCHOR + 1],
        x0[e, b, 2] + arm[2] - floats[at + S_ANCHOR + 2],
    )
    if rest > 0:
        length = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        a = -k * (length - rest) / (length if length > 0 else 1.0)
    else:
        a = -k
    f = (a * d[0], a * d[1], a * d[2])
    return dot3(f, v) + dot3(cross(arm, f), w)


@njit(cache=True, error_model="numpy", inline="always")
def spring_body(floats, o, s):
    return int(floats[o[O_SPRINGS] + SPRING_WIDTH * s + S_BODY])


@njit(cache=True, error_model="numpy", inline="always")
def trapezoid_terms(floats, at, q, u0v, u0w, v, w):
    """vᵀ m v₀ + (M ω)·ω₀ and vᵀ m v + ωᵀ M ω of one body (M at orientation q), for
    ``energy_removed``."""
    rot = quat_to_matrix(q)
    m0 = tuple9(floats, at + INERTIA)
    spin = inertia_times(floats[at + DIAGONAL] != 0.0, m0, rot, w)
    m = floats[at]
    cross_term = m * dot3(v, u0v) + dot3(spin, u0w)
    square = m * dot3(v, v) + dot3(spin, w)
    return cross_term, square


@njit(cache=True, error_model="numpy")
def separated(ints, floats, o, x, q, out):
    """The separated positions at poses x (n, 3), q (n, 4) of a scene with body–body contacts:
    out (n, 3) ← x with each body on the ground lifted by its deepest overlap, then each pair
    pushed apart (``contact_pairs.pair_pushes``), both found at (x, q). Returns whether
    anything overlapped."""
    n = x.shape[0]
    push = np.empty((n, 3))
    moved = pair_pushes(ints, floats, o, x, q, push)
    for b in range(n):
        for j in range(3):
            out[b, j] = x[b, j]
    for g in range(ints[I_GROUND]):
        b = ints[o[O_SHAPED] + g]
        deep = depth(floats, o, ints, g, (q[b, 0], q[b, 1], q[b, 2], q[b, 3]), x[b, 2])
        if deep > 0:
            out[b, 2] += deep
            moved = True
    if moved:
        for b in range(n):
            for j in range(3):
                out[b, j] += push[b, j]
    return moved


@njit(cache=True, error_model="numpy")
def separate_pairs(pairs, ints, floats, o, x, q):
    """``separate_contacts``' part in a scene with body–body contacts: x (n, 3) ← its
    separated positions at (x, q), every overlap found before any is removed (``separated``);
    whether anything overlapped (False in a scene without, ``contact_assembly.PAIRS``)."""
    if pairs is None:
        return False
    out = np.empty((x.shape[0], 3))
    moved = separated(ints, floats, o, x, q, out)
    if moved:
        x[:] = out
    return moved


@njit(cache=True, error_model="numpy")
def separated_end_potential(pairs, st, e, ints, floats, o, h, elapsed):
    """Σ_b m (x · g) at the separated end positions of a scene with body–body contacts:
    x_end = base + h v, q_end = exp(h ω) q_path for every body (``LimitEnergy``); 0 in a
    scene without (``contact_assembly.PAIRS``)."""
    if pairs is None:
        return 0.0
    n = ints[I_N]
    x_end, q_end, out = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3))
    v, w = st[V], st[W]
    for b in range(n):
        base = base_position(st, e, b, elapsed)
        for j in range(3):
            x_end[b, j] = base[j] + h * v[e, b, j]
        turn = quat_exp((h * w[e, b, 0], h * w[e, b, 1], h * w[e, b, 2]))
        q_path = path_orientation(st, e, b, record_of(ints, o, b), elapsed)
        qb = quat_normalize(quat_multiply(turn, q_path))
        for j in range(4):
            q_end[b, j] = qb[j]
    separated(ints, floats, o, x_end, q_end, out)
    total = 0.0
    for b in range(n):
        total += potential_term(floats, o, b, (out[b, 0], out[b, 1], out[b, 2]))
    return total


# Called by the driver for every element of a contact step (``driver`` says why a call).
@njit(cache=True, error_model="numpy")
def limit_energy(e, st, d):
    """The ``limit_energy`` stage for one engaged element: scale its velocities so that the step keeps
    the module's invariant (1), E_end − W(u) ≤ max(E_start, E_free − W(u₁)); the
    impacts' path becomes the displacement. Leaves in the report row, for ``separate_contacts``,
    whether loads act (``LOADED``) and the energy removed so far."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        return
    ints, floats, pairs = d
    o = offsets(ints)
    n = ints[I_N]
    has_gravity = ints[I_GRAVITY] != 0
    dt = floats[F_DT]
    contact = st[CONTACT]
    x0, q0, v0, w0, v, w = st[X0], st[Q0], st[V0], st[W0], st[V], st[W]
    elapsed = report[e, ELAPSED]
    tail = dt - elapsed
    # Per body: KE at the start (u₀ at q₀), without contacts (u₁ at q₀, positions x₀ + Δt u₁)
    # and of u along the path (q_path: KE at exp(h ω) q_path equals KE at q_path); PE at x₀,
    # at the base x₀ + translation and at its end base + (Δt − elapsed) v; the loads' power
    # at u₁ and at u (W / Δt).
    ke_start = ke_free = ke = 0.0
    p_start = p_free = p_base = p_tail = 0.0
    rate_free = rate = 0.0
    loaded = ints[I_SPRINGS] > 0
    for b in range(n):
        loaded = loaded or has_load(st, e, b)
        row = record_of(ints, o, b)
        qb0, xb0 = vec4(q0, e, b), vec3(x0, e, b)
        ke_start += kinetic_term(
            floats, o[O_BODY] + BODY_WIDTH * b, qb0, vec3(v0, e, b), vec3(w0, e, b)
        )
        p_start += potential_term(floats, o, b, xb0)
        v1, w1 = velocity_after_update(contact, v, w, e, b, row)
        ke_free += kinetic_term(floats, o[O_BODY] + BODY_WIDTH * b, qb0, v1, w1)
        x_free = (xb0[0] + dt * v1[0], xb0[1] + dt * v1[1], xb0[2] + dt * v1[2])
        p_free += potential_term(floats, o, b, x_free)
        vb, wb = vec3(v, e, b), vec3(w, e, b)
        rate_free += applied_rate(st, e, b, v1, w1)
        rate += applied_rate(st, e, b, vb, wb)
        q_path = path_orientation(st, e, b, row, elapsed)
        ke += kinetic_term(floats, o[O_BODY] + BODY_WIDTH * b, q_path, vb, wb)
        base = base_position(st, e, b, elapsed)
        p_base += potential_term(floats, o, b, base)
        x_tail = (base[0] + tail * vb[0], base[1] + tail * vb[1], base[2] + tail * vb[2])
        p_tail += potential_term(floats, o, b, x_tail)
    for s in range(ints[I_SPRINGS]):
        b = spring_body(floats, o, s)
        v1, w1 = velocity_after_update(contact, v, w, e, b, record_of(ints, o, b))
        rate_free += spring_rate(floats, o, s, st, e, v1, w1)
        rate += spring_rate(floats, o, s, st, e, vec3(v, e, b), vec3(w, e, b))
    work = dt * rate  # W(u); W(f u) = f W(u)
    pe0 = potential_end(has_gravity, p_start)
    e_start = ke_start + pe0
    e_free = ke_free + potential_end(has_gravity, p_free) - dt * rate_free
    pe_base = potential_end(has_gravity, p_base) - pe0
    lin = potential_end(has_gravity, p_tail) - pe0 - pe_base - work
    reference = max(e_start, e_free)
    room = reference - pe0 - pe_base
    slack = 1e-12 * abs(e_start) + 1e-300
    # The largest f ∈ [0, 1] with f² ke + f lin ≤ room.
    room_c = max(room, 0.0)
    if ke + lin <= room_c * (1 + 1e-12) + 1e-300:
        f = 1.0
    else:
        disc = math.sqrt(max(lin * lin + 4 * ke * room_c, 0.0))
        root = (-lin + disc) / (2 * ke) if ke > 0 else 1.0
        f = min(max(root, 0.0), 1.0)
    # The separated end positions must fit as well: halve f until they do.
    over = False
    for _ in range(MAX_HALVINGS):
        h = f * tail
        total = separated_end_potential(pairs, st, e, ints, floats, o, h, elapsed)
        for b in range(n if pairs is None else 0):
            g = slot_of(ints, o, b)
            base = base_position(st, e, b, elapsed)
            vb = vec3(v, e, b)
            z = base[2] + h * vb[2]
            if g >= 0:  # separated at its end orientation exp(h ω) q_path
                turn = quat_exp((h * w[e, b, 0], h * w[e, b, 1], h * w[e, b, 2]))
                q_path = path_orientation(st, e, b, record_of(ints, o, b), elapsed)
                deep = depth(floats, o, ints, g, quat_normalize(quat_multiply(turn, q_path)), z)
                if deep > 0:
                    z += deep
            total += potential_term(floats, o, b, (base[0] + h * vb[0], base[1] + h * vb[1], z))
        pe_end = potential_end(has_gravity, total)
        over = f * f * ke + pe_end - pe0 - pe_base - f * work > room + slack
        if not over:
            break
        f = 0.5 * f
    if over:
        f = 0.0
    moved = elapsed > 0
    q = st[Q]
    disp = st[DISPLACEMENT]
    # energy_removed's trapezoid from the velocities the guard leaves,
    # −½ Σ (u − u₁)ᵀ M (u₀ + u) with M at q₀, and u₁ᵀ M u for ``separate_contacts``.
    trapezoid = 0.0
    update_dot = 0.0
    for b in range(n):
        q_path = (0.0, 0.0, 0.0, 1.0)
        row = record_of(ints, o, b)
        if moved:  # (before the body's ω is scaled: q_path turns a body without contacts)
            q_path = path_orientation(st, e, b, row, elapsed)
        v1, w1 = velocity_after_update(contact, v, w, e, b, row)
        if f < 1:
            for j in range(3):
                v[e, b, j] = v[e, b, j] * f
                w[e, b, j] = w[e, b, j] * f
        at = o[O_BODY] + BODY_WIDTH * b
        qb0, vb0, wb0 = vec4(q0, e, b), vec3(v0, e, b), vec3(w0, e, b)
        vb, wb = vec3(v, e, b), vec3(w, e, b)
        dv = (vb[0] - v1[0], vb[1] - v1[1], vb[2] - v1[2])
        dw = (wb[0] - w1[0], wb[1] - w1[1], wb[2] - w1[2])
        mv = (vb0[0] + vb[0], vb0[1] + vb[1], vb0[2] + vb[2])
        mw = (wb0[0] + wb[0], wb0[1] + wb[1], wb0[2] + wb[2])
        trapezoid += trapezoid_terms(floats, at, qb0, dv, dw, mv, mw)[0]
        update_dot += trapezoid_terms(floats, at, qb0, v1, w1, vb, wb)[0]
        if moved:  # the position update turns q by Δt ω: start it at exp(−elapsed ω) q_path
            h = -elapsed
            back = quat_exp((h * w[e, b, 0], h * w[e, b, 1], h * w[e, b, 2]))
            qb = quat_multiply(back, q_path)
            for j in range(4):
                q[e, b, j] = qb[j]
        # The position update adds translation − elapsed v to x₀ + Δt v .
        for j in range(3):
            disp[e, b, j] = disp[e, b, j] - elapsed * v[e, b, j] if elapsed > 0 else 0.0
    report[e, LOADED] = 1.0 if loaded else 0.0
    report[e, UPDATE_DOT] = update_dot
    report[e, ENERGY_REMOVED] = -0.5 * trapezoid


# Called by the driver for every element of a contact step (``driver`` says why a call).
@njit(cache=True, error_model="numpy")
def separate_contacts(e, st, d):
    """The ``separate_contacts`` stage for one engaged element: remove the overlap the step left and pay
    the lift's potential energy out of the kinetic energy (keeping E − W
    unchanged; what cannot be paid without loads: UNPAID), then ``energy_removed``'s separation
    share. The lift goes into x as it is found, the potential energy summed before and after:
    the operations of separating a copy, without the copy."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        return
    ints, floats, pairs = d
    o = offsets(ints)
    n = ints[I_N]
    has_gravity = ints[I_GRAVITY] != 0
    x, q = st[X], st[Q]
    before = 0.0
    for b in range(n):
        before += potential_term(floats, o, b, vec3(x, e, b))
    moved = separate_pairs(pairs, ints, floats, o, x[e], q[e])
    for g in range(ints[I_GROUND] if pairs is None else 0):
        b = ints[o[O_SHAPED] + g]
        deep = depth(floats, o, ints, g, vec4(q, e, b), x[e, b, 2])
        if deep > 0:
            x[e, b, 2] += deep
            moved = True
    if not moved:
        return
    after = 0.0
    for b in range(n):
        after += potential_term(floats, o, b, vec3(x, e, b))
    lift = potential_end(has_gravity, after) - potential_end(has_gravity, before)
    report[e, ENERGY_REMOVED] -= lift
    if not lift > 0:
        return
    v, w = st[V], st[W]
    # KE at the end orientation: that of q₀ or of the path (``LimitEnergy``'s ``rot0``).
    q_end = q if report[e, ELAPSED] > 0 else st[Q0]
    ke = rate = 0.0
    for b in range(n):
        at = o[O_BODY] + BODY_WIDTH * b
        vb, wb = vec3(v, e, b), vec3(w, e, b)
        ke += kinetic_term(floats, at, vec4(q_end, e, b), vb, wb)
        rate += applied_rate(st, e, b, vb, wb)
    loaded = report[e, LOADED] != 0.0
    for s in range(ints[I_SPRINGS]):
        b = spring_body(floats, o, s)
        rate += spring_rate(floats, o, s, st, e, vec3(v, e, b), vec3(w, e, b))
    if not loaded:
        keep = max(ke - lift, 0.0)
        f = math.sqrt(keep / (ke if ke > 0 else 1.0))
        unpaid = max(lift - ke, 0.0)
        if unpaid > 0:
            report[e, UNPAID_ENERGY] = unpaid
    else:  # with loads: f² ke − f W = ke − W − lift, the larger root
        work = floats[F_DT] * rate
        disc = work * work + 4 * ke * (ke - work - lift)
        f = 1.0
        if ke > 0 and disc >= 0:
            f = min(max((work + math.sqrt(disc)) / (2 * ke), 0.0), 1.0)
    # energy_removed with u → f u: −½ Σ (f uᵀMu₀ + f² uᵀMu − f u₁ᵀMu) in place of the
    # f = 1 terms (u₁ᵀMu₀ is unchanged), M at q₀.
    u_u0 = u_u = 0.0
    for b in range(n):
        at = o[O_BODY] + BODY_WIDTH * b
        qb0 = vec4(st[Q0], e, b)
        terms = trapezoid_terms(
            floats, at, qb0, vec3(st[V0], e, b), vec3(st[W0], e, b), vec3(v, e, b), vec3(w, e, b)
        )
        u_u0 += terms[0]
        u_u += terms[1]
        for j in range(3):
            v[e, b, j] = v[e, b, j] * f
            w[e, b, j] = w[e, b, j] * f
    dot = report[e, UPDATE_DOT]
    report[e, ENERGY_REMOVED] -= 0.5 * ((f - 1) * u_u0 + (f * f - 1) * u_u - (f - 1) * dot)


@register("limit_energy")
def _limit_energy(scene):
    data = contact_data(scene)
    if data is None:
        return None
    return Kernel(__name__, "limit_energy", data)


@register("separate_contacts")
def _separate_contacts(scene):
    data = contact_data(scene)
    if data is None:
        return None
    return Kernel(__name__, "separate_contacts", data)
