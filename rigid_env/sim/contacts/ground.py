"""Shapes against the ground plane z = 0: candidate contact points as a padded manifold.

Every shaped body offers the same number K of candidate points, its lowest ones: the centre's
foot for a sphere, the four lowest corners for a box (a face, the most a box can rest on), the
eight lowest vertices for a polyhedron (all of them if it has fewer). Candidates need not touch:
the solver treats a point at gap d > 0 as a speculative contact (Catto, "Contact Manifolds" /
Box2D v3), which is what stops fast bodies from tunnelling. Shorter lists are padded by repeating
a vertex; a repeated point splits its impulse, it does not change the solution.
"""

from __future__ import annotations

import numpy as np

from ..shapes import Box, Polyhedron, Sphere


class GroundContacts:
    """The candidate points of the shaped bodies of a model, which the ground kernel detects
    with (``compiled/ground.py``): ``points`` (G, V, 3) in body coordinates, padded; ``foot``
    the sphere's centre − r ẑ; ``k`` the candidates kept per body, the K lowest; ``bodies``
    the shaped bodies' indices. The normal is +z for all."""

    def __init__(self, bodies):
        shaped = [i for i, b in enumerate(bodies) if b.shape is not None]
        if not shaped:
            raise ValueError("ground: no body has a collision shape")
        points, radii, keep = [], [], []
        for i in shaped:
            shape = bodies[i].shape
            if isinstance(shape, Sphere):
                points.append(np.zeros((1, 3)))
                radii.append(shape.radius)
                keep.append(1)
            elif isinstance(shape, Box):
                points.append(shape.vertices)
                radii.append(0.0)
                keep.append(4)
            elif isinstance(shape, Polyhedron):
                # Only vertices of its faces: a listed point no face uses is not on the body.
                used = sorted({i for face in shape.faces for i in face})
                points.append(np.asarray(shape.vertices, float)[used])
                radii.append(0.0)
                keep.append(min(len(used), 8))
            else:
                raise ValueError(f"ground: unsupported shape {type(shape).__name__}")
        n_points = max(len(p) for p in points)
        self.k = max(keep)
        padded = [np.concatenate([p, np.repeat(p[:1], n_points - len(p), 0)]) for p in points]
        self.points = np.stack(padded)[:, :, :]  # (G, V, 3) body coordinates
        self.foot = np.zeros((len(shaped), 1, 3))
        self.foot[:, 0, 2] = -np.array(radii)  # sphere: centre − r ẑ
        self.bodies = np.array(shaped)
