"""Contact rows, and the data every contact kernel shares (``contacts.assembly`` derives the
scaling).

Per contact slot (``layout``): ``JT``, the three rows of J̃ = J M^(-1/2) (normal, t₁ along the
sliding, t₂ = n × t₁) over the 6 coordinates of its body a, ``T1``; a body–body contact also
``JT_B``, body b's rows, negated (``assemble_pair``). A ground contact's normal is +z. The
Delassus matrix A = J̃ J̃ᵀ couples contacts that share a body (its other entries are exact
zeros). Contact velocities are J u = b·v + (r × b)·ω per row, J̃ (M^(1/2) u) to rounding.
``assemble`` also decides whether the element is engaged (``ENGAGED``): a contact within reach
of the step's velocities; the later contact kernels skip an element that is not.
"""

from __future__ import annotations

import weakref

import numpy as np

from ..contacts.assembly import FAR_GAP
from ..contacts.stages import AssembleContacts, Restitute
from ..shapes import Box, Polyhedron, Sphere
from . import bodies
from .cache import njit
from .forces import spring_table
from .ground import ground_data
from .layout import (
    ARM,
    ARM_B,
    CONTACT,
    DETECTED_A,
    DETECTED_B,
    DETECTED_NORMAL,
    DISPLACEMENT,
    ENGAGED,
    GAP,
    JT,
    JT_B,
    NORMAL,
    PATH_GAP,
    REPORT,
    T1,
    U1,
    Q,
    V,
    W,
)
from .registry import Kernel, register
from .rotation import cross, matmul, quat_to_matrix, rotate, rotate_inverse

# Index of the integer parameters (``I``) and float parameters (``F``) in the data tuple.
I_GROUND, I_K, I_MAX_ITERATIONS, I_MAX_IMPACTS, I_PARTICLE, I_GRAVITY, I_C, I_N, I_V = range(9)
I_OFFSETS = 9  # then the start of each block (``O_*``), written by ``contact_data``
F_DT, F_TOLERANCE, F_GRAVITY = 0, 1, 2  # gravity: 3 entries
F_HEAD = 5
# The blocks after the heads, in this order: owner and shaped in ints, the rest in floats.
# ``contact_data`` names each block by its constant and writes where it starts; kernels read
# the starts (``offsets``), so no size arithmetic is written twice.
O_OWNER, O_SHAPED = 0, 1  # in ints
O_MU, O_EPS, O_THRESHOLD, O_MASS, O_RIM, O_L, O_LINV, O_BODY, O_POINTS, O_FOOT = range(2, 12)
O_SPRINGS = 12  # in floats: the spring table (S, forces.SPRING_WIDTH)
# Body–body contacts (``contact_pairs``): per contact its body b (−1: the ground), per pair its
# bodies, per group of pairs of one kind (``GROUP_COLUMNS``), and the groups' shape tables.
O_OWNER_B, O_PAIR_A, O_PAIR_B, O_GROUPS = 13, 14, 15, 16  # in ints
O_SHAPES = 17  # in floats
O_SPIN = 18  # in floats: per body ‖L‖₂ = 1/√(its least principal moment) (``contact_solve``)
O_ROUND = (
    19  # in ints: per contact, 1 for a sphere–sphere contact (at an impact, ``contact_impacts``)
)
O_BOUND = 20  # in floats: per body, the radius of its bounding sphere (0 without a shape)
# In ints: per body, the contact row that holds its record through the step (``U1``,
# ``PATH_Q``), −1 for a body without contacts: its first ground slot, or in a scene without
# a ground a row of its own after the contacts (``record_rows``).
O_RECORD = 21
N_BLOCKS = 22
INT_BLOCKS = (O_OWNER, O_SHAPED, O_OWNER_B, O_PAIR_A, O_PAIR_B, O_GROUPS, O_ROUND, O_RECORD)
# A group's row: its kind (``contact_pairs.KINDS``), pairs, slots per pair, first pair, first
# contact slot, and where its shape table starts in the ``O_SHAPES`` block.
G_KIND, G_PAIRS, G_SLOTS, G_FIRST_PAIR, G_FIRST_SLOT, G_SHAPES, GROUP_WIDTH = range(7)
# The pair groups' count, the spring count, the warm start's flag and the Newton polish's
# settings sit at the end of the integer array (after the index tables).
I_GROUPS, I_SPRINGS, I_WARM, I_NEWTON_AFTER, I_NEWTON_STEPS = -5, -4, -3, -2, -1
# PAIRS: the data's third slot, ``pairs``, is None in a scene without body–body contacts and
# else holds the number of pair groups. A kernel's pair code runs in a function that takes
# ``pairs`` as an argument and tests ``pairs is None`` first: numba drops a branch on a None
# argument before typing, so a ground scene's kernels compile no pair code
# (``docs/performance.md`` has what that saves).


