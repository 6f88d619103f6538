"""The body an environment simulates: a default box, or the user's ``sim.Body``, checked."""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import sim
from .validation import at_most, finite_array, positive_vector

MAX_HALF_EXTENT = 100.0  # m
MAX_MASS = 1e6  # kg


def make_body(
    body: sim.Body | None,
    half_extents: Any,
    mass: float | None,
    inertia: Any,
    *,
    default_half_extents: Any,
    default_mass: float,
    shapes: tuple[type, ...] | None = None,
) -> sim.Body:
    """``body`` as given, or a uniform box of ``half_extents`` and ``mass`` (defaults otherwise).

    ``inertia`` (3 principal moments or a 3×3 tensor, kg m²) overrides the body's; ``shapes``
    restricts the collision shapes the task can use (e.g. a box to land on its faces). Each
    failure is a ``ValueError`` naming the argument; half extents are at most
    :data:`MAX_HALF_EXTENT` and the mass at most :data:`MAX_MASS`.
    """
    if body is not None:
        if half_extents is not None or mass is not None:
            raise ValueError("body: give either body or half_extents/mass, not both")
        if not isinstance(body, sim.Body):
            raise ValueError(f"body must be a rigid_env.sim.Body, got {body!r}")
        if shapes is not None and not isinstance(body.shape, shapes):
            names = " or ".join(s.__name__ for s in shapes)
            raise ValueError(f"body must have a {names} shape, got {body.shape!r}")
        at_most(body.mass, "body (its mass)", MAX_MASS, " kg")
    else:
        half_extents = positive_vector(
            default_half_extents if half_extents is None else half_extents,
            "half_extents",
            maximum=MAX_HALF_EXTENT,
        )
        body = sim.Body.box(half_extents, default_mass if mass is None else mass)
        at_most(body.mass, "mass", MAX_MASS, " kg")
    if inertia is not None:
        tensor = finite_array(inertia, "inertia")
        if tensor.shape == (3,):
            tensor = np.diag(tensor)
        if tensor.shape != (3, 3):
            raise ValueError(
                f"inertia must be 3 principal moments or a 3×3 tensor, got {inertia!r}"
            )
        body = sim.Body(body.mass, tensor, body.shape, body.center_of_mass)
    return body
