"""Force stages. A scene gets only the terms it was given; each maps a state to (force, torque).

Every term is a stage object (``rigid_env.sim.pipeline.Stage``) with

* ``wrench(x, q, v, w) -> (F, T)`` on world-frame arrays ``(*batch, n, 3)``, with ``None`` for
  a component it does not produce, so integrators can evaluate it at their own intermediate
  states (RK4 stages, splitting half steps);
* ``__call__(ctx)``: adds its wrench at the context's state to the step's accumulators;
* ``velocity_dependent``: whether the wrench depends on (v, ω);
* ``damping_matrix(x, q)`` for velocity-dependent terms: the per-body 6×6 matrix C with
  (F, T) = (F, T)|₍ᵥ,ω₎₌₀ − C (v, ω) (every damping term here is linear in the velocities),
  which the symmetric splitting kicks solve with.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .model import Model
from .rotation import cross, quat_rotate, quat_to_matrix, skew

if TYPE_CHECKING:  # the pipeline imports the model; only its type is needed here
    from .pipeline import StepContext

# (F, T) on world-frame arrays (*batch, n, 3); None for a component a term does not produce.
Wrench = tuple[np.ndarray | None, np.ndarray | None]


class Gravity:
    name = "gravity"
    velocity_dependent = False

    def __init__(self, model: Model) -> None:
        self.weight = model.mass[:, None] * model.gravity  # (n, 3), broadcast over the batch

    def wrench(self, x: np.ndarray, q: np.ndarray, v: np.ndarray, w: np.ndarray) -> Wrench:
        return self.weight, None

    def __call__(self, ctx: StepContext) -> None:
        ctx.add_wrench(self.weight, None)


class Damping:
    """Linear and angular damping as decay rates (1/s): ṗ = −γ_v p, L̇ = −γ_ω L."""

    name = "damping"
    velocity_dependent = True

    def __init__(self, model: Model) -> None:
        self.model = model
        self.gv, self.gw = model.linear_damping, model.angular_damping
        self.m = model.mass[:, None]

    def wrench(self, x: np.ndarray, q: np.ndarray, v: np.ndarray, w: np.ndarray) -> Wrench:
        force = -self.gv * self.m * v if self.gv else None
        torque = -self.gw * self.model.apply_inertia(quat_to_matrix(q), w) if self.gw else None
        return force, torque

    def __call__(self, ctx: StepContext) -> None:
        ctx.add_wrench(*self.wrench(ctx.x, ctx.q, ctx.v, ctx.w))

    def damping_matrix(self, x: np.ndarray, q: np.ndarray) -> np.ndarray:
        """diag(γ_v m I, γ_ω R M0 Rᵀ) per body, (*batch, n, 6, 6)."""
        rot = quat_to_matrix(q)
        out = np.zeros((*q.shape[:-1], 6, 6))
        out[..., :3, :3] = self.gv * self.m[..., None] * np.eye(3)
        out[..., 3:, 3:] = self.gw * (rot @ self.model.inertia @ np.swapaxes(rot, -1, -2))
        return out


class Springs:
    """Sum of the springs' forces and torques ``(R r) × F`` per body (notes: T = (R r) × F)."""

    name = "springs"

    def __init__(self, model: Model) -> None:
        s = model.springs
        self.n_bodies = model.n_bodies
        self.body = np.array([sp.body for sp in s])
        self.anchor = np.stack([sp.anchor for sp in s])  # (s, 3)
        self.attach = np.stack([sp.attach for sp in s])
        self.k = np.array([sp.stiffness for sp in s])[:, None]
        self.c = np.array([sp.damping for sp in s])[:, None]
        self.rest = np.array([sp.rest_length for sp in s])[:, None]
        self.has_rest = self.rest > 0
        self.velocity_dependent = bool(np.any(self.c))
        # Spring → body incidence: sums the springs on each body without a loop or np.add.at.
        self.incidence = np.zeros((len(s), model.n_bodies))
        self.incidence[np.arange(len(s)), self.body] = 1.0

    def _geometry(
        self, x: np.ndarray, q: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        arm = quat_rotate(q[..., self.body, :], self.attach)  # R r, (*batch, s, 3)
        d = x[..., self.body, :] + arm - self.anchor
        length = np.linalg.norm(d, axis=-1, keepdims=True)
        unit = d / np.where(length > 0, length, 1.0)
        return arm, d, length, unit

    def wrench(self, x: np.ndarray, q: np.ndarray, v: np.ndarray, w: np.ndarray) -> Wrench:
        arm, d, length, unit = self._geometry(x, q)
        pdot = v[..., self.body, :] + cross(w[..., self.body, :], arm)
        k, c, has_rest = self.k, self.c, self.has_rest
        stretched = np.where(has_rest, k * (length - self.rest) * unit, k * d)
        damped = np.where(
            has_rest, c * np.sum(pdot * unit, axis=-1, keepdims=True) * unit, c * pdot
        )
        f = -(stretched + damped)
        t = cross(arm, f)
        return (
            np.einsum("...si,sn->...ni", f, self.incidence),
            np.einsum("...si,sn->...ni", t, self.incidence),
        )

    def __call__(self, ctx: StepContext) -> None:
        ctx.add_wrench(*self.wrench(ctx.x, ctx.q, ctx.v, ctx.w))

    def damping_matrix(self, x: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Σ Jᵀ C J over each body's springs, J = [I, −(R r)*] (ṗ = J (v, ω)), C = c d̂ d̂ᵀ (or
        c I without rest length), (*batch, n, 6, 6)."""
        arm, _, _, unit = self._geometry(x, q)
        along = unit[..., :, None] * unit[..., None, :]
        damp = self.c[..., None] * np.where(self.has_rest[..., None], along, np.eye(3))
        eye = np.broadcast_to(np.eye(3), arm.shape + (3,))
        jac = np.concatenate((eye, -skew(arm)), axis=-1)  # (*batch, s, 3, 6)
        return np.einsum("...sai,...sab,...sbj,sn->...nij", jac, damp, jac, self.incidence)


ForceStage = Gravity | Damping | Springs


def build(model: Model) -> tuple[ForceStage, ...]:
    """The force stages a model needs, in order; a free body in space gets none."""
    stages: list[ForceStage] = []
    if model.gravity is not None and np.any(model.gravity):
        stages.append(Gravity(model))
    if model.linear_damping or model.angular_damping:
        stages.append(Damping(model))
    if model.springs:
        stages.append(Springs(model))
    return tuple(stages)