_BUILT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def contact_data(scene) -> tuple | None:
    """The data tuple of the contact kernels, ``(ints, floats, pairs)``, or None for a scene
    without contacts. Built once per scene: every contact kernel's factory asks (and each
    parameter row's scene, ``sim.parameters``)."""
    if scene not in _BUILT:
        _BUILT[scene] = _contact_data(scene)
    return _BUILT[scene]


def _contact_data(scene) -> tuple | None:
    stages = {type(s): s for s in scene.pipeline}
    if AssembleContacts not in stages or Restitute not in stages:
        return None
    lay = stages[AssembleContacts].layout
    settings = stages[Restitute].settings
    model = scene.model
    if lay.n_ground:
        ground = ground_data(model.bodies)
        if ground is None:
            return None
        points, foot, shaped, _ = ground
    else:  # body–body contacts only
        points, foot, shaped = np.zeros((0, 0, 3)), np.zeros(0), np.zeros(0, np.int64)
    n = model.n_bodies
    c = len(lay.a)
    g = len(shaped)
    v = points.shape[1]
    gravity = np.zeros(3) if model.gravity is None else np.asarray(model.gravity, float)
    k = lay.k if lay.n_ground else 1  # (unused without a ground)
    record = np.full(n, -1, np.int64)
    if lay.n_ground:
        record[shaped] = np.arange(len(shaped)) * k
    else:
        record[:] = c + np.arange(n)
    head = [
        g,
        k,
        settings.max_iterations,
        settings.max_impacts,
        int(settings.start == "particle"),
        int(model.gravity is not None),
        c,
        n,
        v,
    ]
    springs = spring_table(model)  # the loads of the energy guard's W (``contact_energy``)
    groups, pair_a, pair_b, shapes = pair_tables(lay)
    tail = [
        len(groups),
        len(springs),
        int(settings.warm_start),
        settings.newton_after,
        settings.newton_steps,
    ]
    body = bodies.body_data(model)
    blocks = {
        O_OWNER: lay.a,
        O_SHAPED: shaped,
        O_MU: lay.mu,
        O_EPS: lay.eps,
        O_THRESHOLD: lay.threshold,
        O_MASS: model.mass,
        O_RIM: lay.root_inv_mass,
        O_L: lay.root_inv_inertia.reshape(-1),
        O_LINV: lay.root_inertia.reshape(-1),  # L⁻¹
        O_BODY: body.reshape(-1),
        O_POINTS: points.reshape(-1),
        O_FOOT: foot,
        O_SPRINGS: springs.reshape(-1),
        O_OWNER_B: lay.b,
        O_PAIR_A: pair_a,
        O_PAIR_B: pair_b,
        O_GROUPS: groups.reshape(-1),
        O_SHAPES: shapes,
        O_SPIN: lay.spin,
        O_ROUND: np.concatenate([np.zeros(lay.n_ground, np.int64), lay.round_pairs]),
        O_BOUND: [bounding_radius(b.shape) for b in model.bodies],
        O_RECORD: record,
    }
    starts = np.zeros(N_BLOCKS, dtype=np.int64)
    int_parts = [np.asarray(head, np.int64), starts]
    float_parts = [np.array([scene.dt, settings.tolerance]), gravity]
    for o in range(N_BLOCKS):
        parts = int_parts if o in INT_BLOCKS else float_parts
        starts[o] = sum(len(part) for part in parts)
        parts.append(np.asarray(blocks[o]))
    ints = np.concatenate([*int_parts, tail]).astype(np.int64)
    floats = np.concatenate(float_parts).astype(float)
    # Two arrays, not fifteen: each array of a kernel's data costs time to pass per call.
    # The third slot is None in a scene without body–body contacts, and its kernels are
    # compiled without the pair code (``PAIRS``).
    pairs = np.array([len(groups)], np.int64) if len(groups) else None
    return (ints, floats, pairs)


