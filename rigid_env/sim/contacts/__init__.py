"""Contacts: detection against the ground and between bodies, and the impulse solver.

``build(model, dt)`` returns the contact stages of a model as two tuples: those that run
between the integrator's velocity and position updates, and those that run after the position
update; both empty when it has neither a ground nor body–body contacts (a free body pays
nothing, a single body on the ground pays no pair detection).
"""

from __future__ import annotations

from .ground import GroundContacts
from .pairs import PairContacts
from .solver import ContactStage
from .stages import CollideGround, CollidePairs, Restitute, SolveContacts


def build(model, dt) -> tuple[tuple, tuple]:
    ground = pairs = None
    stages: list = []
    if model.ground is not None and any(b.shape is not None for b in model.bodies):
        ground = GroundContacts(model.bodies)
        stages.append(CollideGround(ground))
    if model.contacts is not None and sum(b.shape is not None for b in model.bodies) >= 2:
        pairs = PairContacts(model.bodies)
        stages.append(CollidePairs(pairs))
    if not stages:
        return (), ()
    stages.append(SolveContacts(ContactStage(model, dt, ground, pairs)))
    return tuple(stages), (Restitute(),)


__all__ = ["ContactStage", "GroundContacts", "PairContacts", "build"]
