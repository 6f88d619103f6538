"""Pieces the integrators share: force evaluation and the momentum ↔ velocity maps."""

from __future__ import annotations

import numpy as np


def wrench(forces, x, q, v, w, force, torque):
    """Total (F, T) at a state: the scene's force terms plus the applied actuation.

    ``forces`` is ``None`` for a scene without force terms; either result may be ``None``
    (nothing acts), which lets a free body skip the arithmetic entirely.
    """
    if forces is None:
        return force, torque
    return forces(x, q, v, w, force, torque)


def kick(velocity, dt, inverse, load):
    """``velocity + dt · inverse · load``, or ``velocity`` when nothing acts."""
    if load is None:
        return velocity
    return velocity + dt * inverse * load


def align_sign(q_new: np.ndarray, q_old: np.ndarray) -> np.ndarray:
    """Pick the sign of ``q_new`` nearest ``q_old`` so trajectories are continuous (q ≡ −q)."""
    return q_new * np.where(np.sum(q_new * q_old, axis=-1, keepdims=True) < 0, -1.0, 1.0)