def record_rows(lay) -> int:
    """The rows a scene's contact array holds after its contacts: a scene without a ground
    keeps each body's record (``O_RECORD``) in a row of its own; a ground scene keeps it in
    the body's first ground slot."""
    return 0 if lay.n_ground else lay.n_bodies


def bounding_radius(shape) -> float:
    """The radius of the smallest sphere about the centre of mass that holds ``shape``."""
    if isinstance(shape, Sphere):
        return float(shape.radius)
    if isinstance(shape, Box):
        return float(np.sqrt(np.sum(np.square(shape.half_extents))))
    if isinstance(shape, Polyhedron):
        return float(np.max(np.sqrt(np.sum(np.square(shape.vertices), axis=-1))))
    return 0.0


def pair_tables(lay) -> tuple:
    """The body–body blocks of ``contact_data``: the groups (Gp, ``GROUP_WIDTH``), each pair's
    bodies a and b, and the groups' shape tables (``contact_pairs.shape_table``)."""
    from .contact_pairs import KINDS, shape_table

    groups, pair_a, pair_b, shapes = [], [], [], []
    first_pair, first_slot, at = 0, lay.n_ground, 0
    if lay.pairs is not None:
        for (pa, pb, detect, slots), kind in zip(lay.pairs.groups, lay.pairs.kinds, strict=True):
            table = shape_table(kind, detect.params)
            groups.append([KINDS.index(kind), len(pa), slots, first_pair, first_slot, at])
            pair_a.append(pa)
            pair_b.append(pb)
            shapes.append(table)
            first_pair += len(pa)
            first_slot += len(pa) * slots
            at += len(table)
    cat = np.concatenate
    return (
        np.array(groups, np.int64).reshape(-1, GROUP_WIDTH),
        cat(pair_a).astype(np.int64) if pair_a else np.zeros(0, np.int64),
        cat(pair_b).astype(np.int64) if pair_b else np.zeros(0, np.int64),
        cat(shapes) if shapes else np.zeros(0),
    )


# ``reshape`` gives these views through a call into numba's C helper per view per element; a
# C-ordered block's strides are known, so ``as_strided`` sets them directly.


@njit(cache=True, error_model="numpy", inline="always")
def block(flat, start, rows, cols):
    """``flat[start : start + rows·cols]`` as a C-ordered (rows, cols) view."""
    size = flat.itemsize
    part = flat[start : start + rows * cols]
    return np.lib.stride_tricks.as_strided(part, (rows, cols), (cols * size, size))


@njit(cache=True, error_model="numpy", inline="always")
def block3(flat, start, a, b, c):
    """``flat[start : start + a·b·c]`` as a C-ordered (a, b, c) view."""
    size = flat.itemsize
    part = flat[start : start + a * b * c]
    return np.lib.stride_tricks.as_strided(part, (a, b, c), (b * c * size, c * size, size))


@njit(cache=True, error_model="numpy", inline="always")
def offsets(ints):
    """Start of each block of ``contact_data``'s arrays (``O_*``): owner and shaped in ints,
    the rest in floats. Kernels on the common path index the two arrays in place with these:
    each view ``unpack`` makes costs a reference count per element. A tuple of
    scalars, not a view of ``ints``, for the same reason."""
    s = I_OFFSETS
    return (
        ints[s],
        ints[s + 1],
        ints[s + 2],
        ints[s + 3],
        ints[s + 4],
        ints[s + 5],
        ints[s + 6],
        ints[s + 7],
        ints[s + 8],
        ints[s + 9],
        ints[s + 10],
        ints[s + 11],
        ints[s + 12],
        ints[s + 13],
        ints[s + 14],
        ints[s + 15],
        ints[s + 16],
        ints[s + 17],
        ints[s + 18],
        ints[s + 19],
        ints[s + 20],
        ints[s + 21],
    )


@njit(cache=True, error_model="numpy", inline="always")
def solver_views(ints, floats, o):
    """The views of ``contact_data``'s arrays that the solve takes (``o``: ``offsets``):
    (μ, owner, shaped, mass, 1/√m, L (n, 9), L⁻¹ (n, 9), owner b). ``solve`` builds only
    these (each view costs a reference count); ``unpack`` adds the rest."""
    g, c, n = ints[I_GROUND], ints[I_C], ints[I_N]
    return (
        floats[o[O_MU] : o[O_MU] + c],
        ints[o[O_OWNER] : o[O_OWNER] + c],
        ints[o[O_SHAPED] : o[O_SHAPED] + g],
        floats[o[O_MASS] : o[O_MASS] + n],
        floats[o[O_RIM] : o[O_RIM] + n],
        block(floats, o[O_L], n, 9),
        block(floats, o[O_LINV], n, 9),
        ints[o[O_OWNER_B] : o[O_OWNER_B] + c],
    )


