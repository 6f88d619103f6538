"""Classical fourth-order Runge–Kutta on the full state (x, q, v, L).

Forces are re-evaluated at each stage (the first from the step's force stages); the applied
force and torque are held over the step. The quaternion is normalised where a rotation is needed
and once at the end: RK4 preserves neither |q| nor energy exactly, but its errors are O(Δt⁴).
"""

from __future__ import annotations

import numpy as np

from ..rotation import quat_multiply, quat_normalize, quat_to_matrix
from .common import INTEGRATE, Integrator


def integrate(ctx) -> None:
    model, dt = ctx.model, ctx.dt
    inv_m = model.inv_mass[:, None]
    x0, q0, v0, w0 = ctx.x, ctx.q, ctx.v, ctx.w
    l0 = model.apply_inertia(quat_to_matrix(q0), w0)
    zero = np.zeros_like(x0)

    def derivative(x, q, v, angular_momentum, wrench=None):
        qn = quat_normalize(q)
        w = model.apply_inverse_inertia(quat_to_matrix(qn), angular_momentum)
        f, t = ctx.wrench_at(x, qn, v, w) if wrench is None else wrench
        w_quat = np.concatenate((w, np.zeros_like(w[..., :1])), axis=-1)
        qdot = 0.5 * quat_multiply(w_quat, qn)
        vdot = zero if f is None else f * inv_m
        ldot = zero if t is None else t + zero
        return v, qdot, vdot, ldot

    y0 = (x0, q0, v0, l0)
    k1 = derivative(*y0, wrench=(ctx.force, ctx.torque))  # the force stages' wrench at y0
    k2 = derivative(*(y + 0.5 * dt * k for y, k in zip(y0, k1, strict=True)))
    k3 = derivative(*(y + 0.5 * dt * k for y, k in zip(y0, k2, strict=True)))
    k4 = derivative(*(y + dt * k for y, k in zip(y0, k3, strict=True)))
    x, q, v, angular_momentum = (
        y + dt / 6 * (a + 2 * b + 2 * c + d)
        for y, a, b, c, d in zip(y0, k1, k2, k3, k4, strict=True)
    )
    q = quat_normalize(q)
    ctx.x, ctx.q, ctx.v = x, q, v
    ctx.w = model.apply_inverse_inertia(quat_to_matrix(q), angular_momentum)


RK4 = Integrator(
    "rk4",
    ((INTEGRATE, integrate),),
    order=4,
    symplectic=False,
    summary="classical Runge–Kutta, 4 force evaluations; drift O(Δt⁴), nothing kept exactly",
)
RECORDS = (RK4,)
