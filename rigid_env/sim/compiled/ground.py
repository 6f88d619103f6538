"""Ground detection kernel, mirroring ``contacts.ground.GroundContacts.detect``.

Each shaped body offers its candidate points (a sphere its foot, a box its 8 corners, a
polyhedron its vertices, padded to a common count V by repeating the first) and
takes the K lowest into its K contact slots, in ascending vertex order; among equal heights the
lower vertex index wins. Detection runs at the start-of-step pose (x0, q0).
"""

from __future__ import annotations

import math

import numpy as np

from ..contacts.ground import GroundContacts
from .cache import njit
from .layout import ARM, BODY, CONTACT, GAP, Q0, X0
from .registry import Kernel, register
from .rotation import quat_rotate, quat_to_matrix


def ground_data(bodies) -> tuple | None:
    """(points (G, V, 3), foot heights (G,), body indices (G,), [K]) from the detector
    set-up (``contacts.GroundContacts``, one source of candidate points), or None for an unsupported shape."""
    try:
        ground = GroundContacts(bodies)
    except ValueError:
        return None
    return (
        np.ascontiguousarray(ground.points, dtype=float),
        np.ascontiguousarray(ground.foot[:, 0, 2], dtype=float),
        np.asarray(ground.bodies, dtype=np.int64),
        np.array([ground.k], dtype=np.int64),
    )


@njit(cache=True, error_model="numpy", inline="always")
def _height(r2, z, points, foot, g, i):
    """Vertex i's height by the third row of R, for the ordering only (``GAP`` is the rotated point's)."""
    return z + (
        (r2[0] * points[g, i, 0] + r2[1] * points[g, i, 1] + r2[2] * points[g, i, 2]) + foot[g]
    )


@njit(cache=True, error_model="numpy", inline="always")
def _after(h, i, h0, i0):
    """(h, i) after (h0, i0): by height, ties to the lower index ."""
    return h > h0 or (h == h0 and i > i0)


# Called by the driver for every element of a contact step (``driver`` says why a call). It
# allocates nothing and calls nothing that can raise: either would make numba's pruner keep a reference count
# per array of the step and data tuples, ~36 atomic operations per element step. So the K
# lowest are found in K passes, each the lowest after the previous one (no flags to store),
# ordered by the height through R's third row (3 products a vertex); their arms and gaps are
# then numpy's operations, as before.
@njit(cache=True, error_model="numpy")
def detect(e, st, d):
    points, foot, bodies, keep = d
    k = keep[0]
    n_points = points.shape[1]
    contact = st[CONTACT]
    xs, qs = st[X0], st[Q0]
    for g in range(bodies.shape[0]):
        b = bodies[g]
        z = xs[e, b, 2]
        q = (qs[e, b, 0], qs[e, b, 1], qs[e, b, 2], qs[e, b, 3])
        rot = quat_to_matrix(q)
        r2 = (rot[6], rot[7], rot[8])
        # The K-th lowest (h_k, i_k): every vertex up to it in that order is kept.
        h_k = -math.inf
        i_k = -1
        for _ in range(k):
            best = -1
            h_best = 0.0
            for i in range(n_points):
                h = _height(r2, z, points, foot, g, i)
                if _after(h, i, h_k, i_k) and (best < 0 or h < h_best):
                    best, h_best = i, h
            if best < 0:
                break
            h_k, i_k = h_best, best
        slot = g * k
        for i in range(n_points):
            if _after(_height(r2, z, points, foot, g, i), i, h_k, i_k):
                continue
            arm = quat_rotate(q, (points[g, i, 0], points[g, i, 1], points[g, i, 2]))
            contact[e, slot, ARM] = arm[0] + 0.0
            contact[e, slot, ARM + 1] = arm[1] + 0.0
            contact[e, slot, ARM + 2] = arm[2] + foot[g]
            contact[e, slot, GAP] = z + (arm[2] + foot[g])
            contact[e, slot, BODY] = b
            slot += 1


@register("collide_ground")
def _collide_ground(scene):
    model = scene.model
    if model.ground is None:
        return None
    data = ground_data(model.bodies)
    if data is None:
        return None
    return Kernel(__name__, "detect", data, slots=len(data[2]) * int(data[3][0]))
