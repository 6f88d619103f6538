"""Ground contact rows, mirroring ``contacts.assembly`` for scenes whose contacts are all
ground contacts (no body–body pairs), and the data every contact kernel shares.

Per contact slot (``layout``): ``JT``, the three rows of J̃ = J M^(-1/2) (normal +z, t₁ along
the sliding, t₂ = n × t₁) over the 6 coordinates of its body, ``T1``; the Delassus matrix
A = J̃ J̃ᵀ couples only contacts of one body (its other entries are the exact zeros numpy's
product gives). Contact velocities are J u = b·v + (r × b)·ω per row, the same quantity as
numpy's J̃ (M^(1/2) u) to rounding. ``assemble`` also decides whether the element is engaged
(``ENGAGED``): a contact within reach of the step's velocities; the later contact kernels skip
an element that is not, as numpy's stages skip it.
"""

from __future__ import annotations

import weakref

import numpy as np

from ..contacts.stages import AssembleContacts, CollidePairs, Restitute
from . import bodies
from .cache import njit
from .forces import spring_table
from .ground import ground_data
from .layout import ARM, CONTACT, ENGAGED, GAP, JT, PATH_GAP, REPORT, T1, U1, Q, V, W
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
N_BLOCKS = 13
INT_BLOCKS = (O_OWNER, O_SHAPED)
# The spring count, the warm start's flag and the Newton polish's settings sit at the end of the
# integer array (after the index tables).
I_SPRINGS, I_WARM, I_NEWTON_AFTER, I_NEWTON_STEPS = -4, -3, -2, -1


_BUILT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def contact_data(scene) -> tuple | None:
    """The data tuple of the contact kernels, or None when the scene has body–body contacts
    (those step with numpy) or no ground contacts. Built once per scene: every contact
    kernel's factory asks (and each parameter row's scene, ``sim.parameters``)."""
    if scene not in _BUILT:
        _BUILT[scene] = _contact_data(scene)
    return _BUILT[scene]


def _contact_data(scene) -> tuple | None:
    stages = {type(s): s for s in scene.pipeline}
    if CollidePairs in stages or AssembleContacts not in stages or Restitute not in stages:
        return None
    lay = stages[AssembleContacts].layout
    settings = stages[Restitute].settings
    if lay.pairs is not None or lay.n_ground == 0:
        return None
    model = scene.model
    ground = ground_data(model.bodies)
    if ground is None:
        return None
    points, foot, shaped, _ = ground
    n = model.n_bodies
    c = len(lay.a)
    g = len(shaped)
    v = points.shape[1]
    gravity = np.zeros(3) if model.gravity is None else np.asarray(model.gravity, float)
    head = [
        g,
        lay.k,
        settings.max_iterations,
        settings.max_impacts,
        int(settings.start == "particle"),
        int(model.gravity is not None),
        c,
        n,
        v,
    ]
    springs = spring_table(model)  # the loads of the energy guard's W (``contacts.energy``)
    tail = [len(springs), int(settings.warm_start), settings.newton_after, settings.newton_steps]
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
    # Two arrays, not fifteen: each array of a kernel's data costs ~0.15 µs to pass per call.
    return (ints, floats)


# ``reshape`` gives these views through a call into numba's C helper, ~35 ns per view per
# element; a C-ordered block's strides are known, so ``as_strided`` sets them directly.


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
    each view ``unpack`` makes costs ~8 ns per element (its reference count). A tuple of
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
    )


@njit(cache=True, error_model="numpy", inline="always")
def solver_views(ints, floats, o):
    """The views of ``contact_data``'s arrays that the solve takes (``o``: ``offsets``):
    (μ, owner, shaped, mass, 1/√m, L (n, 9), L⁻¹ (n, 9)). ``solve`` builds only these (each
    view costs a reference count); ``unpack`` adds the rest."""
    g, c, n = ints[I_GROUND], ints[I_C], ints[I_N]
    return (
        floats[o[O_MU] : o[O_MU] + c],
        ints[o[O_OWNER] : o[O_OWNER] + c],
        ints[o[O_SHAPED] : o[O_SHAPED] + g],
        floats[o[O_MASS] : o[O_MASS] + n],
        floats[o[O_RIM] : o[O_RIM] + n],
        block(floats, o[O_L], n, 9),
        block(floats, o[O_LINV], n, 9),
    )


