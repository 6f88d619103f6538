"""``rigid_env.sim``: a batched rigid-body simulator in numpy (no Gymnasium, no torch).

Conventions (course notes): ``p = x + R r``; quaternions (x, y, z, w) with w = cos(θ/2);
angular velocity in the world frame; world inertia ``M = R M0 Rᵀ``.
"""

from . import rotation
from .body import Body
from .model import Ground, Material, Model, Spring
from .scene import (
    CONTACT_INTEGRATOR,
    DEFAULT_INTEGRATOR,
    INTEGRATORS,
    DivergenceError,
    Scene,
)
from .shapes import Box, Polyhedron, Sphere
from .state import State

__all__ = [
    "Body",
    "Box",
    "CONTACT_INTEGRATOR",
    "DEFAULT_INTEGRATOR",
    "DivergenceError",
    "Ground",
    "INTEGRATORS",
    "Material",
    "Model",
    "Polyhedron",
    "Scene",
    "Sphere",
    "Spring",
    "State",
    "rotation",
]
