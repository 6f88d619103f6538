"""Body–body contacts of one element: detection into the contact slots, and the separation
that ``contact_energy`` applies, the pairs' part of the separation.

The pairs' slots follow the ground's (``Layout``: G bodies × K slots, then each group of pairs
of one kind, S slots per pair). Detection runs the kernels of ``compiled.pairs``, the one
implementation of body–body detection, on each group's poses gathered from the element's
bodies. The solve's rows then take each contact between its two bodies (``contact_assembly``).
"""

from __future__ import annotations

import numpy as np

from ..contacts.box_box import FAR
from .cache import njit
from .contact_assembly import (
    F_DT,
    G_FIRST_PAIR,
    G_FIRST_SLOT,
    G_KIND,
    G_PAIRS,
    G_SHAPES,
    G_SLOTS,
    GROUP_WIDTH,
    I_C,
    I_GROUND,
    I_GROUPS,
    I_K,
    I_N,
    O_BOUND,
    O_GROUPS,
    O_LINV,
    O_MASS,
    O_PAIR_A,
    O_PAIR_B,
    O_RIM,
    O_SHAPES,
    O_SPIN,
    block,
    contact_data,
    load_velocities,
    norm,
    offsets,
    record_rows,
    scaled_velocity,
)
from .layout import (
    ARM,
    ARM_B,
    BODY,
    CONTACT,
    CONTACT_WIDTH,
    DETECTED_A,
    DETECTED_B,
    DETECTED_NORMAL,
    GAP,
    NORMAL,
    Q,
    X,
)
from .pairs import box_box, sphere_box, sphere_sphere
from .registry import Kernel, register

KINDS = ("sphere_sphere", "sphere_box", "box_box")  # ``PairContacts.kinds``, by index


def shape_table(kind: str, params: tuple) -> np.ndarray:
    """A group's shape parameters (``compiled.pairs``' tables, P rows each) one after the
    other, flat: sphere–sphere ra, rb; sphere–box radius, half extents; box–box half extents
    of a and of b, face margin."""
    if kind not in KINDS:
        raise ValueError(f"no compiled detection for {kind!r} pairs")
    return np.concatenate([np.asarray(p, float).reshape(-1) for p in params])