@njit(cache=True, error_model="numpy", inline="always")
def unpack(d):
    """The views of ``contact_data``'s two arrays: (ints, floats, mu, eps, threshold, owner,
    shaped, mass, 1/√m, L (n, 9), L⁻¹ (n, 9), body data, points (G, V, 3), foot, gravity,
    owner b)."""
    ints, floats = d[0], d[1]
    g, c, n, v = ints[I_GROUND], ints[I_C], ints[I_N], ints[I_V]
    o = offsets(ints)
    mu, owner, shaped, mass, rim, lflat, linv, owner_b = solver_views(ints, floats, o)
    return (
        ints,
        floats,
        mu,
        floats[o[O_EPS] : o[O_EPS] + c],
        floats[o[O_THRESHOLD] : o[O_THRESHOLD] + c],
        owner,
        shaped,
        mass,
        rim,
        lflat,
        linv,
        block(floats, o[O_BODY], n, bodies.BODY_WIDTH),
        block3(floats, o[O_POINTS], g, v, 3),
        floats[o[O_FOOT] : o[O_FOOT] + g],
        floats[F_GRAVITY : F_GRAVITY + 3],
        owner_b,
    )


# --- helpers shared by the contact kernels ---------------------------------------------------


@njit(cache=True, error_model="numpy", inline="always")
def scale_matrix(q, lflat, b):
    """R L of body b : maps scaled angular coordinates back to ω."""
    el = (
        lflat[b, 0],
        lflat[b, 1],
        lflat[b, 2],
        lflat[b, 3],
        lflat[b, 4],
        lflat[b, 5],
        lflat[b, 6],
        lflat[b, 7],
        lflat[b, 8],
    )
    return matmul(quat_to_matrix(q), el)


@njit(cache=True, error_model="numpy", inline="always")
def tuple9(flat, start):
    """The 9 entries of ``flat`` from ``start`` (a row-major 3×3 stored in place)."""
    return (
        flat[start],
        flat[start + 1],
        flat[start + 2],
        flat[start + 3],
        flat[start + 4],
        flat[start + 5],
        flat[start + 6],
        flat[start + 7],
        flat[start + 8],
    )


@njit(cache=True, error_model="numpy", inline="always")
def mat9(a, b):
    return (a[b, 0], a[b, 1], a[b, 2], a[b, 3], a[b, 4], a[b, 5], a[b, 6], a[b, 7], a[b, 8])


@njit(cache=True, error_model="numpy", inline="always")
def basis_row(t1, r):
    """Row r of the contact basis (n, t₁, t₂) of a ground contact, normal +z."""
    if r == 0:
        return (0.0, 0.0, 1.0)
    if r == 1:
        return t1
    return cross((0.0, 0.0, 1.0), t1)


@njit(cache=True, error_model="numpy", inline="always")
def load_velocities(st, e, u):
    """u (n, 6) ← the element's working (v, ω)."""
    for b in range(u.shape[0]):
        for i in range(3):
            u[b, i] = st[V][e, b, i]
            u[b, 3 + i] = st[W][e, b, i]


@njit(cache=True, error_model="numpy", inline="always")
def store_velocities(st, e, u):
    for b in range(u.shape[0]):
        for i in range(3):
            st[V][e, b, i] = u[b, i]
            st[W][e, b, i] = u[b, 3 + i]


@njit(cache=True, error_model="numpy", inline="always")
def pair_basis(cs, c, r):
    """Row r of the contact basis (n, t₁, t₂) of a body–body contact (its ``NORMAL``)."""
    n = (cs[c, NORMAL], cs[c, NORMAL + 1], cs[c, NORMAL + 2])
    if r == 0:
        return n
    t1 = (cs[c, T1], cs[c, T1 + 1], cs[c, T1 + 2])
    if r == 1:
        return t1
    return cross(n, t1)


