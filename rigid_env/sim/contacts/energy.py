"""Energy guard of a contact step: the contacts add no energy, the loads do their full work.

The invariant. Per batch element, with E = KE + PE_gravity (a spring's potential is not
counted; its force is one of the loads below), u₀ the velocities the step starts with, u₁ those
after the velocity update (the step without contacts), u those the step ends with and

    W(u) = Δt Σ_b (F_b · v_b + τ_b · ω_b),

the work along the step's displacement Δt u of the velocity-independent loads other than
gravity (applied forces, world torques, body torques turned into the world at q₀, springs at
the start pose), the guard enforces

    E_end − W(u) ≤ max(E_start, E_free − W(u₁)),            (1)

E_free the energy of the step without contacts (positions x₀ + Δt u₁). In words: the step ends
with no more energy than it started with plus what the loads put in along the motion it
actually made; the contacts add none. Without loads W = 0 and (1) is E_end ≤ max(E_start,
E_free): no contact response gains energy (any ε ≤ 1, any Δt up to 1 s). The maximum keeps what
the contact-free step itself gains (an integrator's own error), not what it loses: a resting
body's free step falls and loses ½ m g² Δt² (semi-implicit Euler), which must not bound the
work of a push that stays below it.

Why W at the end velocities: semi-implicit Euler moves the bodies by Δt u, so W(u) is a
constant load's exact work along the step's discrete displacement, and the velocity update's
own kinetic energy change from a load F is F·Δt (v₀ + v₁)/2 = W − ½ F² Δt²/m: (1) holds with a
margin of ½ F² Δt²/m per pushed body, so rounding never scales a push away.

How: before the position update, if (1) fails, the element's velocities are scaled by the
largest f ∈ [0, 1] that keeps it: E(f) − W(f u) = PE(x₀) + f² KE + f (lin − W(u)) is a
quadratic in f (``scale_to``), and E(0) = PE(x₀) ≤ E_start. Scaling keeps every contact
constraint v_n ≥ −d/Δt. Sources of such a gain: the linearised solve at a large ω Δt, and a
bounce, which moves the body up with its new velocity for the whole step. (1) is checked with
the end positions separated from the ground (the overlap the rotation over the step leaves);
the separation after the position update (``SeparateContacts``) then lifts the bodies and pays
the lift's potential energy out of the kinetic energy, keeping E − W unchanged (``pay``), so
the step ends at or below the bound; what cannot be paid is reported
(``ContactReport.unpaid_energy``).

Price: the stored velocities of semi-implicit Euler are step means, so even an exact elastic
bounce ends its step with E above E_start by m g Δt v⁺ (repaid during the flight up); the guard
takes that out, and a ball with ε = 1 loses at most Δt v⁺ of height per bounce — first order in
Δt (``restitution`` alone keeps the modified energy exactly).

What the contacts removed (``ContactReport.energy_removed``, per element): the work of the
contact impulses against the bodies at the step's mean velocity (the trapezoid rule), less the
potential energy the separation's lift added,

    removed = −Σ_b (u_b − u₁_b)ᵀ M_b (u₀_b + u_b) / 2 − ΔPE_separation,

M_b = diag(m_b I, R₀ M0_b R₀ᵀ). It is exact bookkeeping: ½ uᵀMu − ½ u₀ᵀMu₀ = (u₁ − u₀)ᵀ M
(u₀ + u)/2 − removed − ΔPE_separation. It is 0 for a body at rest, pushed on frictionless
ground, or in flight; the friction work for a sliding body; the kinetic energy lost in an
inelastic impact; and the guard's price above.
"""

from __future__ import annotations

import numpy as np

from ..rotation import quat_rotate


def energy(model, x, q_rot, u):
    """KE + gravity PE per element (N,): x (N, n, 3), rotations (N, n, 3, 3), u (N, n, 6)."""
    return kinetic(model, q_rot, u) + potential(model, x)


def kinetic(model, rot, u):
    spin = model.apply_inertia(rot, u[..., 3:])
    lin = 0.5 * model.mass * np.sum(u[..., :3] ** 2, axis=-1)
    return np.sum(lin + 0.5 * np.sum(u[..., 3:] * spin, axis=-1), axis=-1)


def potential(model, x):
    if model.gravity is None:
        return np.zeros(len(x))
    return -np.sum(model.mass * (x @ model.gravity), axis=-1)