@njit(cache=True, error_model="numpy")
def detect_pairs(ints, floats, o, x, q, speed, horizon, arm_a, arm_b, normal, gap):
    """Every pair slot's arms, normal (from b to a) and gap at the element's poses x (n, 3),
    q (n, 4), into rows 0 … (C − G·K) of the outputs (the pair slots in ``Layout`` order).

    The broad phase: a pair whose bounding spheres (``O_BOUND``) stay apart by more than its
    points can close over ``horizon`` seconds at the bodies' largest speeds (``speed`` = |z|,
    ``contact_solve.reach_bound``) cannot touch within it, and its slots get no contact point
    (gap ``box_box.FAR``, normal +z, zero arms) without the narrow phase. ``speed`` 0: only
    pairs whose bounding spheres overlap are tested (the separation's question)."""
    n_ground = ints[I_GROUND] * ints[I_K]
    bound, rim = floats[o[O_BOUND] :], floats[o[O_RIM] :]
    spin = floats[o[O_SPIN] :]
    for g in range(ints[I_GROUPS]):
        row = o[O_GROUPS] + GROUP_WIDTH * g
        kind, p, slots = ints[row + G_KIND], ints[row + G_PAIRS], ints[row + G_SLOTS]
        first = ints[row + G_FIRST_PAIR]
        start = ints[row + G_FIRST_SLOT] - n_ground
        at = o[O_SHAPES] + ints[row + G_SHAPES]
        kept = np.empty(p, np.int64)
        count = 0
        for m in range(p):
            ia, ib = ints[o[O_PAIR_A] + first + m], ints[o[O_PAIR_B] + first + m]
            d = (x[ia, 0] - x[ib, 0], x[ia, 1] - x[ib, 1], x[ia, 2] - x[ib, 2])
            # the points' closing speed: each body's |v| + |ω| R (``reach_bound``)
            closing = speed * ((rim[ia] + spin[ia] * bound[ia]) + (rim[ib] + spin[ib] * bound[ib]))
            if norm(d) <= (bound[ia] + bound[ib]) + horizon * closing * (1.0 + 1e-9):
                kept[count] = m
                count += 1
            else:
                for s in range(slots):
                    r = start + m * slots + s
                    gap[r] = FAR
                    for j in range(3):
                        arm_a[r, j] = 0.0
                        arm_b[r, j] = 0.0
                        normal[r, j] = 1.0 if j == 2 else 0.0
        if count == 0:
            continue
        xa, xb = np.empty((count, 3)), np.empty((count, 3))
        qa, qb = np.empty((count, 4)), np.empty((count, 4))
        width = 2 if kind == 0 else (4 if kind == 1 else 7)  # shape floats per pair
        table = np.empty(width * count)  # the kept pairs' shape table, laid out as the group's
        for k in range(count):
            m = kept[k]
            ia, ib = ints[o[O_PAIR_A] + first + m], ints[o[O_PAIR_B] + first + m]
            for j in range(3):
                xa[k, j] = x[ia, j]
                xb[k, j] = x[ib, j]
            for j in range(4):
                qa[k, j] = q[ia, j]
                qb[k, j] = q[ib, j]
            if kind == 0:  # ra (P), rb (P)
                table[k] = floats[at + m]
                table[count + k] = floats[at + p + m]
            elif kind == 1:  # radius (P), half extents (P, 3)
                table[k] = floats[at + m]
                for j in range(3):
                    table[count + 3 * k + j] = floats[at + p + 3 * m + j]
            else:  # half extents of a (P, 3) and of b (P, 3), face margin (P)
                for j in range(3):
                    table[3 * k + j] = floats[at + 3 * m + j]
                    table[3 * count + 3 * k + j] = floats[at + 3 * p + 3 * m + j]
                table[6 * count + k] = floats[at + 6 * p + m]
        out_a, out_b, out_n = (
            np.empty((count, slots, 3)),
            np.empty((count, slots, 3)),
            np.empty((count, slots, 3)),
        )
        out_gap = np.empty((count, slots))
        if kind == 0:
            ra, rb = table[:count], table[count : 2 * count]
            sphere_sphere(
                xa, qa, xb, qb, ra, rb, out_a[:, 0], out_b[:, 0], out_n[:, 0], out_gap[:, 0]
            )
        elif kind == 1:
            radius, half = table[:count], block(table, count, count, 3)
            sphere_box(
                xa, qa, xb, qb, radius, half, out_a[:, 0], out_b[:, 0], out_n[:, 0], out_gap[:, 0]
            )
        else:
            half_a, half_b = block(table, 0, count, 3), block(table, 3 * count, count, 3)
            margin = table[6 * count : 7 * count]
            box_box(xa, qa, xb, qb, half_a, half_b, margin, out_a, out_b, out_n, out_gap)
        for k in range(count):
            m = kept[k]
            for s in range(slots):
                r = start + m * slots + s
                gap[r] = out_gap[k, s]
                for j in range(3):
                    arm_a[r, j] = out_a[k, s, j]
                    arm_b[r, j] = out_b[k, s, j]
                    normal[r, j] = out_n[k, s, j]


