"""The energy guard and the separation of one element, mirroring ``contacts.stages.LimitEnergy``,
``separated`` and ``SeparateContacts`` with ``contacts.energy`` (see there for why)."""

from __future__ import annotations

import math

import numpy as np

from ..contacts.stages import MAX_HALVINGS
from .bodies import apply_inertia
from .cache import njit
from .contact_assembly import F_DT, I_GRAVITY, I_K, block, contact_data, unpack
from .layout import (
    CONTACT,
    DISPLACEMENT,
    ELAPSED,
    ENGAGED,
    PATH_Q,
    Q0,
    REPORT,
    U1,
    UNPAID_ENERGY,
    V0,
    W0,
    X0,
    Q,
    V,
    W,
    X,
)
from .registry import Kernel, register
from .rotation import quat_exp, quat_multiply, quat_normalize, quat_rotate, quat_to_matrix


@njit(cache=True, error_model="numpy", inline="always")
def kinetic(bd, q, u):
    """``energy.kinetic`` at orientations q (n, 4) of velocities u (n, 6)."""
    total = 0.0
    for b in range(u.shape[0]):
        rot = quat_to_matrix((q[b, 0], q[b, 1], q[b, 2], q[b, 3]))
        w = (u[b, 3], u[b, 4], u[b, 5])
        spin = apply_inertia(bd, b, rot, w)
        lin = 0.5 * bd[b, 0] * (u[b, 0] ** 2 + u[b, 1] ** 2 + u[b, 2] ** 2)
        total += lin + 0.5 * (w[0] * spin[0] + w[1] * spin[1] + w[2] * spin[2])
    return total


@njit(cache=True, error_model="numpy", inline="always")
def kinetic_vw(bd, q, v, w):
    """``kinetic`` of u = (v, ω), read in place from v, ω (n, 3): the same operations."""
    total = 0.0
    for b in range(v.shape[0]):
        rot = quat_to_matrix((q[b, 0], q[b, 1], q[b, 2], q[b, 3]))
        wb = (w[b, 0], w[b, 1], w[b, 2])
        spin = apply_inertia(bd, b, rot, wb)
        lin = 0.5 * bd[b, 0] * (v[b, 0] ** 2 + v[b, 1] ** 2 + v[b, 2] ** 2)
        total += lin + 0.5 * (wb[0] * spin[0] + wb[1] * spin[1] + wb[2] * spin[2])
    return total


@njit(cache=True, error_model="numpy", inline="always")
def potential(mass, gravity, has_gravity, x):
    """``energy.potential``: −Σ m (x · g) of positions x (n, 3)."""
    if not has_gravity:
        return 0.0
    total = 0.0
    for b in range(x.shape[0]):
        total += mass[b] * (x[b, 0] * gravity[0] + x[b, 1] * gravity[1] + x[b, 2] * gravity[2])
    return -total


@njit(cache=True, error_model="numpy")
def separate(x, q, shaped, points, foot):
    """``stages.separated`` (ground): lift each shaped body by its deepest overlap at (x, q),
    in place; False if nothing overlaps. The deepest of its K lowest points is its deepest."""
    moved = False
    for g in range(shaped.shape[0]):
        b = shaped[g]
        qb = (q[b, 0], q[b, 1], q[b, 2], q[b, 3])
        depth = 0.0
        for i in range(points.shape[1]):
            arm = quat_rotate(qb, (points[g, i, 0], points[g, i, 1], points[g, i, 2]))
            gap = x[b, 2] + (arm[2] + foot[g])
            depth = max(depth, -gap)
        if depth > 0:
            x[b, 2] += depth
            moved = True
    return moved


