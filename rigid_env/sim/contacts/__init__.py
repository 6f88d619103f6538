"""Contacts: detection against the ground and between bodies, and the impulse solver.

``build(model, dt)`` returns the stage names and the stage for a model, or ``((), None)`` when
it has neither a ground nor body–body contacts: a free body pays nothing, a single body on the
ground pays no pair detection.
"""

from __future__ import annotations

from .ground import GroundContacts
from .pairs import PairContacts
from .solver import ContactStage

# The stage is appended to the step: it needs the positions to have drifted with the same
# velocity it corrects (x₁ = x₀ + Δt v₁), i.e. a semi-implicit (symplectic) Euler step.
COMPATIBLE_INTEGRATORS = ("euler", "euler_quat", "implicit_gyro", "implicit")


def build(model, dt):
    ground = pairs = None
    names = []
    if model.ground is not None and any(b.shape is not None for b in model.bodies):
        ground = GroundContacts(model.bodies)
        names.append("collide_ground")
    if model.contacts is not None and sum(b.shape is not None for b in model.bodies) >= 2:
        pairs = PairContacts(model.bodies)
        names.append("collide_pairs")
    if not names:
        return (), None
    names.append("solve_contacts")
    return tuple(names), ContactStage(model, dt, ground, pairs)


__all__ = ["COMPATIBLE_INTEGRATORS", "ContactStage", "GroundContacts", "PairContacts", "build"]
