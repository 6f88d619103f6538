"""Contact scenes for the stability matrix: ground impacts, body–body impacts, stacks.

Each factory returns ``(scene, state, depth)`` where ``depth(state)`` is the deepest
penetration in the state (m, ≥ 0 when overlapping, per batch element) and, for the ground
cases, ``below(state)`` tells whether a body ended under the ground (tunnelled). Scenes need a
contact-capable integrator (``rigid_env.sim.CONTACT_CAPABLE``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rigid_env import sim
from rigid_env.sim.contacts.pairs import sphere_box
from rigid_env.sim.rotation import quat_exp, quat_rotate

GRAVITY = (0.0, 0.0, -9.81)
GROUND = sim.Ground(restitution=0.3, friction=0.5)  # the landing scene's
BODY_MATERIAL = sim.Material(restitution=0.5, friction=0.0)

# (scene, initial state, depth(state)): what every factory returns.
Case = tuple[sim.Scene, sim.State, Callable[[sim.State], np.ndarray]]


def compatible() -> tuple[str, ...]:
    from rigid_env.sim import CONTACT_CAPABLE

    return CONTACT_CAPABLE


def lowest_point(box: sim.Body, state: sim.State) -> np.ndarray:
    """Height of each body's lowest corner, (*batch, n)."""
    corners = quat_rotate(state.orientation[..., None, :], box.shape.vertices)
    return state.position[..., 2] + np.min(corners[..., 2], axis=-1)


def ground_impact(integrator: str, dt: float, speed: float) -> Case:
    """The landing box thrown at the ground at ``speed`` m/s from 0.5 m, tilted, spinning."""
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    scene = sim.Scene(box, dt, integrator=integrator, gravity=GRAVITY, ground=GROUND)
    state = scene.initial_state(
        position=(0.0, 0.0, 0.5),
        orientation=quat_exp(np.array([0.3, 0.2, 0.0])),
        linear_velocity=(0.0, 0.0, -speed),
        angular_velocity=(1.0, 2.0, 3.0),
    )

    def depth(s: sim.State) -> np.ndarray:
        return np.maximum(-lowest_point(box, s)[..., 0], 0.0)

    return scene, state, depth


def two_spheres(integrator: str, dt: float, ratio: float, speed: float = 1.0) -> Case:
    """A 1 kg sphere hits a sphere ``ratio`` times heavier, at rest, head on, in space."""
    light, heavy = sim.Body.sphere(0.1, 1.0), sim.Body.sphere(0.1, ratio)
    scene = sim.Scene([light, heavy], dt, integrator=integrator, contacts=BODY_MATERIAL)
    state = scene.initial_state(
        position=[(-0.3, 0.0, 0.0), (0.0, 0.0, 0.0)],
        linear_velocity=[(speed, 0.0, 0.0), (0.0, 0.0, 0.0)],
    )

    def depth(s: sim.State) -> np.ndarray:
        gap = np.linalg.norm(s.position[..., 0, :] - s.position[..., 1, :], axis=-1) - 0.2
        return np.maximum(-gap, 0.0)

    return scene, state, depth


def sphere_and_box(integrator: str, dt: float, ratio: float, speed: float = 1.0) -> Case:
    """A box ``ratio`` times heavier than a 1 kg sphere hits it off-centre, in space."""
    ball, box = sim.Body.sphere(0.1, 1.0), sim.Body.box((0.2, 0.2, 0.2), ratio)
    scene = sim.Scene([ball, box], dt, integrator=integrator, contacts=BODY_MATERIAL)
    state = scene.initial_state(
        position=[(0.0, 0.05, 0.0), (-0.5, 0.0, 0.0)],
        linear_velocity=[(0.0, 0.0, 0.0), (speed, 0.0, 0.0)],
    )
    detect = sphere_box([0.1], np.array([[0.2, 0.2, 0.2]]))

    def depth(s: sim.State) -> np.ndarray:
        x, q = s.position, s.orientation
        gap = detect(x[..., :1, :], q[..., :1, :], x[..., 1:, :], q[..., 1:, :])[3]
        return np.maximum(-gap[..., 0], 0.0)

    return scene, state, depth


def stack(integrator: str, dt: float, ratio: float, count: int) -> Case:
    """``count`` unit cubes (0.2 m) resting on each other on the ground, each ``ratio``^(1/(count−1))
    times heavier than the one below (the top one ``ratio`` times the bottom one)."""
    masses = ratio ** (np.arange(count) / max(count - 1, 1))
    boxes = [sim.Body.box((0.1, 0.1, 0.1), float(m)) for m in masses]
    scene = sim.Scene(
        boxes, dt, integrator=integrator, gravity=GRAVITY, ground=GROUND, contacts=GROUND
    )
    heights = 0.1 + 0.2 * np.arange(count)
    state = scene.initial_state(position=np.stack([np.zeros(count), np.zeros(count), heights], 1))

    def depth(s: sim.State) -> np.ndarray:
        z = s.position[..., 2]
        gaps = np.concatenate([z[..., :1] - 0.1, np.diff(z, axis=-1) - 0.2], axis=-1)
        return np.maximum(-np.min(gaps, axis=-1), 0.0)

    return scene, state, depth
