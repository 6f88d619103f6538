"""Contacts: detection, assembly, impacts and the solve, as stages of the step pipeline.

One idea per module: ``ground``, ``pairs`` and ``box_box`` detect; ``assembly`` builds the rows
and effective masses; ``restitution`` resolves impacts in time order; ``solve`` is the
Gauss–Seidel solve to a stated tolerance (:class:`SolverSettings`), ``warm_start`` its
starting impulses, ``newton`` its semi-smooth Newton polish for the slow cases; ``energy`` keeps the step from gaining energy; ``stages`` wires them into
the pipeline and reports (:class:`ContactReport` in ``scene.report["contacts"]``).

``build(model, dt, settings)`` returns the contact stages of a model as two tuples: those that
run between the integrator's velocity and position updates, and those that run after the
position update; both empty when it has neither a ground nor body–body contacts (a free body
pays nothing, a single body on the ground pays no pair detection).
"""

from __future__ import annotations

from .assembly import Layout
from .ground import GroundContacts
from .pairs import PairContacts
from .solve import SolverSettings
from .stages import (
    AssembleContacts,
    CollideGround,
    CollidePairs,
    ContactReport,
    ContactSolverWarning,
    LimitEnergy,
    Restitute,
    SeparateContacts,
    SolveContacts,
)


def build(model, dt, settings: SolverSettings | None = None) -> tuple[tuple, tuple]:
    if settings is None:
        settings = SolverSettings()
    if not isinstance(settings, SolverSettings):
        raise ValueError(f"contact_solver must be a SolverSettings, got {settings!r}")
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
    layout = Layout(model, ground, pairs)
    stages += [
        AssembleContacts(layout),
        Restitute(layout, settings),
        SolveContacts(layout, settings),
        LimitEnergy(layout),
    ]
    return tuple(stages), (SeparateContacts(layout),)


__all__ = [
    "ContactReport",
    "ContactSolverWarning",
    "GroundContacts",
    "Layout",
    "PairContacts",
    "SolverSettings",
    "build",
]
