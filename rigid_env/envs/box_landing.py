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
world axes (z up).

| Num   | Observation                                            | Min | Max | Unit             |
|-------|--------------------------------------------------------|-----|-----|------------------|
| 0     | height of the centre of mass                           | 0   | 10  | m                |
| 1     | clearance: height of the lowest corner                 | 0   | 10  | m                |
| 2–4   | linear velocity (world) / 5 m/s                        | -5  | 5   | (m/s)/(m/s)      |
| 5–7   | up direction (world +z) in body axes (an IMU's gravity) | -1  | 1   |                  |
| 8–10  | body angular velocity Ω / ``spin_scale``                | -5  | 5   | (rad/s)/(rad/s)  |
| 11–13 | target face outward normal in body axes (±e_x, ±e_y, ±e_z) | -1 | 1 |               |
| 14–21 | corner touch flags (1 when within ``contact_tolerance`` of the ground), corners in the order of ``sim.Box.vertices`` (index 4 i_x + 2 i_y + i_z, i = 0 for −, 1 for +) | 0 | 1 | |
| 22–24 | previous action                                        | -1  | 1   | ``max_torque``   |

Height and clearance are bounded below by the ground (a resting contact may sink by rounding:
the clearance is clipped at 0) and clipped at 10 m above. The velocities are clipped: a default
throw starts within ±0.4 scaled units and a 2 m fall adds 6.3 m/s (1.3 units); torque can spin
the box up without limit, which a sensible policy avoids. ``info`` carries the values unclipped.

## Rewards

Per step, with θ the angle between the target face's outward normal and world −z (0 when the
box stands on it), Ω the body angular velocity, a the action:

| Term     | Value                                               | Default weight         |
|----------|-----------------------------------------------------|------------------------|
| face     | ``-face_weight · θ / π``                            | ``face_weight=1``      |
| spin     | ``-spin_weight · |Ω| / spin_scale``                 | ``spin_weight=0.05``   |
| bounce   | ``-bounce_weight`` at each touchdown after the first | ``bounce_weight=0.5``  |
| effort   | ``-action_weight · |a|² / 3``                        | ``action_weight=0.01`` |
| success  | ``+success_bonus`` on every step ``is_success`` holds | ``success_bonus=10``  |

The face term is linear in θ so its pull does not fade near the goal; the spin term is small
because turning the box in flight needs spin. A *touchdown* is an action period in which the
box touched the ground after a period in which it did not (the touch switches are latched at
every physics step, so a bounce shorter than a period still counts if it spans one). Every term
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
m g z, J) and ``is_success`` (``bool``).

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
| ``render_mode``          | ``None``         | ``"human"`` or ``"rgb_array"`` (vector env: ``"rgb_array"``) |

Why these defaults: the box is the simulator's landing scene. A fall of 1–2 m takes 0.45–0.64 s
before the first touchdown; at 1 N m the wheels turn the box by π about its largest axis in
about 0.6 s (bang-bang, 2 √(π I / τ)), so turning the target face down in flight is feasible from
most throws but not from all, and braking the initial spin takes part of that time (a saturated
PD law on the face error succeeds in about 9 episodes of 10, zero torque in 1 of 25). Resting,
the wheels tip the box over an edge only if τ > m g d, d the horizontal distance from the
centre of mass to that edge: 0.98 N m off the ±y and ±z faces about their 0.1 m edges, so a bad
policy can topple a box standing on its target, but 1.96 N m onto the −z face (d = 0.2 m): with
the default target, a box at rest on a wrong face never reaches the target face.

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

import numpy as np
from gymnasium import spaces

from .. import sim
from ..sim.rotation import quat_from_axis_angle, quat_multiply
from ..sim.scenes import LANDING_HALF_EXTENTS
from .bodies import make_body
from .core import BatchedTask, TaskEnv, TaskVectorEnv, step_body_torque
from .kinematics import apply_transpose, rotation_matrices
from .rendering import Camera, Frame, Item, Mesh, View
from .validation import (
    choice,
    finite_array,
    nonnegative_scalar,
    positive_int,
    positive_scalar,
    positive_vector,
    scalar_range,
)

