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
``ValueError`` and leave the env unchanged. The torque is body-fixed: it turns with the body
within a physics step too, as the integrator evaluates it in the world at the orientation of
each of its load evaluations (``Scene.step(..., body_torque=)``); the ``frame_skip`` physics
steps of an action run in one simulator call.

| Num | Action                     | Min | Max | Unit              |
|-----|----------------------------|-----|-----|-------------------|
| 0   | torque about body x        | -1  | 1   | ``max_torque`` N m |
| 1   | torque about body y        | -1  | 1   | ``max_torque`` N m |
| 2   | torque about body z        | -1  | 1   | ``max_torque`` N m |

## Observation Space

``Box((10,), float32)``, in named parts (``env.unwrapped.observation_structure``, as in
Gymnasium's MuJoCo v5 envs; ``rigid_env.envs.split_observation`` slices by name):
``error_quaternion`` (4), ``angular_velocity`` (3), ``previous_action`` (3). The error
rotation ``q_err = q_target⁻¹ ∘ q`` (Hamilton product, quaternions ``(x, y, z, w)``, ``q`` maps
body to world) is the rotation from the target body frame to the current one, in body axes; its sign is chosen with ``w >= 0`` so it is
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
is clipped to ±5 (``OBS_LIMIT``), five times the fastest initial spin with the default
``spin_scale``; it
starts within ±1 and a sensible policy keeps it there. ``info["spin"]`` is never clipped.

## Rewards

Per step, with θ the angle error (rad), Ω the body angular velocity (rad/s), a the action:

| Term (``info`` key)  | Value                                      | Default weight      |
|----------------------|--------------------------------------------|---------------------|
| ``reward_angle``     | ``-angle_weight · θ / π``                  | ``angle_weight=1``  |
| ``reward_spin``      | ``-spin_weight · |Ω| / spin_scale``        | ``spin_weight=0.1`` |
| ``reward_ctrl``      | ``-action_weight · |a|² / 3``              | ``action_weight=0.01`` |
| ``reward_success``   | ``+success_bonus`` on every step ``is_success`` holds | ``success_bonus=10`` |

The reward is their sum; each term is in ``info`` under its key (as in Gymnasium's ``Hopper-v5``).

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

``reset(options=...)`` replaces parts of the drawn start (the draws are made all the same, so
later episodes do not depend on the options); a vector env broadcasts each value over the
sub-envs it resets (``options["reset_mask"]``), or takes one row per reset sub-env. Other keys,
and values that are not these, raise ``ValueError`` naming ``options[key]``:

| Key                    | Value                                                  |
|------------------------|--------------------------------------------------------|
| ``orientation``        | quaternion (x, y, z, w), body to world (normalised)    |
| ``angular_velocity``   | (3,) world frame, rad/s                                |
| ``target``             | the target orientation, a quaternion (normalised)      |

## Episode End

1. Termination: ``is_success`` (only with ``terminate_on_success=True``, the default).
2. Truncation: ``max_episode_steps`` = 200 steps (10 s with the default 0.05 s action period).

## Info

Every ``reset`` and ``step`` returns ``angle_error`` (θ, rad), ``spin`` (|Ω|, rad/s), ``energy``
(kinetic, J), ``angular_momentum`` (world frame, (3,), kg m²/s, a fresh array), the reward
terms ``reward_*`` (0 at a reset) and ``is_success`` (``bool``). With ``torque_scale_range``:
``torque_limit`` (the episode's, (3,), N m); with ``mass_scale_range`` or
``inertia_scale_range``: ``mass_scale`` or ``inertia_scale`` (the episode's, float); with
``observation_noise``: ``observation_clean`` (the observation without noise).

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
| ``spin_scale``        | ``None``              | observation scale of Ω, rad/s; ``None``: ``spin_range`` high, at least 1 rad/s |
| ``backend``           | ``None``              | the simulator's step (``rigid_env.sim.Scene``'s ``backend``): ``None`` reads ``RIGID_ENV_BACKEND``; ``"compiled-threads"`` splits a vector env's batch over the cores |
| ``torque_scale_range``| ``None``              | ``(low, high)``: each episode's torque limit is ``max_torque`` × s, s uniform in it (one s for the three axes), drawn at the reset |
| ``mass_scale_range``  | ``None``              | ``(low, high)``: each episode's body is s times denser (mass and inertia × s), s uniform in it, drawn at the reset |
| ``inertia_scale_range``| ``None``              | ``(low, high)``: each episode's inertia × k (its mass moved outward), k uniform in it, drawn at the reset; with either, each env steps its own scene (one simulator call per env) |
| ``observation_noise`` | ``None``              | ``{part: std}``: Gaussian noise added to those observation parts (std in the part's units, table above), clipped to the observation space; ``info["observation_clean"]`` keeps the observation without it |
| ``render_mode``       | ``None``              | ``"human"`` or ``"rgb_array"`` (vector env: ``"rgb_array"``) |
| ``width``, ``height`` | ``480``, ``480``      | frame size, pixels                                        |
| ``default_camera_config`` | ``None``          | a dict of ``distance`` (m), ``azimuth`` and ``elevation`` (degrees) and ``lookat`` (a point, m), as in MuJoCo's v5 envs; keys not given keep the default: 5.5 body radii from the origin, azimuth 124°, elevation −24° |

Bounds: ``dt`` ≤ 1 s, ``frame_skip`` ≤ 10 000, ``max_torque`` (and its randomised value) ≤
10⁴ N m, ``spin_range``, ``spin_scale`` and ``spin_threshold`` ≤ 1000 rad/s,
``angle_threshold`` ≤ π, ``tumble_spread`` ≤ 10, ``hold_time`` ≤ 10⁴ s, every weight and the
bonus ≤ 10⁶, ``half_extents`` ≤ 100 m, ``mass`` ≤ 10⁶ kg, noise std ≤ 10, ``width`` and
``height`` ≤ 4096. Beyond them an episode's numbers stop meaning anything (a torque of
1e300 N m gave rewards of −inf), so they are refused.

Randomisation draws from the env's generator once per episode, after the start state, so it is
reproducible from the reset seed (a vector sub-env ``i`` seeded ``s + i`` as before), and with
none configured nothing more is drawn: the default episodes are unchanged.

The arguments other than ``render_mode``, ``width``, ``height`` and
``default_camera_config`` form a :class:`ReorientConfig` (a frozen dataclass,
validated when built); ``make(..., config=ReorientConfig(...))`` passes one whole.
Bad values raise ``ValueError`` naming the argument. The vector env also takes ``num_envs`` and
``max_episode_steps``; seeded with ``s`` its sub-env ``i`` uses seed ``s + i`` and equals a single
env seeded ``s + i`` step for step (Gymnasium ``NEXT_STEP`` autoreset). ``set_state(orientation=,
angular_velocity=, target=)`` on the unwrapped env builds a state by hand (angular velocity in the
world frame, as in :mod:`rigid_env.sim`).

## Version History

* v0: initial version.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .. import sim
from ..sim.rotation import quat_rotate
from . import kernels
from .core import TaskEnv, TaskVectorEnv
from .hold_task import (
    MAX_SPIN,
    OBS_LIMIT,
    Bounds,
    HoldTask,
    HoldTaskConfig,
    unit_quaternions,
    weight,
)
from .rendering import CameraConfig, Frame, Item, Mesh, View
from .validation import at_most, nonnegative_scalar, positive_scalar, quaternions, unit_interval

MAX_EPISODE_STEPS = 200
MAX_TUMBLE_SPREAD = 10.0  # beyond about 3 the tumbling episodes' spin axis is already isotropic
OBSERVATION_BOUNDS: dict[str, Bounds] = {
    "error_quaternion": ((-1.0, -1.0, -1.0, 0.0), (1.0, 1.0, 1.0, 1.0)),
    "angular_velocity": ((-OBS_LIMIT,) * 3, (OBS_LIMIT,) * 3),
    "previous_action": ((-1.0,) * 3, (1.0,) * 3),
}


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True, kw_only=True, eq=False)
class ReorientConfig(HoldTaskConfig):
    """The arguments of Reorient-v0 (table in the module docstring), validated."""

    default_half_extents: ClassVar[tuple[float, float, float]] = (0.3, 0.2, 0.1)
    default_mass: ClassVar[float] = 12.0
    observation_parts: ClassVar[tuple[str, ...]] = tuple(OBSERVATION_BOUNDS)

    tumble_fraction: float = 0.25
    tumble_spread: float = 0.05
    target_orientation: Any = None
    angle_threshold: float = 0.1
    spin_threshold: float = 0.05
    angle_weight: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()

        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("tumble_fraction", unit_interval(self.tumble_fraction, "tumble_fraction"))
        spread = nonnegative_scalar(self.tumble_spread, "tumble_spread")
        put("tumble_spread", at_most(spread, "tumble_spread", MAX_TUMBLE_SPREAD))
        if self.target_orientation is not None:
            target = quaternions(self.target_orientation, "target_orientation")
            if target.shape != (4,):
                raise ValueError(f"target_orientation must be one quaternion, got {target!r}")
            put("target_orientation", tuple(target.tolist()))
        angle = positive_scalar(self.angle_threshold, "angle_threshold")
        put("angle_threshold", at_most(angle, "angle_threshold", np.pi, " rad"))
        spin = positive_scalar(self.spin_threshold, "spin_threshold")
        put("spin_threshold", at_most(spin, "spin_threshold", MAX_SPIN, " rad/s"))
        put("angle_weight", weight(self.angle_weight, "angle_weight"))


class ReorientTask(HoldTask):
    """Batched core of Reorient-v0; arguments as in the module docstring."""

    config_class = ReorientConfig
    config: ReorientConfig
    observation_bounds = OBSERVATION_BOUNDS
    task_reward_terms = ("reward_angle",)
    start_options = ("orientation", "angular_velocity", "target")

    def __init__(self, num_envs: int, config: ReorientConfig | None = None, **kwargs: Any):
        super().__init__(num_envs, config, **kwargs)
        moments, axes = np.linalg.eigh(self.inertia)
        self.principal_moments = moments
        self.intermediate_axis = axes[:, 1]  # eigh sorts ascending: column 1 is the middle one
        shape = self.body.shape
        self.mesh = Mesh.from_shape(shape) if shape is not None else None

        n = self.num_envs
        self.state = self.scene.initial_state(batch_shape=(n,))
        self.target = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        cfg = self.config
        self._params = np.array(  # what reorient_measure reads, in its order
            [
                self.spin_scale,
                OBS_LIMIT,
                cfg.angle_threshold,
                cfg.spin_threshold,
                cfg.angle_weight / np.pi,
            ]
        )
        self._meas = np.empty((n, 9))  # see kernels.reorient_measure
        self._measure(self._all)

    def build_scene(self) -> sim.Scene:
        """The scene of the configured body (an episode's randomised mass and inertia are a
        row of ``parameters``: ``HoldTask.episode_parameters``)."""
        cfg = self.config
        # a free body only: no gravity, ground or springs
        return sim.Scene(self.body, cfg.dt, integrator=cfg.integrator, backend=cfg.backend)

    # --- resets ---------------------------------------------------------------------------------

    def draw_start(self, rng: np.random.Generator) -> np.ndarray:
        # [spin magnitude, tumble coin] uniforms; [q0 (4), target (4), direction (3), perturbation (3)].
        return np.concatenate((rng.random(2), rng.standard_normal(14)))

    def reset_start(self, index: np.ndarray, draws: np.ndarray) -> None:
        cfg = self.config
        u, g = draws[:, :2], draws[:, 2:]
        q0 = _normalize(g[:, 0:4])  # normalised 4-D Gaussians are uniform on SO(3)
        target = _normalize(g[:, 4:8]) if cfg.target_orientation is None else cfg.target_orientation
        low, high = cfg.spin_range
        speed = low + (high - low) * u[:, 0]
        isotropic = _normalize(g[:, 8:11])
        side = np.where(isotropic @ self.intermediate_axis < 0, -1.0, 1.0)[:, None]
        tumble = _normalize(side * self.intermediate_axis + cfg.tumble_spread * g[:, 11:14])
        direction = np.where((u[:, 1] < cfg.tumble_fraction)[:, None], tumble, isotropic)
        omega = quat_rotate(q0, speed[:, None] * direction)  # body → world
        self._set_state(index, q0, omega, target, trusted=True)

    def set_state(
        self,
        index: Any,
        orientation: Any = None,
        angular_velocity: Any = None,
        target: Any = None,
    ) -> None:
        """Hand-built state for envs ``index``: orientation (x, y, z, w), world angular velocity
        (rad/s), target quaternion; each broadcasts over ``index``; ``None`` keeps the current.
        The hold timer, the reward terms and the previous action are cleared."""
        index = np.asarray(index, dtype=np.intp)
        self._set_state(index, orientation, angular_velocity, target, trusted=False)

    def _check_value(self, name: str, value: Any, k: int, label: str) -> np.ndarray:
        # The target is a quaternion like the orientation.
        return super()._check_value("orientation" if name == "target" else name, value, k, label)

    def _set_state(
        self, index: np.ndarray, orientation: Any, angular_velocity: Any, target: Any, trusted: bool
    ) -> None:
        """:meth:`set_state`; ``trusted``: the values come from :meth:`reset_start` (no checks,
        see ``HoldTask._edited_state``)."""
        state = self._edited_state(
            index, trusted, orientation=orientation, angular_velocity=angular_velocity
        )
        if target is not None:
            unit = (
                unit_quaternions(target)
                if trusted
                else self._check_value("target", target, len(index), "target")
            )
            self.target[index] = np.broadcast_to(unit, (len(index), 4))
        self.state = state
        self._start_episode(index)
        self._measure(index)

    # --- measurements, observation, reward ------------------------------------------------------

    def _measure(self, index: np.ndarray) -> None:
        """Error quaternion, body angular velocity, angle, spin, observation, goal and the angle
        term of envs ``index``: one compiled call (``kernels.reorient_measure``)."""
        kernels.reorient_measure(
            index,
            self.state.orientation,
            self.state.angular_velocity,
            self.target,
            self.inertias,
            self._params,
            self.prev_action,
            self._obs,
            self._rot,
            self._meas,
            self._within_goal,
            self._task_terms,
        )

    def _task_info(self) -> dict[str, np.ndarray]:
        return {
            "angle_error": self._angle.copy(),
            "spin": self._spin.copy(),
            "energy": self._meas[:, 5].copy(),
            "angular_momentum": self._meas[:, 6:9].copy(),  # L = R I0 Ω, world axes
        }

    def _task_single_info(self) -> dict[str, Any]:
        angle, spin, energy = self._meas[0, 3:6].tolist()
        return {
            "angle_error": angle,
            "spin": spin,
            "energy": energy,
            "angular_momentum": self._meas[0, 6:9].copy(),
        }

    # --- rendering ------------------------------------------------------------------------------

    def _radius(self) -> float:
        return float(np.max(np.linalg.norm(self.mesh.vertices, axis=1))) if self.mesh else 0.3

    def view(self) -> View:
        return View()

    def default_camera(self) -> CameraConfig:
        """The body at the origin from 5.5 of its radii: it fills about half the frame."""
        return CameraConfig(distance=5.5 * self._radius(), azimuth=124.0, elevation=-24.0)

    def frame(self, i: int) -> Frame:
        if self.mesh is None:
            raise ValueError(
                "body has no shape to draw; give a Body with a Box, Sphere or Polyhedron"
            )
        axes = 1.35 * self._radius()
        origin = np.zeros(3)
        body = Item(self.mesh, self._rot[i], origin, color=(214, 178, 92), axes_length=axes)
        ghost = Item(
            self.mesh,
            kernels.rotation_matrices(self.target[i : i + 1])[0],
            origin,
            axes_length=axes,
        )
        text = (
            f"angle error {np.degrees(self._angle[i]):6.1f} deg",
            f"spin {self._spin[i]:6.3f} rad/s   {self.status(i)}",
        )
        return Frame(bodies=(body,), ghosts=(ghost,), text=text)


class ReorientEnv(TaskEnv):
    __doc__ = __doc__
    task_class = ReorientTask


class ReorientVectorEnv(TaskVectorEnv):
    """Native vector version of :class:`ReorientEnv` (one batched simulator step for all)."""

    task_class = ReorientTask
    default_max_episode_steps = MAX_EPISODE_STEPS