def scale_to(ke, lin, room):
    """Largest f ∈ [0, 1] with f² ke + f lin ≤ room (room ≥ 0): the energy of the step with
    its velocities scaled by f, ``ke`` their kinetic energy and ``lin`` the potential energy
    they move the positions through (E(f) − PE(x₀) = f² ke + f lin)."""
    room = np.maximum(room, 0.0)
    fits = ke + lin <= room * (1 + 1e-12) + 1e-300
    disc = np.sqrt(np.maximum(lin * lin + 4 * ke * room, 0.0))
    root = np.where(ke > 0, (-lin + disc) / np.where(ke > 0, 2 * ke, 1.0), 1.0)
    return np.where(fits, 1.0, np.clip(root, 0.0, 1.0))


def load_rates(ctx, idx):
    """The loads of ``W`` for the engaged elements ``idx``: world force and torque per body,
    each (M, n, 3), at the start pose (the applied force and torque, the body torque turned at
    q₀, the springs' elastic part); None when nothing but gravity and damping acts (loads of
    zero included)."""
    from ..forces import Springs

    n = ctx.model.n_bodies
    start = ctx.start
    shape = start.position.shape
    force = torque = None
    if ctx.applied_force is not None:
        force = np.broadcast_to(ctx.applied_force, shape)
    if ctx.applied_torque is not None:
        torque = np.broadcast_to(ctx.applied_torque, shape)
    if ctx.body_torque is not None:
        turned = quat_rotate(start.orientation, np.broadcast_to(ctx.body_torque, shape))
        torque = turned if torque is None else torque + turned
    for term in ctx.forces:
        if isinstance(term, Springs):
            zero = np.zeros(shape)
            f, t = term.wrench(start.position, start.orientation, zero, zero)
            force = f if force is None else force + f
            torque = t if torque is None else torque + t
    if (
        not np.any(force)
        and not np.any(torque)
        and not any(isinstance(term, Springs) for term in ctx.forces)
    ):
        return None  # zero loads (as the compiled step sees an absent one)
    force = np.zeros(shape) if force is None else force
    torque = np.zeros(shape) if torque is None else torque
    return force.reshape(-1, n, 3)[idx], torque.reshape(-1, n, 3)[idx]


def work(rates, u, dt):
    """``W(u)`` per element (M,): Δt Σ_b (F_b·v_b + τ_b·ω_b) of ``load_rates`` over u (M, n, 6);
    zeros without loads."""
    if rates is None:
        return np.zeros(len(u))
    force, torque = rates
    return dt * np.sum(np.sum(force * u[..., :3] + torque * u[..., 3:], axis=-1), axis=-1)


def contact_work(model, rot0, u0, u1, u):
    """−Σ_b (u_b − u₁_b)ᵀ M_b (u₀_b + u_b)/2 per element: the work the contacts took out at the
    step's mean velocity (``removed`` above, before the separation's share)."""
    du, mean = u - u1, 0.5 * (u0 + u)
    lin = model.mass * np.sum(du[..., :3] * mean[..., :3], axis=-1)
    ang = np.sum(du[..., 3:] * model.apply_inertia(rot0, mean[..., 3:]), axis=-1)
    return -np.sum(lin + ang, axis=-1)


def pay(ke, excess, work=None, rates=None):
    """Velocity factor (N,) that takes ``excess`` (≥ 0) out of the kinetic energy ``ke``, and
    what is left unpaid. With loads (``rates``, and ``work`` = W(u) at f = 1) the factor f keeps
    E − W unchanged instead, f² ke − f W = ke − W − excess (the larger root); where no f ∈ [0, 1]
    does (a body pushed from rest, W ≥ 2 ke), nothing is paid: the guard already admitted the
    lifted positions (invariant (1))."""
    if rates is None:
        keep = np.maximum(ke - excess, 0.0)
        factor = np.where(excess > 0, np.sqrt(keep / np.where(ke > 0, ke, 1.0)), 1.0)
        return factor, np.maximum(excess - ke, 0.0)
    disc = work * work + 4 * ke * (ke - work - excess)
    safe = np.where(ke > 0, 2 * ke, 1.0)
    root = np.where(disc >= 0, (work + np.sqrt(np.maximum(disc, 0.0))) / safe, 1.0)
    factor = np.where((excess > 0) & (ke > 0), np.clip(root, 0.0, 1.0), 1.0)
    return factor, np.zeros(len(ke))


__all__ = [
    "contact_work",
    "energy",
    "kinetic",
    "load_rates",
    "pay",
    "potential",
    "scale_to",
    "work",
]
