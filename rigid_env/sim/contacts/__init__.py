"""Contacts: what a scene's contact stages are and what their kernels read.

One idea per module: ``ground``, ``pairs`` and ``box_box`` set up the detectors (candidate
points, pair groups, shape tables; the detection kernels are ``compiled/ground.py`` and
``compiled/pairs.py``); ``assembly`` lays the contact slots out (``Layout``); ``settings``
holds the solve's settings (:class:`SolverSettings`); ``stages`` names the stages and defines
the report (:class:`ContactReport` in ``state.report["contacts"]``). The physics of every
stage is its element kernel in ``rigid_env.sim.compiled``.

``build(model, dt, settings)`` returns the contact stages of a model as two tuples: those that
run between the integrator's velocity and position updates, and those that run after the
position update; both empty when it has neither a ground nor body–body contacts (a free body
pays nothing, a single body on the ground pays no pair detection).
"""

from __future__ import annotations

from .assembly import Layout
from .ground import GroundContacts
from .pairs import PairContacts
from .settings import SolverSettings
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
