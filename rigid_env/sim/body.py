"""A rigid body's static description: mass, inertia about the centre of mass, collision shape."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import mass as mass_properties
from .shapes import Box, Polyhedron, Shape, Sphere
from .validation import finite_array, inertia_tensor, positive_scalar


class Body:
    """Mass properties in body axes with the origin at the centre of mass.

    ``inertia`` is the 3×3 tensor ``M0`` of the notes; the world tensor is ``R M0 Rᵀ``.
    ``center_of_mass`` is where that origin lies in the coordinates the body was described in
    (zero for primitives, Mirtich's centroid for polyhedra).
    """

    def __init__(
        self,
        mass: float,
        inertia: ArrayLike,
        shape: Shape | None = None,
        center_of_mass: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        self.mass = positive_scalar(mass, "mass")
        self.inertia = inertia_tensor(inertia, "inertia")
        self.inertia.setflags(write=False)
        # Any, not Shape | None: the envs read their box's corners without narrowing the union.
        self.shape: Any = shape
        self.center_of_mass = finite_array(center_of_mass, "center_of_mass", (3,))
        if self.center_of_mass.shape != (3,):
            raise ValueError(
                f"center_of_mass must be a 3-vector, got shape {self.center_of_mass.shape}"
            )
        self.center_of_mass.setflags(write=False)

    @classmethod
    def box(cls, half_extents: ArrayLike, mass: float) -> Body:
        """A uniform box centred on its centre of mass, edges along the body axes."""
        props = mass_properties.box(half_extents, mass)
        return cls(props.mass, props.inertia, Box(np.array(half_extents, dtype=float)))

    @classmethod
    def sphere(cls, radius: float, mass: float) -> Body:
        props = mass_properties.sphere(radius, mass)
        return cls(props.mass, props.inertia, Sphere(float(radius)))

    @classmethod
    def polyhedron(cls, vertices: ArrayLike, faces: mass_properties.Faces, density: float) -> Body:
        """A closed uniform polyhedron (Mirtich 1996); body origin moves to its centre of mass."""
        props = mass_properties.polyhedron(vertices, faces, density)
        local = np.array(vertices, dtype=float) - props.center_of_mass
        shape = Polyhedron(local, tuple(tuple(int(i) for i in f) for f in faces))
        return cls(props.mass, props.inertia, shape, props.center_of_mass)

    def __repr__(self) -> str:
        kind = type(self.shape).__name__ if self.shape is not None else "Body"
        return f"<Body {kind} mass={self.mass:g} inertia_diag={np.diag(self.inertia)}>"