@njit(cache=True, error_model="numpy", inline="always")
def point_velocity(basis, arm, u, b):
    """basis · (v_b + ω_b × arm), as bᵀ v + (arm × b)ᵀ ω."""
    rxb = cross(arm, basis)
    return (basis[0] * u[b, 0] + basis[1] * u[b, 1] + basis[2] * u[b, 2]) + (
        rxb[0] * u[b, 3] + rxb[1] * u[b, 4] + rxb[2] * u[b, 5]
    )


@njit(cache=True, error_model="numpy", inline="always")
def contact_velocity(cs, c, a, b, u, r):
    """Row r (normal, t₁, t₂) of J u at contact slot row ``cs[c]`` between body a and body b
    (b < 0: the ground): a's contact point's velocity relative to b's along that row."""
    if b < 0:
        t1 = (cs[c, T1], cs[c, T1 + 1], cs[c, T1 + 2])
        return point_velocity(basis_row(t1, r), (cs[c, ARM], cs[c, ARM + 1], cs[c, ARM + 2]), u, a)
    basis = pair_basis(cs, c, r)
    va = point_velocity(basis, (cs[c, ARM], cs[c, ARM + 1], cs[c, ARM + 2]), u, a)
    vb = point_velocity(basis, (cs[c, ARM_B], cs[c, ARM_B + 1], cs[c, ARM_B + 2]), u, b)
    return va - vb


@njit(cache=True, error_model="numpy", inline="always")
def _rows_dot(cs, i, col_i, r, j, col_j, s):
    """Row r of contact i's block at column ``col_i`` (``JT`` or ``JT_B``) dotted with row s of
    contact j's at ``col_j``: their product over one body's 6 coordinates."""
    acc = 0.0
    for k in range(6):
        acc += cs[i, col_i + 6 * r + k] * cs[j, col_j + 6 * s + k]
    return acc


@njit(cache=True, error_model="numpy")
def delassus(cs, owner, owner_b, slots, m, rows, a):
    """A = J̃ J̃ᵀ (rows·m, rows·m) of the m contacts ``slots`` (every slot, in order, when
    ``slots`` is empty: no index array to allocate) over the first ``rows`` rows of each (3:
    all, 1: the normal block A_nn). Two contacts couple through each body they share (a
    ground contact has one body, ``owner_b`` −1), summed in the bodies' order."""
    every = slots.shape[0] == 0
    # The lower triangle, mirrored: entry (q, p) is the same products summed in the same order.
    for si in range(m):
        i = si if every else slots[si]
        ai, bi = owner[i], owner_b[i]
        for r in range(rows):
            p = rows * si + r
            for sj in range(si + 1):
                j = sj if every else slots[sj]
                aj, bj = owner[j], owner_b[j]
                for s in range(rows):
                    q = rows * sj + s
                    if q > p:
                        break
                    acc = 0.0
                    if bi < 0 and bj < 0:  # two ground contacts: one body at most
                        if ai == aj:
                            acc = _rows_dot(cs, i, JT, r, j, JT, s)
                    else:
                        # each body of contact i (a, then b) against the same body of j
                        lo_i, hi_i = (ai, bi) if bi < 0 or ai < bi else (bi, ai)
                        for body in (lo_i, hi_i):
                            if body < 0:
                                continue
                            col_i = JT if body == ai else JT_B
                            if body == aj:
                                acc += _rows_dot(cs, i, col_i, r, j, JT, s)
                            elif body == bj:
                                acc += _rows_dot(cs, i, col_i, r, j, JT_B, s)
                    a[p, q] = acc
                    a[q, p] = acc


@njit(cache=True, error_model="numpy")
def add_impulses(st, e, cs, owner, owner_b, lflat, rim, lam, rows, u, alpha):
    """u += α M^(-1/2) J̃ᵀ λ with impulses λ (rows·C); ``rows`` 3
    (normal, t₁, t₂ per contact) or 1 (normal only). Body b of a body–body contact takes its
    rows ``JT_B``, which carry the opposite sign."""
    n = u.shape[0]
    for b in range(n):
        d0 = d1 = d2 = d3 = d4 = d5 = 0.0
        touched = False
        for c in range(owner.shape[0]):
            if owner[c] == b:
                col = JT
            elif owner_b[c] == b:
                col = JT_B
            else:
                continue
            touched = True
            for r in range(rows):
                lam_r = lam[rows * c + r]
                j = col + 6 * r
                d0 += lam_r * cs[c, j]
                d1 += lam_r * cs[c, j + 1]
                d2 += lam_r * cs[c, j + 2]
                d3 += lam_r * cs[c, j + 3]
                d4 += lam_r * cs[c, j + 4]
                d5 += lam_r * cs[c, j + 5]
        if not touched:
            continue
        q = (st[Q][e, b, 0], st[Q][e, b, 1], st[Q][e, b, 2], st[Q][e, b, 3])
        dw = rotate(scale_matrix(q, lflat, b), (d3, d4, d5))
        u[b, 0] += alpha * (d0 * rim[b])
        u[b, 1] += alpha * (d1 * rim[b])
        u[b, 2] += alpha * (d2 * rim[b])
        for i in range(3):
            u[b, 3 + i] += alpha * dw[i]