@njit(cache=True, error_model="numpy")
def limit_energy(e, st, d):
    """``LimitEnergy`` for one engaged element: scale its velocities so the step ends with no
    more energy than max(E_start, E_free); the impacts' path becomes the displacement."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        return
    ints, floats, _, _, _, _, shaped, mass, _, _, _, bd, points, foot, gravity = unpack(d)
    has_gravity = ints[I_GRAVITY] != 0
    k = ints[I_K]
    dt = floats[F_DT]
    cs = st[CONTACT][e]
    disp = st[DISPLACEMENT]
    n = st[0].shape[1]
    buf = np.empty(35 * n)  # one scratch allocation, carved into views
    u0 = block(buf, 0, n, 6)
    u1 = block(buf, 6 * n, n, 6)
    u = block(buf, 12 * n, n, 6)
    x0 = block(buf, 18 * n, n, 3)
    scratch = block(buf, 21 * n, n, 3)
    base = block(buf, 24 * n, n, 3)
    q_end = block(buf, 27 * n, n, 4)
    for b in range(n):
        for j in range(3):
            u0[b, j] = st[V0][e, b, j]
            u0[b, 3 + j] = st[W0][e, b, j]
            u[b, j] = st[V][e, b, j]
            u[b, 3 + j] = st[W][e, b, j]
            x0[b, j] = st[X0][e, b, j]
        for j in range(6):
            u1[b, j] = u[b, j]  # a body without contacts: unchanged since the velocity update
    for g in range(shaped.shape[0]):
        for j in range(6):
            u1[shaped[g], j] = cs[g * k, U1 + j]
    elapsed = report[e, ELAPSED]
    tail = dt - elapsed
    q0 = st[Q0][e]
    pe0 = potential(mass, gravity, has_gravity, x0)
    e_start = kinetic(bd, q0, u0) + pe0
    for b in range(n):
        for j in range(3):
            scratch[b, j] = x0[b, j] + dt * u1[b, j]
    e_free = kinetic(bd, q0, u1) + potential(mass, gravity, has_gravity, scratch)
    # The orientation follows the path (``LimitEnergy``): q_path is the restitution's
    # ``PATH_Q`` when an event moved the element (a body without contacts kept its ω: turned
    # by elapsed ω at once), else q₀; KE at exp(h ω) q_path equals KE at q_path.
    moved = elapsed > 0
    q_path = block(buf, 31 * n, n, 4)
    for b in range(n):
        for j in range(4):
            q_path[b, j] = q0[b, j]
    if moved:
        for b in range(n):
            h = elapsed
            turn = quat_exp((h * u[b, 3], h * u[b, 4], h * u[b, 5]))
            qb = quat_multiply(
                turn, (st[Q][e, b, 0], st[Q][e, b, 1], st[Q][e, b, 2], st[Q][e, b, 3])
            )
            for j in range(4):
                q_path[b, j] = qb[j]
        for g in range(shaped.shape[0]):
            for j in range(4):
                q_path[shaped[g], j] = cs[g * k, PATH_Q + j]
    ke = kinetic(bd, q_path, u)
    # x_end = base + f (Δt − elapsed) v, base = x₀ + translation (the path's).
    for b in range(n):
        for j in range(3):
            shift = disp[e, b, j] - elapsed * u[b, j]
            base[b, j] = (x0[b, j] + shift) + elapsed * u[b, j]
    pe_base = potential(mass, gravity, has_gravity, base) - pe0
    for b in range(n):
        for j in range(3):
            scratch[b, j] = base[b, j] + tail * u[b, j]
    lin = potential(mass, gravity, has_gravity, scratch) - pe0 - pe_base
    room = max(e_start, e_free) - pe0 - pe_base
    # energy.scale_to: the largest f ∈ [0, 1] with f² ke + f lin ≤ room.
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
        for b in range(n):
            for j in range(3):
                scratch[b, j] = base[b, j] + (f * tail) * u[b, j]
            h = f * tail
            qe = quat_normalize(
                quat_multiply(
                    quat_exp((h * u[b, 3], h * u[b, 4], h * u[b, 5])),
                    (q_path[b, 0], q_path[b, 1], q_path[b, 2], q_path[b, 3]),
                )
            )
            for j in range(4):
                q_end[b, j] = qe[j]
        separate(scratch, q_end, shaped, points, foot)
        pe_end = potential(mass, gravity, has_gravity, scratch)
        over = f * f * ke + pe_end - pe0 - pe_base > room + 1e-12 * abs(e_start) + 1e-300
        if not over:
            break
        f = 0.5 * f
    if over:
        f = 0.0
    if f < 1:
        for b in range(n):
            for j in range(3):
                st[V][e, b, j] = u[b, j] * f
                st[W][e, b, j] = u[b, 3 + j] * f
                u[b, j] = u[b, j] * f
                u[b, 3 + j] = u[b, 3 + j] * f
    if moved:  # the position update turns q by Δt ω: start it at exp(−elapsed ω) q_path
        for b in range(n):
            h = -elapsed
            back = quat_exp((h * u[b, 3], h * u[b, 4], h * u[b, 5]))
            qb = quat_multiply(back, (q_path[b, 0], q_path[b, 1], q_path[b, 2], q_path[b, 3]))
            for j in range(4):
                st[Q][e, b, j] = qb[j]
    # The position update adds translation − elapsed v to x₀ + Δt v (``Path.displacement``).
    for b in range(n):
        for j in range(3):
            disp[e, b, j] = disp[e, b, j] - elapsed * u[b, j] if elapsed > 0 else 0.0


@njit(cache=True, error_model="numpy")
def separate_contacts(e, st, d):
    """``SeparateContacts`` for one engaged element: remove the overlap the step left and pay
    the lift's potential energy out of the kinetic energy (what cannot be paid: UNPAID).
    In place, without scratch arrays (an allocation is ~40 ns per element): the lift is
    written into x as ``separate`` finds it, the potential energy summed before and after;
    the operations and their order are those of separating a copy."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        return
    ints, floats, _, _, _, _, shaped, mass, _, _, _, bd, points, foot, gravity = unpack(d)
    has_gravity = ints[I_GRAVITY] != 0
    x = st[X][e]
    before = potential(mass, gravity, has_gravity, x)
    if not separate(x, st[Q][e], shaped, points, foot):
        return
    lift = potential(mass, gravity, has_gravity, x) - before
    if lift > 0:
        v, w = st[V][e], st[W][e]
        # KE at the end orientation: that of q₀ or of the path (``LimitEnergy``'s ``rot0``).
        ke = kinetic_vw(bd, st[Q][e] if report[e, ELAPSED] > 0 else st[Q0][e], v, w)
        # energy.pay
        keep = max(ke - lift, 0.0)
        factor = math.sqrt(keep / (ke if ke > 0 else 1.0))
        unpaid = max(lift - ke, 0.0)
        for b in range(v.shape[0]):
            for j in range(3):
                v[b, j] = v[b, j] * factor
                w[b, j] = w[b, j] * factor
        if unpaid > 0:
            report[e, UNPAID_ENERGY] = unpaid


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
