"""Semi-implicit Euler with the gyroscopic term solved implicitly (one Newton step).

Catto, "Numerical Methods", GDC 2015 (as in Bullet's ``computeGyroscopicImpulseImplicit_Body``):
in body axes, solve f(Ω₂) = I (Ω₂ − Ω₁) + h Ω₂ × I Ω₂ = 0 from Ω₁ with Jacobian
J = I + h (Ω₁* I − (I Ω₁)*). Explicit Euler on ω̇ = I⁻¹(−ω × Iω) gains energy and blows up
for elongated bodies at game time steps; the implicit term dissipates a little instead. The
rotation then follows by the exact exponential map q ← exp(h ω) ∘ q. First order.
"""

from __future__ import annotations

import numpy as np

from ..rotation import (
    cross,
    matvec,
    quat_exp,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
    rotate,
    rotate_inverse,
    skew,
)
from ..state import State
from .common import kick, wrench


def _solve3(rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve J x = rhs for stacks of 3×3 J by Cramer's rule (J⁻¹ = adj(J)/det J)."""
    r0, r1, r2 = rows[..., 0, :], rows[..., 1, :], rows[..., 2, :]
    c12, c20, c01 = cross(r1, r2), cross(r2, r0), cross(r0, r1)
    det = np.sum(r0 * c12, axis=-1, keepdims=True)
    return (c12 * rhs[..., 0:1] + c20 * rhs[..., 1:2] + c01 * rhs[..., 2:3]) / det


def implicit_gyro(model, state, dt, forces, force, torque) -> State:
    x, q, v, w = state.arrays()
    f, t = wrench(forces, x, q, v, w, force, torque)
    v = kick(v, dt, model.inv_mass[:, None], f)
    rot = quat_to_matrix(q)
    if t is not None:
        w = w + dt * model.apply_inverse_inertia(rot, t)
    omega = rotate_inverse(rot, w)
    inertia = model.inertia
    i_omega = matvec(inertia, omega)
    residual = dt * cross(omega, i_omega)
    # J = I + h (Ω* I − (IΩ)*), built row by row through Ω* I = Ω × (columns of I).
    omega_star_i = np.swapaxes(cross(omega[..., None, :], np.swapaxes(inertia, -1, -2)), -1, -2)
    jac = inertia + dt * (omega_star_i - skew(i_omega))
    omega = omega - _solve3(jac, residual)
    w = rotate(rot, omega)
    q = quat_normalize(quat_multiply(quat_exp(dt * w), q))
    return State(x + dt * v, q, v, w)