@njit(cache=True, error_model="numpy", inline="always")
def scaled_velocity(st, e, mass, linv, u, z):
    """z (n, 6) = M^(1/2) u: √m v and L⁻¹ Rᵀ ω (``assembly.scaled_velocity``)."""
    for b in range(u.shape[0]):
        q = (st[Q][e, b, 0], st[Q][e, b, 1], st[Q][e, b, 2], st[Q][e, b, 3])
        local = rotate_inverse(quat_to_matrix(q), (u[b, 3], u[b, 4], u[b, 5]))
        zw = rotate(mat9(linv, b), local)
        root = np.sqrt(mass[b])
        for i in range(3):
            z[b, i] = u[b, i] * root
            z[b, 3 + i] = zw[i]


@njit(cache=True, error_model="numpy", inline="always")
def vec(contact, e, i, col):
    """Columns col … col + 2 of slot i of element e's contact rows."""
    return (contact[e, i, col], contact[e, i, col + 1], contact[e, i, col + 2])


@njit(cache=True, error_model="numpy", inline="always")
def relative_velocity(u, a, b, arm_a, arm_b):
    """World velocity of a's contact point relative to b's (``Layout.relative_velocity``) at
    velocities u (n, 6)."""
    spin_a = cross((u[a, 3], u[a, 4], u[a, 5]), arm_a)
    spin_b = cross((u[b, 3], u[b, 4], u[b, 5]), arm_b)
    return (
        (u[a, 0] + spin_a[0]) - (u[b, 0] + spin_b[0]),
        (u[a, 1] + spin_a[1]) - (u[b, 1] + spin_b[1]),
        (u[a, 2] + spin_a[2]) - (u[b, 2] + spin_b[2]),
    )


@njit(cache=True, error_model="numpy", inline="always")
def tangent(n, rel):
    """t₁ for normal n: the sliding direction of the relative velocity,
    else the unit part of (1, 0, 0), or of (0, 1, 0) for a normal near the x axis, normal to n."""
    along = rel[0] * n[0] + rel[1] * n[1] + rel[2] * n[2]
    vt = (rel[0] - along * n[0], rel[1] - along * n[1], rel[2] - along * n[2])
    speed = np.sqrt(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2])
    if speed > 1e-9:
        return (vt[0] / speed, vt[1] / speed, vt[2] / speed)
    helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    h = helper[0] * n[0] + helper[1] * n[1] + helper[2] * n[2]
    perp = (helper[0] - h * n[0], helper[1] - h * n[1], helper[2] - h * n[2])
    size = np.sqrt(perp[0] * perp[0] + perp[1] * perp[1] + perp[2] * perp[2])
    return (perp[0] / size, perp[1] / size, perp[2] / size)


