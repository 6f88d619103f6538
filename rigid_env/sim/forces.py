"""Force terms. A scene gets only the terms it was given; each maps a state to (force, torque).

Every term is ``term(x, q, v, w) -> (F, T)`` on world-frame arrays ``(*batch, n, 3)``, with
``None`` for a component it does not produce, so integrators can evaluate forces at their own
intermediate states (RK4 stages, splitting half steps).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .model import Model
from .rotation import cross, quat_rotate, quat_to_matrix

Vec = np.ndarray | None
Term = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[Vec, Vec]]


def gravity(model: Model) -> Term:
    weight = model.mass[:, None] * model.gravity  # (n, 3), broadcast over the batch

    def term(x, q, v, w):
        return weight, None

    return term


def damping(model: Model) -> Term:
    """Linear and angular damping as decay rates (1/s): ṗ = −γ_v p, L̇ = −γ_ω L."""
    gv, gw = model.linear_damping, model.angular_damping
    m = model.mass[:, None]

    def term(x, q, v, w):
        force = -gv * m * v if gv else None
        torque = -gw * model.apply_inertia(quat_to_matrix(q), w) if gw else None
        return force, torque

    return term


def springs(model: Model) -> Term:
    """Sum of the springs' forces and torques ``(R r) × F`` per body (notes: T = (R r) × F)."""
    s = model.springs
    body = np.array([sp.body for sp in s])
    anchor = np.stack([sp.anchor for sp in s])  # (s, 3)
    attach = np.stack([sp.attach for sp in s])
    k = np.array([sp.stiffness for sp in s])[:, None]
    c = np.array([sp.damping for sp in s])[:, None]
    rest = np.array([sp.rest_length for sp in s])[:, None]
    has_rest = rest > 0
    # Spring → body incidence: sums the springs on each body without a Python loop or np.add.at.
    incidence = np.zeros((len(s), model.n_bodies))
    incidence[np.arange(len(s)), body] = 1.0

    def term(x, q, v, w):
        arm = quat_rotate(q[..., body, :], attach)  # R r, (*batch, s, 3)
        d = x[..., body, :] + arm - anchor
        pdot = v[..., body, :] + cross(w[..., body, :], arm)
        length = np.linalg.norm(d, axis=-1, keepdims=True)
        unit = d / np.where(length > 0, length, 1.0)
        stretched = np.where(has_rest, k * (length - rest) * unit, k * d)
        damped = np.where(
            has_rest, c * np.sum(pdot * unit, axis=-1, keepdims=True) * unit, c * pdot
        )
        f = -(stretched + damped)
        t = cross(arm, f)
        return (
            np.einsum("...si,sn->...ni", f, incidence),
            np.einsum("...si,sn->...ni", t, incidence),
        )

    return term


def build_terms(model: Model) -> tuple[tuple[str, Term], ...]:
    """The force stages a model needs, in order; a free body in space gets none."""
    terms = []
    if model.gravity is not None and np.any(model.gravity):
        terms.append(("gravity", gravity(model)))
    if model.linear_damping or model.angular_damping:
        terms.append(("damping", damping(model)))
    if model.springs:
        terms.append(("springs", springs(model)))
    return tuple(terms)


def combine(terms: tuple[tuple[str, Term], ...], velocity_dependent: bool = True):
    """One function ``(x, q, v, w, F_applied, T_applied) -> (F, T)`` summing the terms.

    ``wrench.velocity_dependent`` tells integrators whether the forces depend on v or ω (damping),
    which a symmetric splitting must treat with a corrected final half kick to stay 2nd order.
    """
    fns = tuple(fn for _, fn in terms)

    def wrench(x, q, v, w, force, torque):
        for fn in fns:
            f, t = fn(x, q, v, w)
            if f is not None:
                force = f if force is None else force + f
            if t is not None:
                torque = t if torque is None else torque + t
        return force, torque

    wrench.velocity_dependent = velocity_dependent
    return wrench


def is_velocity_dependent(model: Model) -> bool:
    return bool(
        model.linear_damping or model.angular_damping or any(s.damping for s in model.springs)
    )
