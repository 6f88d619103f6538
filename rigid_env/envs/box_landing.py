r"""``RigidEnv/BoxLanding-v0``: land a thrown box on a chosen face and bring it to rest.

## Description

A box (by default a uniform 0.2 m × 0.3 m × 0.4 m box of 1 kg, half extents 0.1, 0.15, 0.2 m,
principal moments 0.0208, 0.0167, 0.0108 kg m²) is thrown at the ground from a random height with
a random tilt, spin and velocity. Gravity (9.81 m/s² down) and the ground plane z = 0 with
Newton restitution and Coulomb friction act on it (the simulator's contact scene: gravity, the
velocity update, ground collision and contact solve, the position update, restitution). The box
carries three reaction wheels: the agent commands saturated torques about the body axes to turn
the *target face* down before touchdown, land on it with few bounces and come to rest on it,
upright and without tumbling over. The default target, ``"-z"``, is the face whose outward
normal is body −z: resting on it the box stands on its smallest face with its centre of mass
highest, which it rarely does by chance.

## Action Space

``Box(-1, 1, (3,), float32)``: the torque about the box's own axes, as a fraction of
``max_torque`` (the wheels' saturation). Values outside [-1, 1] are clipped; NaN, infinity or a
wrong shape raise ``ValueError`` and leave the env unchanged. The torque is body-fixed: it is
rotated into the world at every physics step.

| Num | Action                     | Min | Max | Unit               |
|-----|----------------------------|-----|-----|--------------------|
| 0   | torque about body x        | -1  | 1   | ``max_torque`` N m |
| 1   | torque about body y        | -1  | 1   | ``max_torque`` N m |
| 2   | torque about body z        | -1  | 1   | ``max_torque`` N m |

## Observation Space

``Box((25,), float32)``: what the box's own sensors give (altimeter, velocity estimate, IMU,
gyro, corner touch switches) plus the task. Vectors marked *body* are in body axes, *world* in
world axes (z up). The parts are named in ``env.unwrapped.observation_structure`` (as in
Gymnasium's MuJoCo v5 envs; ``rigid_env.envs.split_observation`` slices by name):

| Num   | Part                | Observation                                      | Min | Max | Unit            |
|-------|---------------------|--------------------------------------------------|-----|-----|-----------------|
| 0     | ``height``          | height of the centre of mass                     | 0   | 10  | m               |
| 1     | ``clearance``       | height of the lowest corner                      | 0   | 10  | m               |
| 2–4   | ``linear_velocity`` | linear velocity (world) / 5 m/s                  | -5  | 5   | (m/s)/(m/s)     |
| 5–7   | ``up``              | world +z in body axes (an IMU's gravity)         | -1  | 1   |                 |
| 8–10  | ``angular_velocity``| body angular velocity Ω / ``spin_scale``         | -5  | 5   | (rad/s)/(rad/s) |
| 11–13 | ``target_normal``   | target face outward normal in body axes (±e_x, ±e_y, ±e_z) | -1 | 1 |    |
| 14–21 | ``corner_contacts`` | corner touch flags (1 when within ``contact_tolerance`` of the ground), corners in the order of ``sim.Box.vertices`` (index 4 i_x + 2 i_y + i_z, i = 0 for −, 1 for +) | 0 | 1 | |
| 22–24 | ``previous_action`` | previous action                                  | -1  | 1   | ``max_torque``  |

Height and clearance are bounded below by the ground (a resting contact may sink by rounding:
the clearance is clipped at 0) and clipped at 10 m above. The velocities are clipped: a default
throw starts within ±0.4 scaled units and a 2 m fall adds 6.3 m/s (1.3 units); torque can spin
the box up without limit, which a sensible policy avoids. ``info`` carries the values unclipped.

## Rewards

Per step, with θ the angle between the target face's outward normal and world −z (0 when the
box stands on it), Ω the body angular velocity, a the action:

| Term (``info`` key) | Value                                                | Default weight         |
|---------------------|------------------------------------------------------|------------------------|
| ``reward_angle``    | ``-face_weight · θ / π``                             | ``face_weight=1``      |
| ``reward_bounce``   | ``-bounce_weight`` at each touchdown after the first | ``bounce_weight=0.5``  |
| ``reward_spin``     | ``-spin_weight · |Ω| / spin_scale``                  | ``spin_weight=0.05``   |
| ``reward_ctrl``     | ``-action_weight · |a|² / 3``                        | ``action_weight=0.01`` |
| ``reward_success``  | ``+success_bonus`` on every step ``is_success`` holds | ``success_bonus=10``  |

The reward is their sum; each term is in ``info`` under its key (as in Gymnasium's ``Hopper-v5``).

The face term is linear in θ so its pull does not fade near the goal; the spin term is small
because turning the box in flight needs spin. A *touchdown* is an action period in which the
box touched the ground after a period in which it did not (a touch is a contact impulse at
any physics step of the period, or a corner within ``contact_tolerance`` at its end, so a
bounce shorter than a period still counts if it spans one). Every term
but the bonus is ≤ 0, so with ``terminate_on_success=True`` succeeding sooner is always better.

## Success

The box is *within* the goal when it touches the ground (a corner within
``contact_tolerance``), θ < ``face_threshold`` (0.2 rad), ``|v| < speed_threshold``
(0.05 m/s) and ``|Ω| < spin_threshold`` (0.1 rad/s). ``is_success`` becomes ``True`` once it
has stayed within for ``hold_time`` (0.5 s, 15 steps) and stays ``True`` while it remains within.
Coming to rest on a wrong face does not end the episode: the face penalty keeps accruing until
truncation, so it costs more the earlier it happens (ending it early would reward a policy whose
per-step rewards are negative for failing fast), and the wheels may still tip the box over.

## Starting State

The centre of mass at (0, 0, h) with h uniform in ``height_range`` (1 to 2 m). Velocity:
vertical uniform in ``vertical_velocity_range`` (−2 to 1 m/s, + up), horizontal of speed uniform
in ``horizontal_speed_range`` (0 to 1 m/s) in a uniform direction. Orientation: ZYZ Euler angles
R_z(α) R_y(β) R_z(γ) with α, γ uniform and cos β uniform between cos of the ``tilt_range`` ends,
so β is the tilt of body +z from world +z and the default (0, π) is uniform on SO(3). Angular
velocity of magnitude uniform in ``spin_range`` (0 to 3 rad/s) about a uniform direction. The
target face is ``target_face`` or, with ``"random"``, uniform over the six faces per episode.

## Episode End

1. Termination: ``is_success`` (only with ``terminate_on_success=True``, the default).
2. Truncation: ``max_episode_steps`` = 120 steps (4 s with the default 1/30 s action period).

## Info

Every ``reset`` and ``step`` returns ``angle_error`` (θ, rad), ``spin`` (|Ω|, rad/s), ``speed``
(|v|, m/s), ``height`` (centre of mass, m), ``clearance`` (lowest corner, m), ``contact_count``
(corners touching, int), ``touchdowns`` (int), ``bounces`` (touchdowns after the first, int),
``down_face`` (index into ``FACES`` = ("+x", "-x", "+y", "-y", "+z", "-z") of the face now
facing the ground, int), ``target_face`` (index, int), ``energy`` (kinetic + gravitational
m g z, J), the reward terms ``reward_*`` (0 at a reset) and ``is_success`` (``bool``).

## Arguments

``gymnasium.make("RigidEnv/BoxLanding-v0", **kwargs)`` and
``gymnasium.make_vec("RigidEnv/BoxLanding-v0", num_envs=N, vectorization_mode="vector_entry_point",
**kwargs)`` take:

| Argument                 | Default          | Meaning                                                   |
|--------------------------|------------------|-----------------------------------------------------------|
| ``body``                 | ``None``         | a ``rigid_env.sim.Body`` with a ``Box`` shape             |
| ``half_extents``         | ``(0.1, 0.15, 0.2)`` | of the default box, m (only without ``body``)          |
| ``mass``                 | ``1.0``          | of the default box, kg (only without ``body``)            |
| ``inertia``              | ``None``         | override: 3 principal moments or a 3×3 tensor, kg m²      |
| ``integrator``           | ``"implicit_gyro"`` | one of ``rigid_env.sim.CONTACT_CAPABLE``                |
| ``dt``                   | ``1/240``        | physics time step, s                                      |
| ``frame_skip``           | ``8``            | physics steps per action (1/30 s)                         |
| ``restitution``          | ``0.3``          | of the ground, in [0, 1]                                  |
| ``friction``             | ``0.5``          | Coulomb coefficient of the ground                         |
| ``max_torque``           | ``1.0``          | N m at action 1; a number or one per body axis            |
| ``height_range``         | ``(1.0, 2.0)``   | initial height of the centre of mass, m (low above the box's reach) |
| ``vertical_velocity_range`` | ``(-2.0, 1.0)`` | initial vertical velocity, m/s, + up                     |
| ``horizontal_speed_range`` | ``(0.0, 1.0)``  | initial horizontal speed, m/s                             |
| ``spin_range``           | ``(0.0, 3.0)``   | initial angular speed, rad/s                              |
| ``tilt_range``           | ``(0.0, π)``     | initial tilt of body +z from world +z, rad                |
| ``target_face``          | ``"-z"``         | one of ``FACES`` or ``"random"`` (per episode)            |
| ``face_threshold``       | ``0.2``          | success angle θ, rad                                      |
| ``speed_threshold``      | ``0.05``         | success speed, m/s                                        |
| ``spin_threshold``       | ``0.1``          | success spin, rad/s                                       |
| ``hold_time``            | ``0.5``          | time to stay within the goal, s                           |
| ``contact_tolerance``    | ``0.005``        | a corner this close to the ground touches it, m           |
| ``terminate_on_success`` | ``True``         | end the episode at success                                |
| ``face_weight``, ``spin_weight``, ``bounce_weight``, ``action_weight``, ``success_bonus`` | 1, 0.05, 0.5, 0.01, 10 | reward terms (table above) |
| ``spin_scale``           | ``None``         | observation scale of Ω, rad/s; ``None``: ``spin_range`` high (at least 1 rad/s) |
| ``backend``              | ``None``         | the simulator's step (``rigid_env.sim.Scene``'s ``backend``): ``None`` reads ``RIGID_ENV_BACKEND``; ``"compiled-threads"`` splits a vector env's batch over the cores |
| ``contact_solver``       | ``CONTACT_SOLVER`` | the contact solve's ``rigid_env.sim.SolverSettings``; the default warm-starts an action's physics steps after its first from the previous step's impulses: the same tolerance, ~1.4× cheaper physics on this task than ``SolverSettings()`` |
| ``render_mode``          | ``None``         | ``"human"`` or ``"rgb_array"`` (vector env: ``"rgb_array"``) |

Why these defaults: the box is the simulator's landing scene. A fall of 1–2 m takes 0.45–0.64 s
before the first touchdown; at 1 N m the wheels turn the box by π about its largest axis in
about 0.6 s (bang-bang, 2 √(π I / τ)), so turning the target face down in flight is feasible from
most throws but not from all, and braking the initial spin takes part of that time (the analytic
controller, ``python -m agents.evaluate --env RigidEnv/BoxLanding-v0 --policy analytic``,
succeeds in 96 % of the 200 seeded evaluation episodes; zero torque in about 1 of 30). Resting,
the wheels tip the box over an edge only if τ > m g d, d the horizontal distance from the
centre of mass to that edge: 0.98 N m off the ±y and ±z faces about their 0.1 m edges, so a bad
policy can topple a box standing on its target, but 1.96 N m onto the −z face (d = 0.2 m): with
the default target, a box at rest on a wrong face never reaches the target face.

The arguments other than ``render_mode`` form a :class:`BoxLandingConfig` (a frozen dataclass,
validated when built); ``make(..., config=BoxLandingConfig(...))`` passes one whole.
Bad values raise ``ValueError`` naming the argument. The vector env also takes ``num_envs`` and
``max_episode_steps``; seeded with ``s`` its sub-env ``i`` uses seed ``s + i`` and equals a single
env seeded ``s + i`` step for step (Gymnasium ``NEXT_STEP`` autoreset). ``set_state(position=,
orientation=, linear_velocity=, angular_velocity=, target_face=)`` on the unwrapped env builds a
state by hand (velocities in the world frame, as in :mod:`rigid_env.sim`).

## Version History

* v0: initial version.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .. import sim
from ..sim.rotation import quat_from_axis_angle, quat_multiply
from ..sim.scenes import LANDING_HALF_EXTENTS
from . import kernels
from .core import TaskEnv, TaskVectorEnv
from .hold_task import OBS_LIMIT, STATE_FIELDS, HoldTask, HoldTaskConfig
from .rendering import Camera, Frame, Item, Mesh, View
from .validation import choice, nonnegative_scalar, positive_scalar, scalar_range, unit_interval

MAX_EPISODE_STEPS = 120
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
FACE_NORMALS = np.array(
    [[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
)  # outward normals in body axes, in the order of FACES
GRAVITY = 9.81  # m/s², down
VELOCITY_SCALE = 5.0  # m/s: the observed linear velocity is v / VELOCITY_SCALE
HEIGHT_LIMIT = 10.0  # m: observed height and clearance are clipped to [0, this]


def _lerp(bounds: tuple[float, float], u: np.ndarray) -> np.ndarray:
    return bounds[0] + (bounds[1] - bounds[0]) * u


def _face_index(value: Any, name: str = "target_face") -> np.ndarray | int:
    """A face name or index (or an array of indices) as index into :data:`FACES`."""
    if isinstance(value, str):
        return FACES.index(str(choice(value, name, FACES)))
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu" or np.any((arr < 0) | (arr >= len(FACES))):
        raise ValueError(f"{name} must be one of {FACES} or an index 0..5, got {value!r}")
    return arr.astype(np.intp)


# The contact solve of this task's scene (see ``contact_solver`` in the module docstring). On
# BoxLanding's rollout states, 8 physics steps per call (512 envs, random actions, replayed
# through the compiled step), µs per element and physics step: SolverSettings() 6.4,
# warm_start 4.5, with the same capped solves (0.3 % of the calls with contacts); on a trained
# PPO policy's states 6.2 and 5.5. Going on from a failed warm probe instead of the cold start
# gave 4.2 and 5.2, but 10-18 % more capped solves; with that, newton_after 3 gave 3.85
# against 4.2, but the backends' answers on the 8 tumbling boxes of
# tests/sim/test_compiled_contacts.py then differ by 4× the bound derived there: neither taken.
CONTACT_SOLVER = sim.SolverSettings(warm_start=True)


@dataclass(frozen=True, kw_only=True, eq=False)
class BoxLandingConfig(HoldTaskConfig):
    """The arguments of BoxLanding-v0 (table in the module docstring), validated."""

    default_half_extents: ClassVar[tuple[float, float, float]] = LANDING_HALF_EXTENTS
    default_mass: ClassVar[float] = 1.0
    body_shapes: ClassVar[tuple[type, ...] | None] = (sim.Box,)
    integrators: ClassVar[tuple[str, ...]] = sim.CONTACT_CAPABLE

    integrator: str = sim.CONTACT_INTEGRATOR
    dt: float = 1 / 240
    frame_skip: int = 8
    spin_range: tuple[float, float] = (0.0, 3.0)
    hold_time: float = 0.5
    spin_weight: float = 0.05
    restitution: float = 0.3
    friction: float = 0.5
    height_range: tuple[float, float] = (1.0, 2.0)
    vertical_velocity_range: tuple[float, float] = (-2.0, 1.0)
    horizontal_speed_range: tuple[float, float] = (0.0, 1.0)
    tilt_range: tuple[float, float] = (0.0, math.pi)
    target_face: str | int = "-z"
    face_threshold: float = 0.2
    speed_threshold: float = 0.05
    spin_threshold: float = 0.1
    contact_tolerance: float = 0.005
    face_weight: float = 1.0
    bounce_weight: float = 0.5
    contact_solver: sim.SolverSettings = CONTACT_SOLVER

    def __post_init__(self) -> None:
        super().__post_init__()

        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("restitution", unit_interval(self.restitution, "restitution"))
        put("friction", nonnegative_scalar(self.friction, "friction"))
        corners = np.array(self.rigid_body.shape.vertices)
        reach = float(np.max(np.linalg.norm(corners, axis=1)))
        put("height_range", scalar_range(self.height_range, "height_range"))
        if self.height_range[0] <= reach:
            raise ValueError(
                f"height_range must start above the box's reach {reach:.3f} m (its corners "
                f"would start in the ground), got {self.height_range!r}"
            )
        put(
            "vertical_velocity_range",
            scalar_range(self.vertical_velocity_range, "vertical_velocity_range", -math.inf),
        )
        put(
            "horizontal_speed_range",
            scalar_range(self.horizontal_speed_range, "horizontal_speed_range"),
        )
        put("tilt_range", scalar_range(self.tilt_range, "tilt_range"))
        if self.tilt_range[1] > math.pi:
            raise ValueError(f"tilt_range must lie within [0, π], got {self.tilt_range!r}")
        if self.target_face != "random":
            put("target_face", FACES[int(_face_index(self.target_face))])
        for name in ("face_threshold", "speed_threshold", "spin_threshold", "contact_tolerance"):
            put(name, positive_scalar(getattr(self, name), name))
        for name in ("face_weight", "bounce_weight"):
            put(name, nonnegative_scalar(getattr(self, name), name))
        if not isinstance(self.contact_solver, sim.SolverSettings):
            raise ValueError(
                f"contact_solver must be a rigid_env.sim.SolverSettings, got {self.contact_solver!r}"
            )


class BoxLandingTask(HoldTask):
    """Batched core of BoxLanding-v0; arguments as in the module docstring."""

    config_class = BoxLandingConfig
    config: BoxLandingConfig
    observation_bounds = {
        "height": (0.0, HEIGHT_LIMIT),
        "clearance": (0.0, HEIGHT_LIMIT),
        "linear_velocity": ((-OBS_LIMIT,) * 3, (OBS_LIMIT,) * 3),
        "up": ((-1.0,) * 3, (1.0,) * 3),
        "angular_velocity": ((-OBS_LIMIT,) * 3, (OBS_LIMIT,) * 3),
        "target_normal": ((-1.0,) * 3, (1.0,) * 3),
        "corner_contacts": ((0.0,) * 8, (1.0,) * 8),
        "previous_action": ((-1.0,) * 3, (1.0,) * 3),
    }
    task_reward_terms = ("reward_angle", "reward_bounce")

    def __init__(self, num_envs: int, config: BoxLandingConfig | None = None, **kwargs: Any):
        super().__init__(num_envs, config, **kwargs)
        cfg = self.config
        self.corners = np.array(self.body.shape.vertices)  # (8, 3) body axes
        self.random_face = cfg.target_face == "random"
        self.mesh = Mesh.from_shape(self.body.shape)

        n = self.num_envs
        self.state = self.scene.initial_state(
            position=(0.0, 0.0, cfg.height_range[0]), batch_shape=(n,)
        )
        self.face = np.full(n, FACES.index("-z" if self.random_face else str(cfg.target_face)))
        self._face_normal = FACE_NORMALS[self.face]
        self.touchdowns = np.zeros(n, dtype=np.int64)
        self._no_contact_report = np.zeros(n, dtype=bool)  # touched, for a scene without one
        self._touched = self._no_contact_report
        self._params = np.array(  # what landing_measure reads, in its order
            [
                self.body.mass,
                GRAVITY,
                self.spin_scale,
                VELOCITY_SCALE,
                HEIGHT_LIMIT,
                OBS_LIMIT,
                cfg.contact_tolerance,
                cfg.face_threshold,
                cfg.speed_threshold,
                cfg.spin_threshold,
                cfg.face_weight / np.pi,
            ]
        )
        self._meas = np.empty((n, 9))  # see kernels.landing_measure
        self._ints = np.empty((n, 2), dtype=np.int64)
        self._measure(self._all)
        self.touching = self._clearance < cfg.contact_tolerance

    def build_scene(self) -> sim.Scene:
        cfg = self.config
        return sim.Scene(
            self.body,
            cfg.dt,
            integrator=cfg.integrator,
            gravity=(0.0, 0.0, -GRAVITY),
            ground=sim.Ground(restitution=cfg.restitution, friction=cfg.friction),
            contact_solver=cfg.contact_solver,
            backend=cfg.backend,
        )

    # --- resets ---------------------------------------------------------------------------------

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        # Uniforms: [height, v_z, horizontal speed, its direction, spin, cos tilt, α, γ, face];
        # Gaussians: [spin direction (3)].
        return np.concatenate((rng.random(9), rng.standard_normal(3)))

    def reset_envs(self, index: np.ndarray, draws: np.ndarray) -> None:
        cfg = self.config
        u, g = draws[:, :9], draws[:, 9:]
        k = len(index)
        position = np.zeros((k, 3))
        position[:, 2] = _lerp(cfg.height_range, u[:, 0])
        heading = 2 * np.pi * u[:, 3]
        speed = _lerp(cfg.horizontal_speed_range, u[:, 2])
        velocity = np.stack(
            (
                speed * np.cos(heading),
                speed * np.sin(heading),
                _lerp(cfg.vertical_velocity_range, u[:, 1]),
            ),
            axis=1,
        )
        direction = g / np.linalg.norm(g, axis=1, keepdims=True)
        omega = _lerp(cfg.spin_range, u[:, 4])[:, None] * direction
        # Haar measure in ZYZ Euler angles: α, γ uniform, cos β uniform (restricted by tilt_range).
        cos_range = (math.cos(cfg.tilt_range[1]), math.cos(cfg.tilt_range[0]))
        tilt = np.arccos(np.clip(_lerp(cos_range, u[:, 5]), -1.0, 1.0))
        z_axis, y_axis = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
        q = quat_multiply(
            quat_multiply(
                quat_from_axis_angle(z_axis, 2 * np.pi * u[:, 6]),
                quat_from_axis_angle(y_axis, tilt),
            ),
            quat_from_axis_angle(z_axis, 2 * np.pi * u[:, 7]),
        )
        if self.random_face:
            face: Any = np.minimum((u[:, 8] * len(FACES)).astype(np.intp), len(FACES) - 1)
        else:
            face = cfg.target_face
        self._set_state(index, (position, q, velocity, omega), face, trusted=True)

    def set_state(
        self,
        index: Any,
        position: Any = None,
        orientation: Any = None,
        linear_velocity: Any = None,
        angular_velocity: Any = None,
        target_face: Any = None,
    ) -> None:
        """Hand-built state for envs ``index``: centre of mass (m), orientation (x, y, z, w),
        world linear (m/s) and angular (rad/s) velocity, target face (name or index); each
        broadcasts over ``index``; ``None`` keeps the current value. Starts a new episode:
        hold timer, reward terms, touchdown count and previous action are cleared, and a box
        placed touching the ground does not count a touchdown."""
        index = np.asarray(index, dtype=np.intp)
        values = (position, orientation, linear_velocity, angular_velocity)
        self._set_state(index, values, target_face, trusted=False)

    def _set_state(
        self, index: np.ndarray, values: tuple[Any, ...], target_face: Any, trusted: bool
    ) -> None:
        """:meth:`set_state` with ``values`` in ``STATE_FIELDS`` order; ``trusted``: they come
        from :meth:`reset_envs` (no checks, see ``HoldTask._edited_state``)."""
        state = self._edited_state(index, trusted, **dict(zip(STATE_FIELDS, values, strict=True)))
        if target_face is not None:
            face = _face_index(target_face)
            self.face[index] = np.broadcast_to(face, (len(index),))
            self._face_normal[index] = FACE_NORMALS[self.face[index]]  # changes only here
        self.state = state
        self._start_episode(index)
        self.touchdowns[index] = 0
        self._measure(index)
        self.touching[index] = self._clearance[index] < self.config.contact_tolerance

    # --- stepping -------------------------------------------------------------------------------

    def _advance(self, torque: np.ndarray) -> None:
        """Step the physics for one action (``frame_skip`` steps, the torque fixed in the body
        frame, one simulator call) and keep which envs' contacts carried an impulse during
        the period (``ContactReport.touched``, merged over its physics steps: a bounce that
        begins and ends within one physics step counts) for :meth:`_step_events`."""
        self.state = self.scene.step(
            self.state, body_torque=torque[:, None, :], steps=self.frame_skip
        )
        report = self.scene.report.get("contacts")
        touched = None if report is None else report.touched
        self._touched = self._no_contact_report if touched is None else touched

    def _step_events(self) -> None:
        """Count a touchdown when the box touched the ground during this action period (a
        contact impulse, or the lowest corner within ``contact_tolerance`` at its end: the
        clearance :meth:`_measure` just wrote) after a period in which it did not; a touchdown
        after the first is a bounce and sets the bounce term."""
        kernels.count_touchdowns(
            self._clearance,
            self.config.contact_tolerance,
            self._touched,
            self.touching,
            self.touchdowns,
            self.config.bounce_weight,
            self._task_terms,
        )

    def _measure(self, index: np.ndarray) -> None:
        """Everything the observation, reward and info read off the state of envs ``index``:
        one compiled call (``kernels.landing_measure``)."""
        state = self.state
        kernels.landing_measure(
            index,
            state.position,
            state.orientation,
            state.linear_velocity,
            state.angular_velocity,
            self._face_normal,
            self.corners,
            self.inertia,
            self._params,
            self.prev_action,
            self._obs,
            self._rot,
            self._meas,
            self._ints,
            self._within_goal,
            self._task_terms,
        )

    @property
    def _clearance(self) -> np.ndarray:
        """(N,) the lowest corner's height, m."""
        return self._meas[:, 7]

    @property
    def _down_face(self) -> np.ndarray:
        """(N,) the face nearest down, index into FACES."""
        return self._ints[:, 1]

    def _task_info(self) -> dict[str, np.ndarray]:
        meas = self._meas
        return {
            "angle_error": meas[:, 3].copy(),
            "spin": meas[:, 4].copy(),
            "speed": meas[:, 5].copy(),
            "height": meas[:, 6].copy(),
            "clearance": meas[:, 7].copy(),
            "contact_count": self._ints[:, 0].copy(),
            "touchdowns": self.touchdowns.copy(),
            "bounces": np.maximum(self.touchdowns - 1, 0),
            "down_face": self._ints[:, 1].copy(),
            "target_face": np.array(self.face),
            "energy": meas[:, 8].copy(),
        }

    def _task_single_info(self) -> dict[str, Any]:
        angle, spin, speed, height, clearance, energy = self._meas[0, 3:9].tolist()
        contact_count, down_face = self._ints[0].tolist()
        touchdowns = self.touchdowns.item()
        return {
            "angle_error": angle,
            "spin": spin,
            "speed": speed,
            "height": height,
            "clearance": clearance,
            "contact_count": contact_count,
            "touchdowns": touchdowns,
            "bounces": max(touchdowns - 1, 0),
            "down_face": down_face,
            "target_face": self.face.item(),
            "energy": energy,
        }

    # --- rendering ------------------------------------------------------------------------------

    def view(self) -> View:
        # Frames the throw: the ground around the drop point and the highest start in view.
        top = self.config.height_range[1]
        look_at = np.array([0.0, 0.0, 0.5 * top])
        eye = look_at + (1.9 * top + 0.4) * np.array([0.55, -0.8, 0.24])
        return View(
            Camera(tuple(eye), look_at=tuple(look_at), fov_deg=40.0),
            ground=True,
            ground_extent=2.0 + top,
            ground_cell=0.25,
        )

    def _target_pose(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """The nearest resting pose on the target face: the box turned by the shortest rotation
        that brings the face's normal to world −z, set down where it is."""
        rot = self._rot[i]
        normal = FACE_NORMALS[self.face[i]]
        n_world = rot @ normal
        down = np.array([0.0, 0.0, -1.0])
        axis = np.cross(n_world, down)
        sin, cos = np.linalg.norm(axis), float(n_world @ down)
        if sin < 1e-9:
            axis, angle = np.array([1.0, 0.0, 0.0]), (0.0 if cos > 0 else np.pi)
        else:
            axis, angle = axis / sin, math.atan2(sin, cos)
        align = kernels.rotation_matrices(quat_from_axis_angle(axis, np.array(angle))[None])[0]
        position = np.array(
            [*self.state.position[i, 0, :2], abs(normal @ self.body.shape.half_extents)]
        )
        return align @ rot, position

    def frame(self, i: int) -> Frame:
        axes = 1.4 * float(np.max(self.body.shape.half_extents))
        body = Item(
            self.mesh,
            self._rot[i],
            self.state.position[i, 0],
            color=(214, 178, 92),
            axes_length=axes,
        )
        ghost_rot, ghost_pos = self._target_pose(i)
        ghost = Item(self.mesh, ghost_rot, ghost_pos, axes_length=axes)
        text = (
            f"target face {FACES[self.face[i]]}   down {FACES[self._down_face[i]]}",
            f"face error {np.degrees(self._angle[i]):6.1f} deg   height {self.state.position[i, 0, 2]:5.2f} m",
            f"spin {self._spin[i]:5.2f} rad/s   bounces {max(self.touchdowns[i] - 1, 0)}   {self.status(i)}",
        )
        return Frame(bodies=(body,), ghosts=(ghost,), text=text)


class BoxLandingEnv(TaskEnv):
    __doc__ = __doc__
    task_class = BoxLandingTask


class BoxLandingVectorEnv(TaskVectorEnv):
    """Native vector version of :class:`BoxLandingEnv` (one batched simulator step for all)."""

    task_class = BoxLandingTask
    default_max_episode_steps = MAX_EPISODE_STEPS
