"""Linearised backward Euler in the spring and damper forces (and the gyroscopic term).

Backward Euler, M (u⁺ − u) = Δt F(x⁺, u⁺), on the generalised velocity u = (v, ω) of each body,
linearised once about the start of the step (Baraff & Witkin, "Large Steps in Cloth
Simulation", SIGGRAPH 1998, eq. 6–7): with a spring's point Jacobian J = [I, −(R r)*]
(ṗ = v + ω × R r), its stiffness K = −∂f/∂p and damping C = −∂f/∂ṗ,

    (M + Δt Jᵀ C J + Δt² Jᵀ K J) Δu = Δt (F − Δt Jᵀ K J u),

plus the gyroscopic Jacobian Δt ((ω*) M − (M ω)*) in the angular block (as ``implicit_gyro``).
One batched 6×6 solve per body; positions then drift with the new velocities (semi-implicit,
so contacts combine with it). Unconditionally stable for linear springs: ``k Δt²/m`` of 10⁶ only
damps the oscillation, where symplectic Euler diverges once ω_n Δt > 2. Gravity, applied
loads and the scene's damping rates stay explicit. First order; it dissipates energy at the
rate of the stiffest spring the step cannot resolve.
"""

from __future__ import annotations

import numpy as np

from ..rotation import quat_exp, quat_multiply, quat_rotate, skew
from .common import POSITION, VELOCITY, Integrator, start_rotation, translate


def _spring_matrices(model, x, q):
    """Per body: Σ Jᵀ K J and Σ Jᵀ C J over its springs, (…, n, 6, 6) each."""
    s = model.springs
    body = np.array([sp.body for sp in s])
    anchor = np.stack([sp.anchor for sp in s])
    attach = np.stack([sp.attach for sp in s])
    k = np.array([sp.stiffness for sp in s])[:, None, None]
    c = np.array([sp.damping for sp in s])[:, None, None]
    rest = np.array([sp.rest_length for sp in s])
    arm = quat_rotate(q[..., body, :], attach)
    d = x[..., body, :] + arm - anchor
    length = np.linalg.norm(d, axis=-1)
    unit = d / np.where(length > 0, length, 1.0)[..., None]
    along = unit[..., :, None] * unit[..., None, :]
    eye = np.eye(3)
    # A stretched spring with rest length is stiff along d̂ (k) and, through its tension,
    # across it (k (1 − L₀/|d|)); the transverse part is dropped when compressed (it would be
    # negative and destabilise the solve), the usual choice in cloth solvers.
    ratio = np.where(length > 0, rest / np.where(length > 0, length, 1.0), 0.0)
    transverse = np.maximum(1.0 - ratio, 0.0)[..., None, None]
    has_rest = (rest > 0)[:, None, None]
    stiff = k * np.where(has_rest, along + transverse * (eye - along), eye)
    damp = c * np.where(has_rest, along, eye)
    jac = np.concatenate((np.broadcast_to(eye, arm.shape + (3,)), -skew(arm)), axis=-1)
    incidence = np.zeros((len(s), model.n_bodies))
    incidence[np.arange(len(s)), body] = 1.0
    jkj = np.einsum("...sai,...sab,...sbj,sn->...nij", jac, stiff, jac, incidence)
    jcj = np.einsum("...sai,...sab,...sbj,sn->...nij", jac, damp, jac, incidence)
    return jkj, jcj


def velocity(ctx) -> None:
    model, dt = ctx.model, ctx.dt
    x, q, v, w = ctx.x, ctx.q, ctx.v, ctx.w
    f, t = ctx.force, ctx.torque
    rot = start_rotation(ctx)
    inertia = rot @ model.inertia @ np.swapaxes(rot, -1, -2)  # M = R M0 Rᵀ
    momentum = np.einsum("...ij,...j->...i", inertia, w)
    gyro = -np.cross(w, momentum)
    lin = np.zeros_like(v) if f is None else np.broadcast_to(f, v.shape)
    ang = gyro if t is None else gyro + t
    u = np.concatenate((v, w), axis=-1)
    rhs = dt * np.concatenate((lin, ang), axis=-1)
    system = np.zeros((*v.shape[:-1], 6, 6))
    system[..., :3, :3] = model.mass[:, None, None] * np.eye(3)
    system[..., 3:, 3:] = inertia + dt * (skew(w) @ inertia - skew(momentum))
    if model.springs:
        jkj, jcj = _spring_matrices(model, x, q)
        system = system + dt * jcj + dt * dt * jkj
        rhs = rhs - dt * dt * np.einsum("...ij,...j->...i", jkj, u)
    u = u + np.linalg.solve(system, rhs[..., None])[..., 0]
    ctx.v, ctx.w = np.array(u[..., :3]), np.array(u[..., 3:])


def position(ctx) -> None:
    """x ← x + Δt v; q ← exp(Δt ω) ∘ q."""
    translate(ctx)
    ctx.q = quat_multiply(quat_exp(ctx.dt * ctx.w), ctx.q)


IMPLICIT = Integrator(
    "implicit",
    ((VELOCITY, velocity), (POSITION, position)),
    order=1,
    symplectic=False,
    summary="linearised backward Euler in springs, dampers and gyroscopic term; stiff springs",
)
RECORDS = (IMPLICIT,)
