"""Accuracy problems: a scene, its initial state and applied load, and an exact reference.

Each problem's ``reference(times)`` returns the exact state at those times as a dict of
``orientation``, ``angular_velocity``, ``position``, ``linear_velocity`` (fields it omits stay at
their initial values), so every integrator is scored the same way against the same truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigid_env import sim

from . import reference, scenes


@dataclass(frozen=True)
class Problem:
    name: str
    build: Callable[[str, float], sim.Scene]  # (integrator, dt) -> Scene
    initial: dict[str, Any]  # keyword arguments of Scene.initial_state
    reference: Callable[[np.ndarray], dict[str, np.ndarray]]
    main_error: str  # "orientation" (rad) or "position" (m): the figure plotted and fitted
    torque: np.ndarray | None = None
    note: str = ""
    tags: tuple[str, ...] = field(default=())


def dzhanibekov() -> Problem:
    """Torque-free asymmetric box spun almost about its intermediate axis: it flips."""
    body = scenes.box()
    moments = np.diag(body.inertia).copy()
    omega = np.array(scenes.DZHANIBEKOV_OMEGA)
    q0 = np.array([0.0, 0.0, 0.0, 1.0])

    def ref(times: np.ndarray) -> dict[str, np.ndarray]:
        q, w = reference.torque_free_exact(moments, q0, omega, times)
        return {"orientation": q, "angular_velocity": w}

    return Problem(
        "dzhanibekov",
        scenes.free_body,
        {"angular_velocity": omega},
        ref,
        "orientation",
        note="L&L §37 Jacobi elliptic solution (checked against DOP853)",
    )


def symmetric_top() -> Problem:
    """Torque-free symmetric top, axis tilted from L: steady precession (closed form)."""
    body = scenes.symmetric_body()
    i_perp, i_axis = body.inertia[0, 0], body.inertia[2, 2]
    omega = np.array([1.0, 0.0, 5.0])
    q0 = np.array([0.0, 0.0, 0.0, 1.0])

    def ref(times: np.ndarray) -> dict[str, np.ndarray]:
        q, w = reference.symmetric_top(i_perp, i_axis, q0, omega, times)
        return {"orientation": q, "angular_velocity": w}

    return Problem(
        "symmetric_top",
        lambda integrator, dt: scenes.free_body(integrator, dt, scenes.symmetric_body()),
        {"angular_velocity": omega},
        ref,
        "orientation",
        note="closed-form precession",
    )


def spin_up() -> Problem:
    """Box at rest under a constant torque along its principal axis y: θ = T t² / 2I."""
    body = scenes.box()
    moments = np.diag(body.inertia).copy()
    torque = np.array([0.0, 0.05, 0.0])

    def ref(times: np.ndarray) -> dict[str, np.ndarray]:
        q, w = reference.spin_up(moments, 1, torque[1], times)
        return {"orientation": q, "angular_velocity": w}

    return Problem(
        "spin_up",
        scenes.free_body,
        {},
        ref,
        "orientation",
        torque=torque,
        note="closed form θ = T t²/2I",
    )


def damped_spring() -> Problem:
    """A ball on a damped zero-length spring, released from rest at x = 0.1 m."""
    mass, stiffness, damping = 1.0, 40.0, 0.4
    x0 = np.array([0.1, 0.0, 0.0])

    def ref(times: np.ndarray) -> dict[str, np.ndarray]:
        x, v = reference.damped_spring(mass, stiffness, damping, x0, np.zeros(3), times)
        return {"position": x, "linear_velocity": v}

    return Problem(
        "damped_spring",
        lambda integrator, dt: scenes.spring(integrator, dt, stiffness, damping, mass),
        {"position": x0},
        ref,
        "position",
        note="closed form, under-damped",
    )


def all_problems() -> list[Problem]:
    return [dzhanibekov(), symmetric_top(), spin_up(), damped_spring()]
