"""Box against box: separating axes, then a clipped face manifold or one edge–edge point.

Separating-axis test (Gottschalk, Lin & Manocha, "OBBTree", 1996; Ericson, *Real-Time Collision
Detection* 4.4.1) over the 15 candidate axes: the 3 + 3 face normals and the 9 cross products
of an edge of a with an edge of b (near-parallel pairs skipped: their cross product has no
direction). The axis of largest separation (least penetration) is the contact normal. Face axes
are preferred (Bullet's ``btBoxBoxDetector``, from ODE's ``dBoxBox``: an edge axis must beat the
best face by its relative fudge factor 1.05) plus an absolute margin (Box2D's
``0.1 * linear_slop`` between the two reference-face candidates): near ties otherwise flip
between a 4-point face manifold and a 1-point edge contact from one step to the next, and a
resting stack rocks on that single point.

Face contact: the reference face is the face of the chosen axis, the incident face the face of
the other box most anti-parallel to it; the incident quad is clipped against the reference
face's four side planes (Sutherland–Hodgman on fixed-size padded polygons, ≤ 8 vertices, so the
whole batch clips in one pass of array operations) and reduced to 4 points: the deepest, the one
farthest from it, and the two spanning the largest triangles on either side of that diagonal
(Gregorius, "Robust contact creation for physics simulations", GDC 2015). Points above the
reference face are kept with gap > 0: the solver treats them as speculative contacts.
Edge contact: the closest points of the two supporting edges (Ericson 5.1.8), one point
repeated in all four slots (a repeated point splits its impulse, it does not change it).

Convention as in ``pairs.py``: ``normal`` points from b to a, ``gap`` < 0 is penetration.
"""

from __future__ import annotations

import numpy as np

SLOTS = 4
MAX_POLYGON = 8  # a quad clipped by 4 half-planes gains at most one vertex per plane
NEAR_PARALLEL = 1e-6  # |e_a × e_b| below this: the edge pair defines no axis
EDGE_FUDGE = 1.05  # relative preference for face axes (ODE / Bullet)
FACE_MARGIN = 1e-3  # absolute preference, as a fraction of the smallest half-extent
# Gap of a slot with no contact point (separated boxes whose faces do not overlap): far out of
# reach of any step, yet finite so the solver's arithmetic on it stays finite. Its target is
# no velocity of the problem: the solve's scales leave it out (``compiled.contact_solve``).
FAR = 1e9


def box_box(half_a, half_b):
    """Detection for pairs of boxes with half extents ``half_a``, ``half_b`` (P, 3):
    ``detect(xa, qa, xb, qb)`` on (…, P, 3|4) → arms on a and on b (…, P, 4, 3), normal
    (…, P, 4, 3), gap (…, P, 4), by the compiled kernel (``compiled.pairs.box_box``)."""
    half_a, half_b = np.asarray(half_a, float), np.asarray(half_b, float)
    margin = FACE_MARGIN * np.minimum(half_a.min(-1), half_b.min(-1))

    def detect(xa, qa, xb, qb):
        from ..compiled import pairs as kernels

        return kernels.run(kernels.box_box, (xa, qa, xb, qb), (half_a, half_b, margin), SLOTS)

    detect.params = (half_a, half_b, margin)  # type: ignore[attr-defined]
    return detect


__all__ = ["SLOTS", "box_box"]
