"""The course notes' modified explicit Euler, on rotation matrices and on quaternions.

Notes, "Integración Numérica": v ← v + Δt F/m; x ← x + Δt v; L ← L + Δt T; ω = M⁻¹ L;
R ← R + Δt ω* R; repair R (Gram–Schmidt); M⁻¹ = R M0⁻¹ Rᵀ. First order. The state keeps ω,
so L = M ω is recovered from the start-of-step inertia, which reproduces the notes' sequence
and keeps L constant in torque-free motion.

Split into the pipeline's two parts: the velocity part applies the kicks (v, and ω = M⁻¹ L
with the start-of-step inertia); the position part moves x and R with those (possibly
contact-corrected) velocities and re-expresses ω = M⁻¹ L in the new orientation.
"""

from __future__ import annotations

import numpy as np

from ..rotation import (
    cross,
    gram_schmidt,
    matrix_to_quat,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
)
from .common import POSITION, VELOCITY, Integrator, align_sign, start_rotation, translate


def velocity(ctx) -> None:
    model, dt = ctx.model, ctx.dt
    if ctx.force is not None:
        ctx.v = ctx.v + dt * model.inv_mass[:, None] * ctx.force
    if ctx.torque is not None:
        rot = start_rotation(ctx)
        momentum = model.apply_inertia(rot, ctx.w) + dt * ctx.torque
        ctx.w = model.apply_inverse_inertia(rot, momentum)


def position_matrix(ctx) -> None:
    model, dt, w = ctx.model, ctx.dt, ctx.w
    rot = start_rotation(ctx)
    momentum = model.apply_inertia(rot, w)
    # ω* R, column by column: ω × α, ω × β, ω × γ.
    w_star_r = np.swapaxes(cross(w[..., None, :], np.swapaxes(rot, -1, -2)), -1, -2)
    rot = gram_schmidt(rot + dt * w_star_r)
    translate(ctx)
    ctx.q = align_sign(matrix_to_quat(rot), ctx.q)
    ctx.w = model.apply_inverse_inertia(rot, momentum)


def position_quat(ctx) -> None:
    model, dt, w = ctx.model, ctx.dt, ctx.w
    momentum = model.apply_inertia(start_rotation(ctx), w)
    # Notes: q̇ = ½ (ω, 0) ∘ q, then renormalise (the quaternion form of the repair).
    w_quat = np.concatenate((w, np.zeros_like(w[..., :1])), axis=-1)
    q = quat_normalize(ctx.q + 0.5 * dt * quat_multiply(w_quat, ctx.q))
    translate(ctx)
    ctx.q = q
    ctx.w = model.apply_inverse_inertia(quat_to_matrix(q), momentum)


EULER = Integrator(
    "euler",
    ((VELOCITY, velocity), (POSITION, position_matrix)),
    order=1,
    symplectic=False,
    summary="the notes' Euler on R with Gram–Schmidt repair; world L exact, energy drifts",
)
EULER_QUAT = Integrator(
    "euler_quat",
    ((VELOCITY, velocity), (POSITION, position_quat)),
    order=1,
    symplectic=False,
    summary="the same on quaternions (cheapest); world L exact, energy grows",
)
RECORDS = (EULER, EULER_QUAT)
