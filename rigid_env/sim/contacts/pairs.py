"""Body–body detection for the pairs a scene can have: sphere–sphere, sphere–box, box–box.

Built only when a scene asks for body–body contacts (``Scene(contacts=Material(...))``) and has
at least two shaped bodies. A pair involving a sphere yields one contact point (a sphere touches
a convex shape at one point), a box–box pair a padded manifold of 4 (``box_box.py``); each
group's arrays carry a slot axis of that length so the solver treats them like ground slots.
Each kind is built only when the scene has such a pair. Convention: ``normal`` points from body
b to body a; ``gap`` < 0 is penetration, ``gap`` > 0 a speculative contact.
"""

from __future__ import annotations

import numpy as np

from ..shapes import Box, Sphere
from .box_box import SLOTS as BOX_BOX_SLOTS
from .box_box import box_box


def sphere_sphere(ra, rb):
    """Detection for pairs of spheres of radii ``ra``, ``rb`` (P,): the normal along the
    centres (+z when they coincide), gap = distance − radii (``compiled.pairs``)."""
    params = np.asarray(ra, float), np.asarray(rb, float)

    def detect(xa, qa, xb, qb):
        from ..compiled import pairs as kernels

        return kernels.run(kernels.sphere_sphere, (xa, qa, xb, qb), params)

    detect.params = params  # type: ignore[attr-defined]  # its tables (``contact_pairs``)
    return detect


def sphere_box(radius, half_extents):
    """Sphere a against box b: closest point of the box to the sphere's centre (Ericson 5.1.3);
    a centre inside the box leaves through the face of least penetration (``compiled.pairs``)."""
    params = np.asarray(radius, float), np.asarray(half_extents, float)

    def detect(xa, qa, xb, qb):
        from ..compiled import pairs as kernels

        return kernels.run(kernels.sphere_box, (xa, qa, xb, qb), params)

    detect.params = params  # type: ignore[attr-defined]
    return detect


class PairContacts:
    """All sphere–sphere, sphere–box and box–box pairs of a model, grouped by kind: per group
    its bodies a and b, its detector (whose ``params`` are its shape tables) and its slots per
    pair."""

    def __init__(self, bodies):
        groups: dict[str, list[tuple[int, int]]] = {
            "sphere_sphere": [],
            "sphere_box": [],
            "box_box": [],
        }
        shaped = [i for i, b in enumerate(bodies) if b.shape is not None]
        for n, i in enumerate(shaped):
            for j in shaped[n + 1 :]:
                si, sj = bodies[i].shape, bodies[j].shape
                if isinstance(si, Sphere) and isinstance(sj, Sphere):
                    groups["sphere_sphere"].append((i, j))
                elif isinstance(si, Sphere) and isinstance(sj, Box):
                    groups["sphere_box"].append((i, j))
                elif isinstance(si, Box) and isinstance(sj, Sphere):
                    groups["sphere_box"].append((j, i))
                elif isinstance(si, Box) and isinstance(sj, Box):
                    groups["box_box"].append((i, j))
                else:
                    raise ValueError(
                        f"contacts: body–body contacts support sphere–sphere, sphere–box and "
                        f"box–box, "
                        f"not {type(si).__name__}–{type(sj).__name__} (bodies {i}, {j})"
                    )
        self.groups = []
        self.kinds: list[str] = []  # per group, its kind ("sphere_sphere", ...)
        for kind, pairs in groups.items():
            if not pairs:
                continue
            a = np.array([p[0] for p in pairs])
            b = np.array([p[1] for p in pairs])
            slots = 1
            if kind == "sphere_sphere":
                fn = sphere_sphere(
                    [bodies[i].shape.radius for i in a], [bodies[j].shape.radius for j in b]
                )
            elif kind == "sphere_box":
                fn = sphere_box(
                    [bodies[i].shape.radius for i in a],
                    np.stack([bodies[j].shape.half_extents for j in b]),
                )
            else:
                fn = box_box(
                    np.stack([bodies[i].shape.half_extents for i in a]),
                    np.stack([bodies[j].shape.half_extents for j in b]),
                )
                slots = BOX_BOX_SLOTS
            self.groups.append((a, b, fn, slots))
            self.kinds.append(kind)
        self.n_pairs = sum(len(g[0]) for g in self.groups)


__all__ = ["PairContacts"]
