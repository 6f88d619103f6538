"""Ready-made scenes shared by the benchmarks and the environments."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .body import Body
from .contacts import SolverSettings
from .model import Ground
from .rotation import quat_exp
from .scene import CONTACT_INTEGRATOR, Scene
from .state import State

LANDING_HALF_EXTENTS = (0.1, 0.15, 0.2)


class InitialState(Protocol):
    """The start-state factory a ready-made scene comes with."""

    def __call__(
        self, batch_shape: int | tuple[int, ...] = (), rng: np.random.Generator | None = None
    ) -> State: ...


def landing_scene(
    integrator: str = CONTACT_INTEGRATOR,
    dt: float = 1 / 240,
    restitution: float = 0.3,
    friction: float = 0.5,
    contact_solver: SolverSettings | None = None,
) -> tuple[Scene, InitialState]:
    """A 1 kg box (half extents 0.1, 0.15, 0.2 m) thrown at the ground under gravity
    (``contact_solver``: the scene's, default ``SolverSettings()``).

    Returns ``(scene, initial_state)`` where ``initial_state(batch_shape=(), rng=None)`` drops
    the box from 1 m with a tilt and a spin (random per batch element when ``rng`` is given,
    a fixed tilt of 0.3 rad and spin (1, 2, 3) rad/s otherwise).
    """
    box = Body.box(LANDING_HALF_EXTENTS, 1.0)
    scene = Scene(
        box,
        dt,
        integrator=integrator,
        gravity=(0.0, 0.0, -9.81),
        ground=Ground(restitution=restitution, friction=friction),
        contact_solver=contact_solver,
    )

    def initial_state(
        batch_shape: int | tuple[int, ...] = (), rng: np.random.Generator | None = None
    ) -> State:
        batch_shape = tuple(np.atleast_1d(batch_shape)) if np.ndim(batch_shape) else ()
        if rng is None:
            tilt = quat_exp(np.array([0.3, 0.2, 0.0]))
            spin = np.array([1.0, 2.0, 3.0])
        else:
            tilt = quat_exp(rng.uniform(-0.5, 0.5, (*batch_shape, 1, 3)))
            spin = rng.uniform(-3.0, 3.0, (*batch_shape, 1, 3))
        return scene.initial_state(
            position=(0.0, 0.0, 1.0),
            orientation=tilt,
            angular_velocity=spin,
            batch_shape=batch_shape,
        )

    return scene, initial_state