@njit(cache=True, error_model="numpy", inline="always")
def norm(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True, error_model="numpy")
def assemble_pair(e, st, floats, o, i, a, b, u, moved, round_pair):
    """The rows of body–body slot i between bodies a and b, from what the
    detection found (``DETECTED_*``, ``GAP``): both take the impulse at the midpoint of the two
    features (p_a − p_b = gap n: no impulse has a net moment), so ``ARM`` and ``ARM_B`` become
    the arms to it; t₁ follows the relative sliding there at velocities u (n, 6); body a's rows
    of J̃ go to ``JT``, body b's, negated, to ``JT_B``. ``moved``: the rows at an impact part-way
    through the step (at an impact, ``contact_impacts``), the bodies translated by ``DISPLACEMENT`` since: the
    points move apart by the relative translation, and a sphere–sphere contact (``round_pair``)
    takes the line of the centres there as its normal, its arms along it."""
    contact = st[CONTACT]
    n0 = vec(contact, e, i, DETECTED_NORMAL)
    gap = contact[e, i, GAP]
    raw_a, raw_b = vec(contact, e, i, DETECTED_A), vec(contact, e, i, DETECTED_B)
    along = gap if gap < FAR_GAP else 0.0  # (a slot with no contact point stays unshifted)
    normal = n0
    apart = (along * n0[0], along * n0[1], along * n0[2])
    if moved:
        disp = st[DISPLACEMENT]
        rel = (
            disp[e, a, 0] - disp[e, b, 0],
            disp[e, a, 1] - disp[e, b, 1],
            disp[e, a, 2] - disp[e, b, 2],
        )
        if round_pair:
            ra, rb = norm(raw_a), norm(raw_b)
            reach = ra + rb + gap
            centres = (reach * n0[0] + rel[0], reach * n0[1] + rel[1], reach * n0[2] + rel[2])
            dist = norm(centres)
            if dist > 1e-12:
                normal = (centres[0] / dist, centres[1] / dist, centres[2] / dist)
            raw_a = (-ra * normal[0], -ra * normal[1], -ra * normal[2])
            raw_b = (rb * normal[0], rb * normal[1], rb * normal[2])
            left = dist - ra - rb
            apart = (left * normal[0], left * normal[1], left * normal[2])
        else:
            apart = (
                (apart[0] + disp[e, a, 0]) - disp[e, b, 0],
                (apart[1] + disp[e, a, 1]) - disp[e, b, 1],
                (apart[2] + disp[e, a, 2]) - disp[e, b, 2],
            )
    for j in range(3):
        contact[e, i, NORMAL + j] = normal[j]
        contact[e, i, ARM + j] = raw_a[j] + -0.5 * apart[j]
        contact[e, i, ARM_B + j] = raw_b[j] + 0.5 * apart[j]
    arm_a, arm_b = vec(contact, e, i, ARM), vec(contact, e, i, ARM_B)
    t1 = tangent(normal, relative_velocity(u, a, b, arm_a, arm_b))
    for j in range(3):
        contact[e, i, T1 + j] = t1[j]
    for side in range(2):
        body = a if side == 0 else b
        arm = arm_a if side == 0 else arm_b
        col = JT if side == 0 else JT_B
        sign = 1.0 if side == 0 else -1.0
        q = (st[Q][e, body, 0], st[Q][e, body, 1], st[Q][e, body, 2], st[Q][e, body, 3])
        scale = matmul(quat_to_matrix(q), tuple9(floats, o[O_L] + 9 * body))
        rim = floats[o[O_RIM] + body]
        for r in range(3):
            basis = pair_basis(contact[e], i, r)
            ang = rotate_inverse(scale, cross(arm, basis))
            for j in range(3):
                contact[e, i, col + 6 * r + j] = sign * (basis[j] * rim)
                contact[e, i, col + 6 * r + 3 + j] = sign * ang[j]
    if not moved:
        contact[e, i, PATH_GAP] = gap


@njit(cache=True, error_model="numpy", inline="always")
def detected_velocity(cs, i, a, b, u):
    """Row 0 of J u by the rows ``assemble`` built from the detection (the impact loop's
    ``rows.velocity``, which the rows moved to an impact do not replace)."""
    n0 = (cs[i, DETECTED_NORMAL], cs[i, DETECTED_NORMAL + 1], cs[i, DETECTED_NORMAL + 2])
    gap = cs[i, GAP]
    along = gap if gap < FAR_GAP else 0.0
    arm_a = (
        cs[i, DETECTED_A] + -0.5 * (along * n0[0]),
        cs[i, DETECTED_A + 1] + -0.5 * (along * n0[1]),
        cs[i, DETECTED_A + 2] + -0.5 * (along * n0[2]),
    )
    arm_b = (
        cs[i, DETECTED_B] + 0.5 * (along * n0[0]),
        cs[i, DETECTED_B + 1] + 0.5 * (along * n0[1]),
        cs[i, DETECTED_B + 2] + 0.5 * (along * n0[2]),
    )
    return point_velocity(n0, arm_a, u, a) - point_velocity(n0, arm_b, u, b)