@njit(cache=True, error_model="numpy", inline="always")
def unpack(d):
    """The views of ``contact_data``'s two arrays: (ints, floats, mu, eps, threshold, owner,
    shaped, mass, 1/√m, L (n, 9), L⁻¹ (n, 9), body data, points (G, V, 3), foot, gravity)."""
    ints, floats = d
    g, c, n, v = ints[I_GROUND], ints[I_C], ints[I_N], ints[I_V]
    o = offsets(ints)
    mu, owner, shaped, mass, rim, lflat, linv = solver_views(ints, floats, o)
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
    )


# --- helpers shared by the contact kernels ---------------------------------------------------


@njit(cache=True, error_model="numpy", inline="always")
def scale_matrix(q, lflat, b):
    """R L of body b (``Rows.scale``): maps scaled angular coordinates back to ω."""
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
def contact_velocity(cs, c, b, u, r):
    """Row r (normal, t₁, t₂) of J u at contact slot row ``cs[c]`` on body b."""
    t1 = (cs[c, T1], cs[c, T1 + 1], cs[c, T1 + 2])
    basis = basis_row(t1, r)
    arm = (cs[c, ARM], cs[c, ARM + 1], cs[c, ARM + 2])
    rxb = cross(arm, basis)
    return (basis[0] * u[b, 0] + basis[1] * u[b, 1] + basis[2] * u[b, 2]) + (
        rxb[0] * u[b, 3] + rxb[1] * u[b, 4] + rxb[2] * u[b, 5]
    )


@njit(cache=True, error_model="numpy")
def delassus(cs, owner, rows, a):
    """A = J̃ J̃ᵀ (rows·C, rows·C) over the first ``rows`` rows of each contact (3: all,
    1: the normal block A_nn); contacts of different bodies do not couple."""
    c = owner.shape[0]
    # The lower triangle, mirrored: entry (q, p) is the same products summed in the same order.
    for i in range(c):
        for r in range(rows):
            p = rows * i + r
            for j in range(i + 1):
                for s in range(rows):
                    q = rows * j + s
                    if q > p:
                        break
                    acc = 0.0
                    if owner[i] == owner[j]:
                        for k in range(6):
                            acc += cs[i, JT + 6 * r + k] * cs[j, JT + 6 * s + k]
                    a[p, q] = acc
                    a[q, p] = acc


@njit(cache=True, error_model="numpy")
def add_impulses(st, e, cs, owner, lflat, rim, lam, rows, u, alpha):
    """u += α M^(-1/2) J̃ᵀ λ (``Rows.velocity_change``) with impulses λ (rows·C); ``rows`` 3
    (normal, t₁, t₂ per contact) or 1 (normal only)."""
    n = u.shape[0]
    for b in range(n):
        d0 = d1 = d2 = d3 = d4 = d5 = 0.0
        touched = False
        for c in range(owner.shape[0]):
            if owner[c] != b:
                continue
            touched = True
            for r in range(rows):
                lam_r = lam[rows * c + r]
                j = JT + 6 * r
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


# --- the stage -------------------------------------------------------------------------------


# Called by the driver for every element of a contact step (``driver`` says why a call).
@njit(cache=True, error_model="numpy")
def assemble(e, st, d):
    """``AssembleContacts``: engaged or not; the rows of J̃ and t₁ per contact. Indexes the
    data and contact arrays in place (``offsets``): it runs for every element."""
    ints, floats = d
    o = offsets(ints)
    dt = floats[F_DT]
    contact = st[CONTACT]
    v, w = st[V], st[W]
    c = ints[I_C]
    engaged = False
    for i in range(c):
        b = ints[o[O_OWNER] + i]
        arm = (contact[e, i, ARM], contact[e, i, ARM + 1], contact[e, i, ARM + 2])
        spin = cross((w[e, b, 0], w[e, b, 1], w[e, b, 2]), arm)
        vz = v[e, b, 2] + spin[2]
        if contact[e, i, GAP] + dt * min(vz, 0.0) < 0:
            engaged = True
    if engaged:  # (no early return: see ``ground.detect``'s note)
        st[REPORT][e, ENGAGED] = 1.0
        k = ints[I_K]
        for g in range(ints[I_GROUND]):
            b = ints[o[O_SHAPED] + g]
            for i in range(3):
                contact[e, g * k, U1 + i] = v[e, b, i]
                contact[e, g * k, U1 + 3 + i] = w[e, b, i]
        for i in range(c):
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
