"""Ground detection kernel, mirroring ``contacts.ground.GroundContacts.detect``.

Each shaped body offers its candidate points (a sphere its foot, a box its 8 corners, a
polyhedron its vertices, padded to a common count V by repeating the first as numpy does) and
takes the K lowest into its K contact slots, in ascending vertex order; among equal heights the
lower vertex index wins. Detection runs at the start-of-step pose (x0, q0), as numpy's.
"""

from __future__ import annotations

import numpy as np

from ..contacts.ground import GroundContacts
from .cache import njit
from .layout import ARM, BODY, CONTACT, GAP, Q0, X0
from .registry import Kernel, register
from .rotation import quat_rotate


def ground_data(bodies) -> tuple | None:
    """(points (G, V, 3), foot heights (G,), body indices (G,), [K]) from numpy's own
    detection set-up (one source of candidate points), or None for an unsupported shape."""
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


# Inlined into the driver: it runs for every element (see ``driver``).
@njit(cache=True, error_model="numpy", inline="always")
def detect(e, st, d):
    points, foot, bodies, keep = d
    k = keep[0]
    n_points = points.shape[1]
    contact = st[CONTACT]
    gaps = np.empty(n_points)
    chosen = np.empty(n_points, np.bool_)
    for g in range(bodies.shape[0]):
        b = bodies[g]
        x = st[X0][e, b]
        q = (st[Q0][e, b, 0], st[Q0][e, b, 1], st[Q0][e, b, 2], st[Q0][e, b, 3])
        for i in range(n_points):
            arm = quat_rotate(q, (points[g, i, 0], points[g, i, 1], points[g, i, 2]))
            gaps[i] = x[2] + (arm[2] + foot[g])
            chosen[i] = False
        for _ in range(k):
            best = -1
            for i in range(n_points):
                if not chosen[i] and (best < 0 or gaps[i] < gaps[best]):
                    best = i
            chosen[best] = True
        slot = g * k
        for i in range(n_points):
            if not chosen[i]:
                continue
            arm = quat_rotate(q, (points[g, i, 0], points[g, i, 1], points[g, i, 2]))
            contact[e, slot, ARM] = arm[0] + 0.0
            contact[e, slot, ARM + 1] = arm[1] + 0.0
            contact[e, slot, ARM + 2] = arm[2] + foot[g]
            contact[e, slot, GAP] = gaps[i]
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
