"""Semi-implicit Euler with the gyroscopic term solved implicitly (one Newton step).

Catto, "Numerical Methods", GDC 2015 (as in Bullet's ``computeGyroscopicImpulseImplicit_Body``):
in body axes, solve f(Ω₂) = I (Ω₂ − Ω₁) + h Ω₂ × I Ω₂ = 0 from Ω₁ with Jacobian
J = I + h (Ω₁* I − (I Ω₁)*). Explicit Euler on ω̇ = I⁻¹(−ω × Iω) gains energy and blows up
for elongated bodies at game time steps; the implicit term dissipates a little instead. The
rotation then follows by the exact exponential map q ← exp(h ω) ∘ q. First order.

Worked in principal axes, where I = diag(I₁, I₂, I₃) and
J = [[I₁, hΩ₃(I₃−I₂), hΩ₂(I₃−I₂)], [hΩ₃(I₁−I₃), I₂, hΩ₁(I₁−I₃)], [hΩ₂(I₂−I₁), hΩ₁(I₂−I₁), I₃]],
so the Newton step is a closed-form 3×3 solve on components.
"""

from __future__ import annotations

import numpy as np

from ..rotation import quat_exp, quat_multiply, quat_normalize, rotate, rotate_inverse
from .common import POSITION, VELOCITY, Integrator, kick, start_rotation, translate


def _gyroscopic_newton_step(moments, omega, h):
    """Ω₂ = Ω₁ − J⁻¹ f(Ω₁) with f(Ω₁) = h Ω₁ × IΩ₁, J as in the module docstring."""
    i1, i2, i3 = moments[..., 0], moments[..., 1], moments[..., 2]
    o1, o2, o3 = omega[..., 0], omega[..., 1], omega[..., 2]
    f1 = h * (i3 - i2) * o2 * o3
    f2 = h * (i1 - i3) * o3 * o1
    f3 = h * (i2 - i1) * o1 * o2
    b, c = h * (i3 - i2) * o3, h * (i3 - i2) * o2
    d, g = h * (i1 - i3) * o3, h * (i1 - i3) * o1
    p, r = h * (i2 - i1) * o2, h * (i2 - i1) * o1
    # Cramer's rule with the cofactors of J = [[i1, b, c], [d, i2, g], [p, r, i3]].
    c11, c12, c13 = i2 * i3 - g * r, g * p - d * i3, d * r - i2 * p
    det = i1 * c11 + b * c12 + c * c13
    x1 = (c11 * f1 + (c * r - b * i3) * f2 + (b * g - c * i2) * f3) / det
    x2 = (c12 * f1 + (i1 * i3 - c * p) * f2 + (c * d - i1 * g) * f3) / det
    x3 = (c13 * f1 + (b * p - i1 * r) * f2 + (i1 * i2 - b * d) * f3) / det
    out = np.empty(omega.shape)
    out[..., 0] = o1 - x1
    out[..., 1] = o2 - x2
    out[..., 2] = o3 - x3
    return out


def velocity(ctx) -> None:
    model, dt = ctx.model, ctx.dt
    ctx.v = kick(ctx.v, dt, model.inv_mass[:, None], ctx.force)
    rot = start_rotation(ctx)
    if model.principal_quat is not None:
        rot = rot @ model.principal_axes  # principal axes → world
    omega = rotate_inverse(rot, ctx.w)
    if ctx.torque is not None:
        omega = omega + dt * model.inverse_principal_moments_array * rotate_inverse(rot, ctx.torque)
    omega = _gyroscopic_newton_step(model.principal_moments, omega, dt)
    ctx.w = rotate(rot, omega)


def position(ctx) -> None:
    """x ← x + Δt v; q ← exp(Δt ω) ∘ q (exact exponential map), renormalised."""
    translate(ctx)
    ctx.q = quat_normalize(quat_multiply(quat_exp(ctx.dt * ctx.w), ctx.q))


IMPLICIT_GYRO = Integrator(
    "implicit_gyro",
    ((VELOCITY, velocity), (POSITION, position)),
    order=1,
    symplectic=False,
    summary="semi-implicit Euler, implicit gyroscopic term; never blows up, damps fast spin",
)
RECORDS = (IMPLICIT_GYRO,)
