"""Contacts: detection against the ground and between bodies, assembly, impacts, the solve.

One idea per module: ``ground``, ``pairs`` and ``box_box`` detect; ``assembly`` builds the rows
and effective masses; ``restitution`` resolves impacts in time order; ``solve`` is the
Gauss–Seidel solve to a stated tolerance (``SolverSettings``); ``warm_start`` its starting
impulses; ``stage`` runs them in a step and reports (``ContactReport``).

``build(model, dt, settings)`` returns the stage names and the stage for a model, or
``((), None)`` when it has neither a ground nor body–body contacts: a free body pays nothing, a
single body on the ground pays no pair detection.
"""

from __future__ import annotations

import numpy as np

from ..rotation import quat_exp, quat_multiply, quat_normalize
from ..state import State
from .ground import GroundContacts
from .pairs import PairContacts
from .solve import SolverSettings
from .stage import ContactReport, ContactSolverWarning, ContactStage

# The response acts between the velocity and the position update of a semi-implicit step.
COMPATIBLE_INTEGRATORS = ("euler", "euler_quat", "implicit_gyro", "implicit")


class AppendedContactStage(ContactStage):
    """``stage(old, new) -> State`` for a step whose integrator already moved the positions:
    the response replaces the velocities of the engaged elements and redoes their position
    update, x = x₀ + Δt v, q = exp(Δt ω) q₀, then removes what penetration is left."""

    def __call__(self, old: State, new: State) -> State:
        n, dt = self.model.n_bodies, self.dt
        batch = old.position.shape[:-2]
        x0, q0, v0, w0 = (a.reshape(-1, n, a.shape[-1]) for a in old.arrays())
        x1, q1, v1, w1 = (a.reshape(-1, n, a.shape[-1]) for a in new.arrays())
        u1 = np.concatenate((v1, w1), axis=-1)
        u = self.respond(x0, q0, np.concatenate((v0, w0), axis=-1), u1)
        if u is u1:
            return new
        changed = np.any(u != u1, axis=(-1, -2))
        v, w = u[..., :3], u[..., 3:]
        x = np.where(changed[:, None, None], x0 + dt * v, x1)
        q = np.where(
            changed[:, None, None], quat_normalize(quat_multiply(quat_exp(dt * w), q0)), q1
        )
        x = np.where(changed[:, None, None], self.project(x0, q0, x, q, u), x)
        out = (x, q, v, w)
        return State(*(a.reshape(*batch, n, a.shape[-1]) for a in out))


def build(model, dt, settings: SolverSettings | None = None):
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
    return tuple(names), AppendedContactStage(model, dt, ground, pairs, settings)


__all__ = [
    "COMPATIBLE_INTEGRATORS",
    "ContactReport",
    "ContactSolverWarning",
    "ContactStage",
    "GroundContacts",
    "PairContacts",
    "SolverSettings",
    "build",
]
