r"""``RigidEnv/Reorient-v0``: turn a tumbling satellite to a target attitude and hold it at rest.

## Description

A rigid body with three distinct principal moments of inertia (by default a uniform
0.6 m × 0.4 m × 0.2 m box of 12 kg, principal moments 0.2, 0.4, 0.52 kg m²) floats in space: no
gravity, no ground, no contacts, so the scene is a free body (``scene.stages == ("integrate",)``).
It starts at a uniformly random orientation, spinning. Without control it keeps its angular
momentum and energy exactly but its attitude wanders, and a spin about the intermediate axis
(body *y* by default) flips over periodically (the Dzhanibekov or tennis-racket effect). The
agent fires three body-fixed torques (think reaction wheels or thrusters) to bring the body to a
target orientation and hold it there at rest.

## Action Space

``Box(-1, 1, (3,), float32)``: the torque about the body's own axes, as a fraction of
``max_torque``. Values outside [-1, 1] are clipped; NaN, infinity or a wrong shape raise
``ValueError`` and leave the env unchanged. The torque is body-fixed: it is rotated into the
world at every physics step.

| Num | Action                     | Min | Max | Unit              |
|-----|----------------------------|-----|-----|-------------------|
| 0   | torque about body x        | -1  | 1   | ``max_torque`` N m |
| 1   | torque about body y        | -1  | 1   | ``max_torque`` N m |
| 2   | torque about body z        | -1  | 1   | ``max_torque`` N m |

## Observation Space

``Box((10,), float32)``. The error rotation ``q_err = q_target⁻¹ ∘ q`` (Hamilton product,
quaternions ``(x, y, z, w)``, ``q`` maps body to world) is the rotation from the target body
frame to the current one, expressed in body axes; its sign is chosen with ``w >= 0`` so it is
continuous near the goal, where it tends to ``(0, 0, 0, 1)``. For a small error its vector part
is half the rotation vector that the body must undo, in the body axes the torques act on.

| Num | Observation                                   | Min  | Max  | Unit              |
|-----|-----------------------------------------------|------|------|-------------------|
| 0   | q_err x  (= sin(θ/2) u_x)                      | -1   | 1    |                   |
| 1   | q_err y                                       | -1   | 1    |                   |
| 2   | q_err z                                       | -1   | 1    |                   |
| 3   | q_err w  (= cos(θ/2), θ the angle error)       | 0    | 1    |                   |
| 4   | body angular velocity Ω_x / ``spin_scale``     | -5   | 5    | (rad/s)/(rad/s)   |
| 5   | body angular velocity Ω_y / ``spin_scale``     | -5   | 5    | (rad/s)/(rad/s)   |
| 6   | body angular velocity Ω_z / ``spin_scale``     | -5   | 5    | (rad/s)/(rad/s)   |
| 7   | previous action, x                            | -1   | 1    | ``max_torque``    |
| 8   | previous action, y                            | -1   | 1    | ``max_torque``    |
| 9   | previous action, z                            | -1   | 1    | ``max_torque``    |

Physics does not bound the spin (torque can spin the body up without limit), so its observation
is clipped to ±5, i.e. five times the fastest initial spin with the default ``spin_scale``; it
starts within ±1 and a sensible policy keeps it there. ``info["spin"]`` is never clipped.

## Rewards

Per step, with θ the angle error (rad), Ω the body angular velocity (rad/s), a the action:

| Term        | Value                                      | Default weight      |
|-------------|--------------------------------------------|---------------------|
| attitude    | ``-angle_weight · θ / π``                  | ``angle_weight=1``  |
| spin        | ``-spin_weight · |Ω| / spin_scale``        | ``spin_weight=0.1`` |
| effort      | ``-action_weight · |a|² / 3``              | ``action_weight=0.01`` |
| success     | ``+success_bonus`` on every step ``is_success`` holds | ``success_bonus=10`` |

The attitude and spin terms are linear (not squared) so their pull does not fade near the goal;
every term but the bonus is ≤ 0, so with ``terminate_on_success=True`` reaching the goal sooner is
always better, and the bonus is paid once.

## Success

The body is *within* the goal when ``θ < angle_threshold`` (0.1 rad ≈ 5.7°) and
``|Ω| < spin_threshold`` (0.05 rad/s). ``is_success`` becomes ``True`` once it has stayed within
for ``hold_time`` (1 s, i.e. 20 consecutive steps), and stays ``True`` while it remains within.

## Starting State

Orientation uniform on SO(3). Angular velocity of magnitude uniform in ``spin_range``
(0 to 2 rad/s: from a slow drift to a fast tumble). Its direction is uniform on the sphere,
except in a fraction ``tumble_fraction`` (1/4) of the episodes where it lies within about
``tumble_spread`` (0.05 rad) of the intermediate principal axis: the unstable tumble. The target
orientation is uniform on SO(3) per episode, or fixed by ``target_orientation``.

## Episode End

1. Termination: ``is_success`` (only with ``terminate_on_success=True``, the default).
2. Truncation: ``max_episode_steps`` = 200 steps (10 s with the default 0.05 s action period).

## Info

Every ``reset`` and ``step`` returns ``angle_error`` (θ, rad), ``spin`` (|Ω|, rad/s), ``energy``
(kinetic, J), ``angular_momentum`` (world frame, (3,), kg m²/s, a fresh array) and ``is_success``
(``bool``).

## Arguments

``gymnasium.make("RigidEnv/Reorient-v0", **kwargs)`` and
``gymnasium.make_vec("RigidEnv/Reorient-v0", num_envs=N, vectorization_mode="vector_entry_point",
**kwargs)`` take:

| Argument              | Default               | Meaning                                                   |
|-----------------------|-----------------------|-----------------------------------------------------------|
| ``body``              | ``None``              | a ``rigid_env.sim.Body`` (box, sphere, polyhedron)        |
| ``half_extents``      | ``(0.3, 0.2, 0.1)``   | of the default box, m (only without ``body``)             |
| ``mass``              | ``12.0``              | of the default box, kg (only without ``body``)            |
| ``inertia``           | ``None``              | override: 3 principal moments or a 3×3 tensor, kg m²      |
| ``integrator``        | ``"splitting"``       | one of ``rigid_env.sim.INTEGRATORS``                      |
| ``dt``                | ``0.025``             | physics time step, s                                      |
| ``frame_skip``        | ``2``                 | physics steps per action                                  |
| ``max_torque``        | ``1.0``               | N m at action 1; a number or one per body axis            |
| ``spin_range``        | ``(0.0, 2.0)``        | initial angular speed range, rad/s                        |
| ``tumble_fraction``   | ``0.25``              | share of episodes spun about the intermediate axis        |
| ``tumble_spread``     | ``0.05``              | size of the perturbation off that axis                    |
| ``target_orientation``| ``None``              | ``None``: random per episode; or a quaternion (x, y, z, w) |
| ``angle_threshold``   | ``0.1``               | success angle error, rad                                  |
| ``spin_threshold``    | ``0.05``              | success spin, rad/s                                       |
| ``hold_time``         | ``1.0``               | time to stay within both thresholds, s                    |
| ``terminate_on_success`` | ``True``           | end the episode at success                                |
| ``angle_weight``, ``spin_weight``, ``action_weight``, ``success_bonus`` | 1, 0.1, 0.01, 10 | reward terms (table above) |
| ``spin_scale``        | ``None``              | observation scale of Ω, rad/s; ``None``: ``spin_range`` high (or 1 rad/s) |
| ``render_mode``       | ``None``              | ``"human"`` or ``"rgb_array"`` (vector env: ``"rgb_array"``) |

Bad values raise ``ValueError`` naming the argument. The vector env also takes ``num_envs`` and
``max_episode_steps``; seeded with ``s`` its sub-env ``i`` uses seed ``s + i`` and equals a single
env seeded ``s + i`` step for step (Gymnasium ``NEXT_STEP`` autoreset). ``set_state(orientation=,
angular_velocity=, target=)`` on the unwrapped env builds a state by hand (angular velocity in the
world frame, as in :mod:`rigid_env.sim`).

## Version History

* v0: initial version.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from .. import sim
from ..sim.rotation import quat_conjugate, quat_rotate
from .bodies import make_body
from .core import BatchedTask, TaskEnv, TaskVectorEnv, step_body_torque
from .kinematics import apply, apply_transpose, left_matrices, rotation_matrices
from .rendering import Camera, Frame, Item, Mesh, View
from .validation import (
    choice,
    finite_array,
    nonnegative_scalar,
    positive_int,
    positive_scalar,
    positive_vector,
    quaternion,
    scalar_range,
    unit_interval,
)

MAX_EPISODE_STEPS = 200
SPIN_OBS_LIMIT = 5.0  # observed Ω / spin_scale is clipped to ± this (5× the fastest initial spin)


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class ReorientTask(BatchedTask):
    """Batched core of Reorient-v0; arguments as in the module docstring."""

    def __init__(
        self,
        num_envs: int,
        *,
        body: sim.Body | None = None,
        half_extents=None,
        mass=None,
        inertia=None,
        integrator: str = sim.DEFAULT_INTEGRATOR,
        dt: float = 0.025,
        frame_skip: int = 2,
        max_torque=1.0,
        spin_range=(0.0, 2.0),
        tumble_fraction: float = 0.25,
        tumble_spread: float = 0.05,
        target_orientation=None,
        angle_threshold: float = 0.1,
        spin_threshold: float = 0.05,
        hold_time: float = 1.0,
        terminate_on_success: bool = True,
        angle_weight: float = 1.0,
        spin_weight: float = 0.1,
        action_weight: float = 0.01,
        success_bonus: float = 10.0,
        spin_scale: float | None = None,
    ):
        self.num_envs = positive_int(num_envs, "num_envs")
        self.body = make_body(
            body,
            half_extents,
            mass,
            inertia,
            default_half_extents=(0.3, 0.2, 0.1),
            default_mass=12.0,
        )
        self.integrator = choice(integrator, "integrator", sim.INTEGRATORS)
        self.dt = positive_scalar(dt, "dt")
        self.frame_skip = positive_int(frame_skip, "frame_skip")
        self.max_torque = positive_vector(max_torque, "max_torque")
        self.spin_range = scalar_range(spin_range, "spin_range")
        self.tumble_fraction = unit_interval(tumble_fraction, "tumble_fraction")
        self.tumble_spread = nonnegative_scalar(tumble_spread, "tumble_spread")
        self.fixed_target = (
            None
            if target_orientation is None
            else quaternion(target_orientation, "target_orientation")
        )
        self.angle_threshold = positive_scalar(angle_threshold, "angle_threshold")
        self.spin_threshold = positive_scalar(spin_threshold, "spin_threshold")
        self.hold_time = nonnegative_scalar(hold_time, "hold_time")
        if not isinstance(terminate_on_success, (bool, np.bool_)):
            raise ValueError(f"terminate_on_success must be a bool, got {terminate_on_success!r}")
        self.terminate_on_success = bool(terminate_on_success)
        self.angle_weight = nonnegative_scalar(angle_weight, "angle_weight")
        self.spin_weight = nonnegative_scalar(spin_weight, "spin_weight")
        self.action_weight = nonnegative_scalar(action_weight, "action_weight")
        self.success_bonus = nonnegative_scalar(success_bonus, "success_bonus")
        if spin_scale is None:
            spin_scale = self.spin_range[1] if self.spin_range[1] > 0 else 1.0
        self.spin_scale = positive_scalar(spin_scale, "spin_scale")

        self.action_period = self.dt * self.frame_skip
        self.render_fps = 1.0 / self.action_period
        # Steps within the thresholds before success; at least one so success needs the state.
        self.hold_steps = max(1, math.ceil(self.hold_time / self.action_period - 1e-9))
        self._inertia = np.array(self.body.inertia)  # body axes, symmetric
        moments, axes = np.linalg.eigh(self._inertia)
        self.principal_moments = moments
        self.intermediate_axis = axes[:, 1]  # eigh sorts ascending: column 1 is the middle one

        self.scene = self.build_scene()
        self.mesh = Mesh.from_shape(self.body.shape) if self.body.shape is not None else None

        s = SPIN_OBS_LIMIT
        high = np.array([1, 1, 1, 1, s, s, s, 1, 1, 1], dtype=np.float32)
        low = -high
        low[3] = 0.0
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)

        n = self.num_envs
        self.state = self.scene.initial_state(batch_shape=(n,))
        self.target = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        self._target_left = left_matrices(quat_conjugate(self.target))  # q_err = L(q_t⁻¹) q
        self.prev_action = np.zeros((n, 3))
        self.hold = np.zeros(n, dtype=np.int64)
        self._measure()

    def build_scene(self) -> sim.Scene:
        return sim.Scene(self.body, self.dt, integrator=self.integrator)  # free body only

    # --- resets ---------------------------------------------------------------------------------

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        # [spin magnitude, tumble coin] uniforms; [q0 (4), target (4), direction (3), perturbation (3)].
        return np.concatenate((rng.random(2), rng.standard_normal(14)))

    def reset_envs(self, index: np.ndarray, draws: np.ndarray) -> None:
        u, g = draws[:, :2], draws[:, 2:]
        q0 = _normalize(g[:, 0:4])  # normalised 4-D Gaussians are uniform on SO(3)
        target = _normalize(g[:, 4:8]) if self.fixed_target is None else self.fixed_target
        low, high = self.spin_range
        speed = low + (high - low) * u[:, 0]
        isotropic = _normalize(g[:, 8:11])
        side = np.where(isotropic @ self.intermediate_axis < 0, -1.0, 1.0)[:, None]
        tumble = _normalize(side * self.intermediate_axis + self.tumble_spread * g[:, 11:14])
        direction = np.where((u[:, 1] < self.tumble_fraction)[:, None], tumble, isotropic)
        omega = quat_rotate(q0, speed[:, None] * direction)  # body → world
        self.set_state(index, orientation=q0, angular_velocity=omega, target=target)

    def set_state(self, index, orientation=None, angular_velocity=None, target=None) -> None:
        """Hand-built state for envs ``index``: orientation (x, y, z, w), world angular velocity
        (rad/s), target quaternion; each broadcasts over ``index``; ``None`` keeps the current.
        The hold timer and the previous action are cleared."""
        index = np.asarray(index, dtype=np.intp)
        k = len(index)
        pos, q, vel, w = (np.array(a) for a in self.state.arrays())  # copies: states are values
        if orientation is not None:
            qi = finite_array(orientation, "orientation", (4,))
            norm = np.linalg.norm(qi, axis=-1, keepdims=True)
            if np.any(norm < 1e-12):
                raise ValueError("orientation must be non-zero quaternions (x, y, z, w)")
            q[index, 0] = np.broadcast_to(qi / norm, (k, 4))
        if angular_velocity is not None:
            w[index, 0] = np.broadcast_to(
                finite_array(angular_velocity, "angular_velocity", (3,)), (k, 3)
            )
        if target is not None:
            ti = finite_array(target, "target", (4,))
            norm = np.linalg.norm(ti, axis=-1, keepdims=True)
            if np.any(norm < 1e-12):
                raise ValueError("target must be non-zero quaternions (x, y, z, w)")
            self.target[index] = np.broadcast_to(ti / norm, (k, 4))
            self._target_left = left_matrices(quat_conjugate(self.target))
        pos[index] = 0.0
        vel[index] = 0.0
        self.state = sim.State(pos, q, vel, w)
        self.prev_action[index] = 0.0
        self.hold[index] = 0
        self._measure()

    # --- stepping -------------------------------------------------------------------------------

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        torque = action * self.max_torque  # body frame, (N, 3)
        self.state = step_body_torque(self.scene, self.state, self._rot, torque, self.frame_skip)
        self.prev_action = action
        self._measure()
        within = (self._angle < self.angle_threshold) & (self._spin < self.spin_threshold)
        self.hold = np.where(within, self.hold + 1, 0)
        success = self.hold >= self.hold_steps
        reward = (
            -(self.angle_weight / np.pi) * self._angle
            - (self.spin_weight / self.spin_scale) * self._spin
            - (self.action_weight / 3.0) * np.einsum("ij,ij->i", action, action)
            + self.success_bonus * success
        )
        terminated = success if self.terminate_on_success else np.zeros(self.num_envs, bool)
        return reward, terminated

    def _measure(self) -> None:
        """Error quaternion, body angular velocity, angle and spin of the current state."""
        q = self.state.orientation[:, 0]
        self._rot = rotation_matrices(q)
        err = apply(self._target_left, q)
        err *= np.copysign(1.0, err[:, 3:])  # w >= 0: continuous near the goal
        self._q_err = err
        self._omega = apply_transpose(self._rot, self.state.angular_velocity[:, 0])  # Ω = Rᵀ ω
        self._angle = 2.0 * np.arctan2(np.linalg.norm(err[:, :3], axis=1), err[:, 3])
        self._spin = np.linalg.norm(self._omega, axis=1)

    def observation(self) -> np.ndarray:
        obs = np.empty((self.num_envs, 10), dtype=np.float32)
        obs[:, 0:4] = self._q_err
        obs[:, 4:7] = np.clip(self._omega / self.spin_scale, -SPIN_OBS_LIMIT, SPIN_OBS_LIMIT)
        obs[:, 7:10] = self.prev_action
        return obs

    def info(self) -> dict[str, np.ndarray]:
        body_momentum = self._omega @ self._inertia  # I0 Ω (I0 symmetric)
        return {
            "angle_error": self._angle.copy(),
            "spin": self._spin.copy(),
            "energy": 0.5 * np.einsum("ij,ij->i", self._omega, body_momentum),
            "angular_momentum": apply(self._rot, body_momentum),  # L = R I0 Ω
            "is_success": self.hold >= self.hold_steps,
        }

    # --- rendering ------------------------------------------------------------------------------

    def _radius(self) -> float:
        return float(np.max(np.linalg.norm(self.mesh.vertices, axis=1))) if self.mesh else 0.3

    def view(self) -> View:
        eye = 5.5 * self._radius() * _normalize(np.array([1.0, -1.5, 0.8]))
        return View(Camera(tuple(eye)))

    def frame(self, i: int) -> Frame:
        if self.mesh is None:
            raise ValueError(
                "body has no shape to draw; give a Body with a Box, Sphere or Polyhedron"
            )
        axes = 1.35 * self._radius()
        origin = np.zeros(3)
        body = Item(self.mesh, self._rot[i], origin, color=(214, 178, 92), axes_length=axes)
        ghost = Item(
            self.mesh, rotation_matrices(self.target[i : i + 1])[0], origin, axes_length=axes
        )
        status = (
            "success" if self.hold[i] >= self.hold_steps else ("holding" if self.hold[i] else "")
        )
        text = (
            f"angle error {np.degrees(self._angle[i]):6.1f} deg",
            f"spin {self._spin[i]:6.3f} rad/s   {status}",
        )
        return Frame(bodies=(body,), ghosts=(ghost,), text=text)


class ReorientEnv(TaskEnv):
    __doc__ = __doc__
    task_class = ReorientTask


class ReorientVectorEnv(TaskVectorEnv):
    """Native vector version of :class:`ReorientEnv` (one batched simulator step for all)."""

    task_class = ReorientTask
    default_max_episode_steps = MAX_EPISODE_STEPS
