"""``rigid_env.sim``: a batched rigid-body simulator of numba element kernels over numpy arrays
(no Gymnasium, no torch).

Conventions (course notes): ``p = x + R r``; quaternions (x, y, z, w) with w = cos(θ/2);
angular velocity in the world frame; world inertia ``M = R M0 Rᵀ``.
"""

from . import pipeline, rotation
from .body import Body
from .contacts import ContactReport, ContactSolverWarning, SolverSettings
from .integrators import CONTACT_CAPABLE
from .integrators import RECORDS as INTEGRATOR_RECORDS
from .model import Ground, Material, Model, Spring
from .parameters import Parameters
from .pipeline import Stage, StageTimer
from .scene import (
    BACKENDS,
    CONTACT_INTEGRATOR,
    DEFAULT_INTEGRATOR,
    INTEGRATORS,
    DivergenceError,
    Scene,
)
from .shapes import Box, Polyhedron, Sphere
from .state import State

__all__ = [
    "BACKENDS",
    "Body",
    "Box",
    "CONTACT_CAPABLE",
    "CONTACT_INTEGRATOR",
    "ContactReport",
    "ContactSolverWarning",
    "DEFAULT_INTEGRATOR",
    "DivergenceError",
    "Ground",
    "INTEGRATORS",
    "INTEGRATOR_RECORDS",
    "Material",
    "Model",
    "Parameters",
    "Polyhedron",
    "Scene",
    "SolverSettings",
    "Sphere",
    "Spring",
    "Stage",
    "StageTimer",
    "State",
    "pipeline",
    "rotation",
]