@njit(cache=True, error_model="numpy")
def assemble_pairs(pairs, e, st, ints, floats, o, engaged):
    """``assemble``'s body–body part: whether a pair's contact is within reach (the relative
    velocity at the detected points), and if the element is engaged (``engaged``: a ground
    contact is), the pairs' rows. Returns whether it is."""
    if pairs is None:  # (``PAIRS``)
        return engaged
    contact = st[CONTACT]
    dt = floats[F_DT]
    u = np.empty((ints[I_N], 6))
    load_velocities(st, e, u)
    first, c = ints[I_GROUND] * ints[I_K], ints[I_C]
    for i in range(first, c):
        normal = vec(contact, e, i, NORMAL)
        a, b = ints[o[O_OWNER] + i], ints[o[O_OWNER_B] + i]
        rel = relative_velocity(u, a, b, vec(contact, e, i, ARM), vec(contact, e, i, ARM_B))
        vn = rel[0] * normal[0] + rel[1] * normal[1] + rel[2] * normal[2]
        if contact[e, i, GAP] + dt * min(vn, 0.0) < 0:
            engaged = True
    if engaged:
        for i in range(first, c):
            a, b = ints[o[O_OWNER] + i], ints[o[O_OWNER_B] + i]
            assemble_pair(e, st, floats, o, i, a, b, u, False, False)
    return engaged


# --- the stage -------------------------------------------------------------------------------


# Called by the driver for every element of a contact step (``driver`` says why a call).
@njit(cache=True, error_model="numpy")
def assemble(e, st, d):
    """The ``assemble_contacts`` stage: engaged or not; the rows of J̃ and t₁ per contact. Indexes the
    data and contact arrays in place (``offsets``): it runs for every element."""
    ints, floats, pairs = d
    o = offsets(ints)
    dt = floats[F_DT]
    contact = st[CONTACT]
    v, w = st[V], st[W]
    n_ground = ints[I_GROUND] * ints[I_K]
    engaged = False
    for i in range(n_ground):
        b = ints[o[O_OWNER] + i]
        arm = (contact[e, i, ARM], contact[e, i, ARM + 1], contact[e, i, ARM + 2])
        spin = cross((w[e, b, 0], w[e, b, 1], w[e, b, 2]), arm)
        vz = v[e, b, 2] + spin[2]
        if contact[e, i, GAP] + dt * min(vz, 0.0) < 0:
            engaged = True
    engaged = assemble_pairs(pairs, e, st, ints, floats, o, engaged)
    if engaged:  # (no early return: see ``ground.detect``'s note)
        st[REPORT][e, ENGAGED] = 1.0
        for b in range(ints[I_N]):
            row = ints[o[O_RECORD] + b]
            if row >= 0:
                for i in range(3):
                    contact[e, row, U1 + i] = v[e, b, i]
                    contact[e, row, U1 + 3 + i] = w[e, b, i]
        for i in range(n_ground):
            b = ints[o[O_OWNER] + i]
            arm = (contact[e, i, ARM], contact[e, i, ARM + 1], contact[e, i, ARM + 2])
            spin = cross((w[e, b, 0], w[e, b, 1], w[e, b, 2]), arm)
            vx = v[e, b, 0] + spin[0]
            vy = v[e, b, 1] + spin[1]
            # tangents(): the sliding direction, else the perpendicular (1, 0, 0) of n = +z.
            speed = np.sqrt(vx * vx + vy * vy + 0.0)
            t1 = (vx / speed, vy / speed, 0.0) if speed > 1e-9 else (1.0, 0.0, 0.0)
            q = (st[Q][e, b, 0], st[Q][e, b, 1], st[Q][e, b, 2], st[Q][e, b, 3])
            scale = matmul(quat_to_matrix(q), tuple9(floats, o[O_L] + 9 * b))  # scale_matrix
            rim = floats[o[O_RIM] + b]
            for r in range(3):
                basis = basis_row(t1, r)
                ang = rotate_inverse(scale, cross(arm, basis))  # (r × b)ᵀ R L
                for j in range(3):
                    contact[e, i, JT + 6 * r + j] = basis[j] * rim
                    contact[e, i, JT + 6 * r + 3 + j] = ang[j]
            for j in range(3):
                contact[e, i, T1 + j] = t1[j]
            contact[e, i, PATH_GAP] = contact[e, i, GAP]


@register("assemble_contacts")
def _assemble_contacts(scene):
    data = contact_data(scene)
    if data is None:
        return None
    return Kernel(__name__, "assemble", data)