@njit(cache=True, error_model="numpy")
def collide(e, st, d):
    """``CollidePairs`` for one element: detection at the working poses (the start's), the
    broad phase over the step at the speeds the velocity update left (the contact stages add
    no kinetic energy, so no pair it passes over can touch or take an impulse this step)."""
    ints, floats, _ = d
    o = offsets(ints)
    n_ground = ints[I_GROUND] * ints[I_K]
    rows = ints[I_C] - n_ground
    n = ints[I_N]
    u, z = np.empty((n, 6)), np.empty((n, 6))
    load_velocities(st, e, u)
    mass, linv = floats[o[O_MASS] : o[O_MASS] + n], block(floats, o[O_LINV], n, 9)
    scaled_velocity(st, e, mass, linv, u, z)
    energy = 0.0
    for b in range(n):
        for j in range(6):
            energy += z[b, j] * z[b, j]
    arm_a, arm_b, normal = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, 3))
    gap = np.empty(rows)
    speed = np.sqrt(energy)
    detect_pairs(
        ints, floats, o, st[X][e], st[Q][e], speed, floats[F_DT], arm_a, arm_b, normal, gap
    )
    contact = st[CONTACT]
    for r in range(rows):
        i = n_ground + r
        for j in range(3):  # the detection, and the rows' until ``assemble`` builds them
            contact[e, i, DETECTED_A + j] = contact[e, i, ARM + j] = arm_a[r, j]
            contact[e, i, DETECTED_B + j] = contact[e, i, ARM_B + j] = arm_b[r, j]
            contact[e, i, DETECTED_NORMAL + j] = contact[e, i, NORMAL + j] = normal[r, j]
        contact[e, i, GAP] = gap[r]
        contact[e, i, BODY] = ints[o[O_PAIR_A] + pair_of(ints, o, r)]


@njit(cache=True, error_model="numpy", inline="always")
def pair_of(ints, o, r):
    """The pair (index into the ``O_PAIR_*`` tables) of pair slot r (0: the first pair slot)."""
    n_ground = ints[I_GROUND] * ints[I_K]
    for g in range(ints[I_GROUPS]):
        row = o[O_GROUPS] + GROUP_WIDTH * g
        start = ints[row + G_FIRST_SLOT] - n_ground
        slots = ints[row + G_SLOTS]
        if r < start + ints[row + G_PAIRS] * slots:
            return ints[row + G_FIRST_PAIR] + (r - start) // slots
    return -1


@njit(cache=True, error_model="numpy")
def pair_pushes(ints, floats, o, x, q, push):
    """The separation's body–body part at poses x (n, 3), q (n, 4): push (n, 3) ← the sum
    over pairs, in their order, of each pair's deepest overlap along its normal, split by mass
    (a moves by m_b/(m_a + m_b) of it, b by −m_a/(m_a + m_b): momentum unchanged). Returns
    whether a pair overlaps."""
    n_ground = ints[I_GROUND] * ints[I_K]
    rows = ints[I_C] - n_ground
    arm_a, arm_b, normal = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, 3))
    gap = np.empty(rows)
    detect_pairs(ints, floats, o, x, q, 0.0, 0.0, arm_a, arm_b, normal, gap)
    push[:] = 0.0
    found = False
    for g in range(ints[I_GROUPS]):
        row = o[O_GROUPS] + GROUP_WIDTH * g
        slots = ints[row + G_SLOTS]
        start = ints[row + G_FIRST_SLOT] - n_ground
        first = ints[row + G_FIRST_PAIR]
        for m in range(ints[row + G_PAIRS]):
            r0 = start + m * slots
            deepest = -gap[r0]
            for s in range(1, slots):
                deepest = max(deepest, -gap[r0 + s])
            if not deepest > 0:
                continue
            found = True
            a, b = ints[o[O_PAIR_A] + first + m], ints[o[O_PAIR_B] + first + m]
            ma, mb = floats[o[O_MASS] + a], floats[o[O_MASS] + b]
            share_a, share_b = mb / (ma + mb), -ma / (ma + mb)
            for j in range(3):
                step = deepest * normal[r0, j]
                push[a, j] += share_a * step
                push[b, j] += share_b * step
    return found


@register("collide_pairs")
def _collide_pairs(scene):
    data = contact_data(scene)
    if data is None:
        return None
    stage = next(s for s in scene.pipeline if s.name == "collide_pairs")
    slots = sum(len(pa) * s for pa, _, _, s in stage.pairs.groups)
    lay = next(s for s in scene.pipeline if s.name == "assemble_contacts").layout
    return Kernel(__name__, "collide", data, slots=slots + record_rows(lay), width=CONTACT_WIDTH)