MAX_EPISODE_STEPS = 120
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
FACE_NORMALS = np.array(
    [[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
)  # outward normals in body axes, in the order of FACES
GRAVITY = 9.81  # m/s², down
VELOCITY_SCALE = 5.0  # m/s: the observed linear velocity is v / VELOCITY_SCALE
OBS_LIMIT = 5.0  # scaled velocities are clipped to ± this
HEIGHT_LIMIT = 10.0  # m: observed height and clearance are clipped to [0, this]


def _lerp(bounds: tuple[float, float], u: np.ndarray) -> np.ndarray:
    return bounds[0] + (bounds[1] - bounds[0]) * u


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (N, 3) stacks, elementwise (exact whatever the batch size)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _face_index(value, name: str = "target_face") -> np.ndarray | int:
    """A face name or index (or an array of indices) as index into :data:`FACES`."""
    if isinstance(value, str):
        return FACES.index(choice(value, name, FACES))
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu" or np.any((arr < 0) | (arr >= len(FACES))):
        raise ValueError(f"{name} must be one of {FACES} or an index 0..5, got {value!r}")
    return arr.astype(np.intp)


class BoxLandingTask(BatchedTask):
    """Batched core of BoxLanding-v0; arguments as in the module docstring."""

    def __init__(
        self,
        num_envs: int,
        *,
        body: sim.Body | None = None,
        half_extents=None,
        mass=None,
        inertia=None,
        integrator: str = sim.CONTACT_INTEGRATOR,
        dt: float = 1 / 240,
        frame_skip: int = 8,
        restitution: float = 0.3,
        friction: float = 0.5,
        max_torque=1.0,
        height_range=(1.0, 2.0),
        vertical_velocity_range=(-2.0, 1.0),
        horizontal_speed_range=(0.0, 1.0),
        spin_range=(0.0, 3.0),
        tilt_range=(0.0, math.pi),
        target_face: str = "-z",
        face_threshold: float = 0.2,
        speed_threshold: float = 0.05,
        spin_threshold: float = 0.1,
        hold_time: float = 0.5,
        contact_tolerance: float = 0.005,
        terminate_on_success: bool = True,
        face_weight: float = 1.0,
        spin_weight: float = 0.05,
        bounce_weight: float = 0.5,
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
            default_half_extents=LANDING_HALF_EXTENTS,
            default_mass=1.0,
            shapes=(sim.Box,),
        )
        self.integrator = choice(integrator, "integrator", sim.CONTACT_CAPABLE)
        self.dt = positive_scalar(dt, "dt")
        self.frame_skip = positive_int(frame_skip, "frame_skip")
        self.ground = sim.Ground(restitution=restitution, friction=friction)
        self.max_torque = positive_vector(max_torque, "max_torque")
        self.corners = np.array(self.body.shape.vertices)  # (8, 3) body axes
        reach = float(np.max(np.linalg.norm(self.corners, axis=1)))
        self.height_range = scalar_range(height_range, "height_range")
        if self.height_range[0] <= reach:
            raise ValueError(
                f"height_range must start above the box's reach {reach:.3f} m (its corners "
                f"would start in the ground), got {height_range!r}"
            )
        self.vertical_velocity_range = scalar_range(
            vertical_velocity_range, "vertical_velocity_range", minimum=-math.inf
        )
        self.horizontal_speed_range = scalar_range(horizontal_speed_range, "horizontal_speed_range")
        self.spin_range = scalar_range(spin_range, "spin_range")
        self.tilt_range = scalar_range(tilt_range, "tilt_range")
        if self.tilt_range[1] > math.pi:
            raise ValueError(f"tilt_range must lie within [0, π], got {tilt_range!r}")
        self.random_face = target_face == "random"
        self.fixed_face = None if self.random_face else _face_index(target_face)
        self.face_threshold = positive_scalar(face_threshold, "face_threshold")
        self.speed_threshold = positive_scalar(speed_threshold, "speed_threshold")
        self.spin_threshold = positive_scalar(spin_threshold, "spin_threshold")
        self.hold_time = nonnegative_scalar(hold_time, "hold_time")
        self.contact_tolerance = positive_scalar(contact_tolerance, "contact_tolerance")
        if not isinstance(terminate_on_success, (bool, np.bool_)):
            raise ValueError(f"terminate_on_success must be a bool, got {terminate_on_success!r}")
        self.terminate_on_success = bool(terminate_on_success)
        self.face_weight = nonnegative_scalar(face_weight, "face_weight")
        self.spin_weight = nonnegative_scalar(spin_weight, "spin_weight")
        self.bounce_weight = nonnegative_scalar(bounce_weight, "bounce_weight")
        self.action_weight = nonnegative_scalar(action_weight, "action_weight")
        self.success_bonus = nonnegative_scalar(success_bonus, "success_bonus")
        if spin_scale is None:
            spin_scale = max(self.spin_range[1], 1.0)
        self.spin_scale = positive_scalar(spin_scale, "spin_scale")

        self.action_period = self.dt * self.frame_skip
        self.render_fps = 1.0 / self.action_period
        # Steps within the goal before success; at least one so success needs the state.
        self.hold_steps = max(1, math.ceil(self.hold_time / self.action_period - 1e-9))
        self._inertia = np.array(self.body.inertia)
        self.scene = self.build_scene()
        self.mesh = Mesh.from_shape(self.body.shape)

        h, s = HEIGHT_LIMIT, OBS_LIMIT
        high = np.array([h, h, s, s, s, 1, 1, 1, s, s, s, 1, 1, 1, *[1] * 8, 1, 1, 1], np.float32)
        low = -high
        low[0:2] = 0.0
        low[14:22] = 0.0
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)

        n = self.num_envs
        self.state = self.scene.initial_state(
            position=(0.0, 0.0, self.height_range[0]), batch_shape=(n,)
        )
        self.face = np.full(n, FACES.index("-z") if self.fixed_face is None else self.fixed_face)
        self.prev_action = np.zeros((n, 3))
        self.hold = np.zeros(n, dtype=np.int64)
        self.touchdowns = np.zeros(n, dtype=np.int64)
        self._measure()
        self.touching = self._gaps.min(axis=1) < self.contact_tolerance

    def build_scene(self) -> sim.Scene:
        return sim.Scene(
            self.body,
            self.dt,
            integrator=self.integrator,
            gravity=(0.0, 0.0, -GRAVITY),
            ground=self.ground,
        )

    # --- resets ---------------------------------------------------------------------------------

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        # Uniforms: [height, v_z, horizontal speed, its direction, spin, cos tilt, α, γ, face];
        # Gaussians: [spin direction (3)].
        return np.concatenate((rng.random(9), rng.standard_normal(3)))

    def reset_envs(self, index: np.ndarray, draws: np.ndarray) -> None:
        u, g = draws[:, :9], draws[:, 9:]
        k = len(index)
        position = np.zeros((k, 3))
        position[:, 2] = _lerp(self.height_range, u[:, 0])
        heading = 2 * np.pi * u[:, 3]
        speed = _lerp(self.horizontal_speed_range, u[:, 2])
        velocity = np.stack(
            (
                speed * np.cos(heading),
                speed * np.sin(heading),
                _lerp(self.vertical_velocity_range, u[:, 1]),
            ),
            axis=1,
        )
        direction = g / np.linalg.norm(g, axis=1, keepdims=True)
        omega = _lerp(self.spin_range, u[:, 4])[:, None] * direction
        # Haar measure in ZYZ Euler angles: α, γ uniform, cos β uniform (restricted by tilt_range).
        cos_range = (math.cos(self.tilt_range[1]), math.cos(self.tilt_range[0]))
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
            face = np.minimum((u[:, 8] * len(FACES)).astype(np.intp), len(FACES) - 1)
        else:
            face = self.fixed_face
        self.set_state(
            index,
            position=position,
            orientation=q,
            linear_velocity=velocity,
            angular_velocity=omega,
            target_face=face,
        )

    def set_state(
        self,
        index,
        position=None,
        orientation=None,
        linear_velocity=None,
        angular_velocity=None,
        target_face=None,
    ) -> None:
        """Hand-built state for envs ``index``: centre of mass (m), orientation (x, y, z, w),
        world linear (m/s) and angular (rad/s) velocity, target face (name or index); each
        broadcasts over ``index``; ``None`` keeps the current value. Starts a new episode:
        hold timer, touchdown count and previous action are cleared, and a box placed touching
        the ground does not count a touchdown."""
        index = np.asarray(index, dtype=np.intp)
        k = len(index)
        arrays = [np.array(a) for a in self.state.arrays()]  # copies: states are values
        given = (position, orientation, linear_velocity, angular_velocity)
        names = ("position", "orientation", "linear_velocity", "angular_velocity")
        for j, (value, name) in enumerate(zip(given, names, strict=True)):
            if value is None:
                continue
            width = 4 if name == "orientation" else 3
            arr = finite_array(value, name, (width,))
            if name == "orientation":
                norm = np.linalg.norm(arr, axis=-1, keepdims=True)
                if np.any(norm < 1e-12):
                    raise ValueError("orientation must be non-zero quaternions (x, y, z, w)")
                arr = arr / norm
            try:
                arrays[j][index, 0] = np.broadcast_to(arr, (k, width))
            except ValueError:
                raise ValueError(f"{name} must broadcast to ({k}, {width})") from None
        if target_face is not None:
            face = _face_index(target_face)
            self.face = np.array(self.face)
            self.face[index] = np.broadcast_to(face, (k,))
        self.state = sim.State(*arrays)
        self.prev_action[index] = 0.0
        self.hold[index] = 0
        self.touchdowns[index] = 0
        self._measure()
        self.touching = np.array(self.touching)
        self.touching[index] = self._gaps[index].min(axis=1) < self.contact_tolerance

    # --- stepping -------------------------------------------------------------------------------

    def _lowest_corner(self, state: sim.State) -> np.ndarray:
        """Height of the lowest corner, (N,): z + min over corners of (R r)_z, with R's last
        row (2(xz − wy), 2(yz + wx), 1 − 2(x² + y²)) taken straight from q (course notes)."""
        x, y, z, w = state.orientation[:, 0].T
        row = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
        c = self.corners
        heights = row[0][:, None] * c[:, 0] + row[1][:, None] * c[:, 1] + row[2][:, None] * c[:, 2]
        return state.position[:, 0, 2] + heights.min(axis=1)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        torque = action * self.max_torque  # body frame, (N, 3)
        touched = np.zeros(self.num_envs, dtype=bool)

        def latch(state):  # the touch switches, sampled at every physics step
            touched[:] |= self._lowest_corner(state) < self.contact_tolerance
            # A bounce can begin and end within one physics step (impacts are resolved at
            # their instant): the contact report's impulses see it when the positions do not.
            report = self.scene.report.get("contacts")
            if report is not None and report.touched is not None:
                touched[:] |= report.touched

        self.state = step_body_torque(
            self.scene, self.state, self._rot, torque, self.frame_skip, after=latch
        )
        self.prev_action = action
        self._measure()
        touchdown = touched & ~self.touching
        bounce = touchdown & (self.touchdowns > 0)
        self.touchdowns = self.touchdowns + touchdown
        self.touching = touched
        within = (
            (self._contact_count > 0)
            & (self._angle < self.face_threshold)
            & (self._speed < self.speed_threshold)
            & (self._spin < self.spin_threshold)
        )
        self.hold = np.where(within, self.hold + 1, 0)
        success = self.hold >= self.hold_steps
        reward = (
            -(self.face_weight / np.pi) * self._angle
            - (self.spin_weight / self.spin_scale) * self._spin
            - self.bounce_weight * bounce
            - (self.action_weight / 3.0) * _dot(action, action)
            + self.success_bonus * success
        )
        terminated = success if self.terminate_on_success else np.zeros(self.num_envs, bool)
        return reward, terminated

    def _measure(self) -> None:
        """Everything the observation, reward and info read off the current state."""
        x, q, v, w = (a[:, 0] for a in self.state.arrays())
        self._rot = rotation_matrices(q)
        self._up = self._rot[:, 2, :]  # world +z in body axes: Rᵀ e_z is R's last row
        normal = FACE_NORMALS[self.face]
        down = -self._up
        # θ between the target face normal and world −z, by atan2 (arccos loses digits near 0).
        cross = np.cross(normal, down)
        self._angle = np.arctan2(np.sqrt(_dot(cross, cross)), _dot(normal, down))
        self._omega = apply_transpose(self._rot, w)  # Ω = Rᵀ ω
        self._spin = np.sqrt(_dot(self._omega, self._omega))
        self._speed = np.sqrt(_dot(v, v))
        c = self.corners
        self._gaps = (
            x[:, 2:3]
            + self._up[:, 0:1] * c[:, 0]
            + self._up[:, 1:2] * c[:, 1]
            + self._up[:, 2:3] * c[:, 2]
        )
        self._contact = self._gaps < self.contact_tolerance
        self._contact_count = self._contact.sum(axis=1)
        axis = np.argmax(np.abs(down), axis=1)
        positive = np.take_along_axis(down, axis[:, None], axis=1)[:, 0] > 0
        self._down_face = 2 * axis + np.where(positive, 0, 1)

    def observation(self) -> np.ndarray:
        x, _, v, _ = (a[:, 0] for a in self.state.arrays())
        obs = np.empty((self.num_envs, 25), dtype=np.float32)
        obs[:, 0] = np.clip(x[:, 2], 0.0, HEIGHT_LIMIT)
        obs[:, 1] = np.clip(self._gaps.min(axis=1), 0.0, HEIGHT_LIMIT)
        obs[:, 2:5] = np.clip(v / VELOCITY_SCALE, -OBS_LIMIT, OBS_LIMIT)
        obs[:, 5:8] = self._up
        obs[:, 8:11] = np.clip(self._omega / self.spin_scale, -OBS_LIMIT, OBS_LIMIT)
        obs[:, 11:14] = FACE_NORMALS[self.face]
        obs[:, 14:22] = self._contact
        obs[:, 22:25] = self.prev_action
        return obs

    def info(self) -> dict[str, np.ndarray]:
        x, _, v, _ = (a[:, 0] for a in self.state.arrays())
        m = self.body.mass
        body_momentum = self._omega @ self._inertia  # I0 Ω (I0 symmetric)
        energy = 0.5 * (m * _dot(v, v) + _dot(self._omega, body_momentum)) + m * GRAVITY * x[:, 2]
        return {
            "angle_error": self._angle.copy(),
            "spin": self._spin.copy(),
            "speed": self._speed.copy(),
            "height": x[:, 2].copy(),
            "clearance": self._gaps.min(axis=1),
            "contact_count": self._contact_count.copy(),
            "touchdowns": self.touchdowns.copy(),
            "bounces": np.maximum(self.touchdowns - 1, 0),
            "down_face": self._down_face.copy(),
            "target_face": np.array(self.face),
            "energy": energy,
            "is_success": self.hold >= self.hold_steps,
        }

    # --- rendering ------------------------------------------------------------------------------

    def view(self) -> View:
        # Frames the throw: the ground around the drop point and the highest start in view.
        top = self.height_range[1]
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
        align = rotation_matrices(quat_from_axis_angle(axis, angle)[None])[0]
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
        status = (
            "success" if self.hold[i] >= self.hold_steps else ("holding" if self.hold[i] else "")
        )
        text = (
            f"target face {FACES[self.face[i]]}   down {FACES[self._down_face[i]]}",
            f"face error {np.degrees(self._angle[i]):6.1f} deg   height {self.state.position[i, 0, 2]:5.2f} m",
            f"spin {self._spin[i]:5.2f} rad/s   bounces {max(self.touchdowns[i] - 1, 0)}   {status}",
        )
        return Frame(bodies=(body,), ghosts=(ghost,), text=text)


class BoxLandingEnv(TaskEnv):
    __doc__ = __doc__
    task_class = BoxLandingTask


class BoxLandingVectorEnv(TaskVectorEnv):
    """Native vector version of :class:`BoxLandingEnv` (one batched simulator step for all)."""

    task_class = BoxLandingTask
    default_max_episode_steps = MAX_EPISODE_STEPS
