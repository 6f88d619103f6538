"""The course notes' modified explicit Euler, on rotation matrices and on quaternions.

Notes, "Integración Numérica": v ← v + Δt F/m; x ← x + Δt v; L ← L + Δt T; ω = M⁻¹ L;
R ← R + Δt ω* R; repair R (Gram–Schmidt); M⁻¹ = R M0⁻¹ Rᵀ. First order. The state keeps ω,
so L = M ω is recovered from the start-of-step inertia, which reproduces the notes' sequence
exactly and keeps L constant in torque-free motion.
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
from ..state import State
from .common import align_sign, kick, wrench


def _translate_and_kick(model, state, dt, forces, force, torque, rot):
    x, q, v, w = state.arrays()
    f, t = wrench(forces, x, q, v, w, force, torque)
    v = kick(v, dt, model.inv_mass[:, None], f)
    angular_momentum = model.apply_inertia(rot, w)
    if t is not None:
        angular_momentum = angular_momentum + dt * t
    return x + dt * v, v, angular_momentum


def euler(model, state, dt, forces, force, torque) -> State:
    rot = quat_to_matrix(state.orientation)
    x, v, angular_momentum = _translate_and_kick(model, state, dt, forces, force, torque, rot)
    w = model.apply_inverse_inertia(rot, angular_momentum)
    # ω* R, column by column: ω × α, ω × β, ω × γ.
    w_star_r = np.swapaxes(cross(w[..., None, :], np.swapaxes(rot, -1, -2)), -1, -2)
    rot = gram_schmidt(rot + dt * w_star_r)
    q = align_sign(matrix_to_quat(rot), state.orientation)
    return State(x, q, v, model.apply_inverse_inertia(rot, angular_momentum))


def euler_quat(model, state, dt, forces, force, torque) -> State:
    rot = quat_to_matrix(state.orientation)
    x, v, angular_momentum = _translate_and_kick(model, state, dt, forces, force, torque, rot)
    w = model.apply_inverse_inertia(rot, angular_momentum)
    # Notes: q̇ = ½ (ω, 0) ∘ q, then renormalise (the quaternion form of the repair).
    w_quat = np.concatenate((w, np.zeros_like(w[..., :1])), axis=-1)
    q = quat_normalize(state.orientation + 0.5 * dt * quat_multiply(w_quat, state.orientation))
    return State(x, q, v, model.apply_inverse_inertia(quat_to_matrix(q), angular_momentum))
