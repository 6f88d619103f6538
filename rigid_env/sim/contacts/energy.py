"""Energy guard of a contact step: the contact response never adds energy, at any Δt.

Before the position update, per batch element, the step's energy E = KE + PE_gravity with
the positions it is about to take (x₀ + Δt v, or along the impacts' path, ``restitution``)
must not exceed

    E_ref = max(E_start, E_free),

E_free the energy the step would have without contacts (the forces' own work, e.g. actuation;
a spring's potential is not counted, its work shows in E_free's kinetic energy).
If it would, the element's velocities are scaled by the largest f ∈ [0, 1] that keeps it
(E(f) is a quadratic in f and E(0) = PE(x₀) ≤ E_start, so f exists; scaling keeps every
contact constraint v_n ≥ −d/Δt satisfied). Sources of such a gain: the linearised solve at a
large ω Δt, and a bounce, which moves the body up with its new velocity for the whole step.

After the position update, the separation stage's lift (penetration left by the rotation over
the step) is paid out of the kinetic energy the same way; what cannot be paid is reported
(``ContactReport.unpaid_energy``).

Price: the stored velocities of semi-implicit Euler are step means, so even an exact elastic
bounce ends its step with E above E_start by m g Δt v⁺ (repaid during the flight up); the guard
takes that out, and a ball with ε = 1 loses at most Δt v⁺ of height per bounce — first order in
Δt (``restitution`` alone keeps the modified energy exactly).
"""

from __future__ import annotations

import numpy as np


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


def pay(ke, excess):
    """Velocity factor (N,) that takes ``excess`` (≥ 0) out of the kinetic energy ``ke``, and
    what is left unpaid."""
    keep = np.maximum(ke - excess, 0.0)
    factor = np.where(excess > 0, np.sqrt(keep / np.where(ke > 0, ke, 1.0)), 1.0)
    return factor, np.maximum(excess - ke, 0.0)


__all__ = ["energy", "kinetic", "pay", "potential", "scale_to"]
