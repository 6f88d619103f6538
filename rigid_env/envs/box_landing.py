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

``reset(options=...)`` replaces parts of the drawn start (the draws are made all the same, so
later episodes do not depend on the options); a vector env broadcasts each value over the
sub-envs it resets (``options["reset_mask"]``), or takes one row per reset sub-env. Other keys,
and values that are not these, raise ``ValueError`` naming ``options[key]``:

| Key                    | Value                                                               |
|------------------------|---------------------------------------------------------------------|
| ``position``           | centre of mass (3,), m; at least the box's reach above the ground unless ``orientation`` is given too (then no corner deeper than ``contact_tolerance``) |
| ``orientation``        | quaternion (x, y, z, w), body to world (normalised)                 |
| ``linear_velocity``    | (3,) world frame, m/s                                               |
| ``angular_velocity``   | (3,) world frame, rad/s                                             |
| ``target_face``        | one of ``FACES`` or its index                                       |

## Episode End

1. Termination: ``is_success`` (only with ``terminate_on_success=True``, the default).
2. Truncation: ``max_episode_steps`` = 120 steps (4 s with the default 1/30 s action period).

## Info

Every ``reset`` and ``step`` returns ``angle_error`` (θ, rad), ``spin`` (|Ω|, rad/s), ``speed``
(|v|, m/s), ``height`` (centre of mass, m), ``clearance`` (lowest corner, m), ``contact_count``
(corners touching, int), ``touchdowns`` (int), ``bounces`` (touchdowns after the first, int),
``down_face`` (index into ``FACES`` = ("+x", "-x", "+y", "-y", "+z", "-z") of the face now
facing the ground, int), ``target_face`` (index, int), ``energy`` (kinetic + gravitational
m g z, J), ``contact_capped`` (the action periods of this episode in which a contact solve
stopped at its cap instead of converging, int; see below), the reward terms ``reward_*`` (0 at a
reset) and ``is_success`` (``bool``). With ``torque_scale_range``: ``torque_limit`` (the
episode's, (3,), N m); with ``mass_scale_range``, ``inertia_scale_range``, ``friction_range``
or ``restitution_range``: ``mass_scale``, ``inertia_scale``, ``friction`` or ``restitution``
(the episode's, float); with ``observation_noise``: ``observation_clean`` (the observation
without noise).

A capped solve keeps the solver's last iterate for that physics step: contact impulses that
meet the friction and no-penetration conditions only approximately, and no energy gained. It is
rare with the default settings and harmless for training. The env counts it instead of passing
on the simulator's ``ContactSolverWarning``, and warns once per env instance
(``rigid_env.envs.contact_caps.ContactCapWarning``).

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
| ``contact_solver``       | ``CONTACT_SOLVER`` | the contact solve's ``rigid_env.sim.SolverSettings``; the default warm-starts an action's physics steps after its first from the previous step's impulses: the same tolerance as ``SolverSettings()``, for less work |
| ``torque_scale_range``   | ``None``         | ``(low, high)``: each episode's torque limit is ``max_torque`` × s, s uniform in it (one s for the three axes), drawn at the reset |
| ``mass_scale_range``     | ``None``         | ``(low, high)``: each episode's box is s times denser (mass and inertia × s), s uniform in it, drawn at the reset |
| ``inertia_scale_range``  | ``None``         | ``(low, high)``: each episode's inertia × k (its mass moved outward), k uniform in it |
| ``friction_range``       | ``None``         | ``(low, high)``: each episode's ground friction μ, uniform in it (≤ 10) |
| ``restitution_range``    | ``None``         | ``(low, high)``: each episode's ground restitution ε, uniform in it (within [0, 1]); with any of these four, each env steps its own scene (one simulator call per env) |
| ``observation_noise``    | ``None``         | ``{part: std}``: Gaussian noise added to those observation parts (std in the part's units, table above), clipped to the observation space; ``info["observation_clean"]`` keeps the observation without it |
| ``render_mode``          | ``None``         | ``"human"`` or ``"rgb_array"`` (vector env: ``"rgb_array"``) |
| ``width``, ``height``    | ``480``, ``480`` | frame size, pixels                                        |
| ``default_camera_config`` | ``None``        | a dict of ``distance`` (m), ``azimuth`` and ``elevation`` (degrees) and ``lookat`` (a point, m), as in MuJoCo's v5 envs; keys not given keep the default camera, which follows the box (no ``lookat``) from 8 of its reaches away, azimuth 125°, elevation −20° |

Bounds: ``dt`` ≤ 1 s, ``frame_skip`` ≤ 10 000, ``max_torque`` (and its randomised value) ≤
10⁴ N m, ``spin_range``, ``spin_scale`` and ``spin_threshold`` ≤ 1000 rad/s,
``height_range`` ≤ 10 m (the altimeter's range), the velocity ranges and ``speed_threshold``
within ±100 m/s, ``friction`` ≤ 10, ``face_threshold`` ≤ π, ``contact_tolerance`` ≤ 1 m,
``hold_time`` ≤ 10⁴ s, every weight and the bonus ≤ 10⁶, ``mass`` ≤ 10⁶ kg, noise std ≤ 10,
``width`` and ``height`` ≤ 4096. Beyond them an episode's numbers stop meaning anything (a torque
of 1e300 N m gave rewards of −inf), so they are refused.

Randomisation draws from the env's generator once per episode, after the start state, so it is
reproducible from the reset seed (a vector sub-env ``i`` seeded ``s + i`` as before), and with
none configured nothing more is drawn: the default episodes are unchanged.

Why these defaults: the box is the simulator's landing scene. A fall of 1–2 m takes 0.45–0.64 s
before the first touchdown; at 1 N m the wheels turn the box by π about its largest axis in
about 0.6 s (bang-bang, 2 √(π I / τ)), so turning the target face down in flight is feasible from
most throws but not from all, and braking the initial spin takes part of that time (the analytic
controller, ``python -m agents.evaluate --env RigidEnv/BoxLanding-v0 --policy analytic``,
succeeds in most seeded evaluation episodes, zero torque in few; the docs' results page has the
figures). Resting,
the wheels tip the box over an edge only if τ > m g d, d the horizontal distance from the
centre of mass to that edge: 0.98 N m off the ±y and ±z faces about their 0.1 m edges, so a bad
policy can topple a box standing on its target, but 1.96 N m onto the −z face (d = 0.2 m): with
the default target, a box at rest on a wrong face never reaches the target face.

The arguments other than ``render_mode``, ``width``, ``height`` and
``default_camera_config`` form a :class:`BoxLandingConfig` (a frozen dataclass,
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
from . import contact_caps, kernels
from .core import TaskEnv, TaskVectorEnv
from .hold_task import (
    MAX_SPIN,
    OBS_LIMIT,
    STATE_FIELDS,
    Bounds,
    HoldTask,
    HoldTaskConfig,
    weight,
)
from .rendering import CameraConfig, Frame, Item, Mesh, View
from .validation import (
    at_most,
    choice,
    nonnegative_scalar,
    positive_scalar,
    scalar_range,
    unit_interval,
)

MAX_EPISODE_STEPS = 120
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
FACE_NORMALS = np.array(
    [[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
)  # outward normals in body axes, in the order of FACES
GRAVITY = 9.81  # m/s², down
VELOCITY_SCALE = 5.0  # m/s: the observed linear velocity is v / VELOCITY_SCALE
HEIGHT_LIMIT = 10.0  # m: observed height and clearance are clipped to [0, this]
MAX_SPEED = 100.0  # m/s: the bound of the initial velocity ranges and speed_threshold
MAX_FRICTION = 10.0
MAX_CONTACT_TOLERANCE = 1.0  # m
OBSERVATION_BOUNDS: dict[str, Bounds] = {
    "height": (0.0, HEIGHT_LIMIT),
    "clearance": (0.0, HEIGHT_LIMIT),
    "linear_velocity": ((-OBS_LIMIT,) * 3, (OBS_LIMIT,) * 3),
    "up": ((-1.0,) * 3, (1.0,) * 3),
    "angular_velocity": ((-OBS_LIMIT,) * 3, (OBS_LIMIT,) * 3),
    "target_normal": ((-1.0,) * 3, (1.0,) * 3),
    "corner_contacts": ((0.0,) * 8, (1.0,) * 8),
    "previous_action": ((-1.0,) * 3, (1.0,) * 3),
}


def _lerp(bounds: tuple[float, float], u: np.ndarray) -> np.ndarray:
    return bounds[0] + (bounds[1] - bounds[0]) * u


def box_reach(body: sim.Body) -> float:
    """The farthest corner of the body's box from its centre of mass, m."""
    corners = np.array(body.shape.vertices)
    return float(np.max(np.linalg.norm(corners, axis=1)))


def _face_index(value: Any, name: str = "target_face") -> np.ndarray | int:
    """A face name or index (or an array of indices) as index into :data:`FACES`."""
    if isinstance(value, str):
        return FACES.index(str(choice(value, name, FACES)))
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu" or np.any((arr < 0) | (arr >= len(FACES))):
        raise ValueError(f"{name} must be one of {FACES} or an index 0..5, got {value!r}")
    return arr.astype(np.intp)


# The contact solve of this task's scene (see ``contact_solver`` in the module docstring):
# warm-started, as an action's physics steps start where the previous one ended; it converges
# to the same tolerance as a cold solve, with no more capped solves, for less work.
CONTACT_SOLVER = sim.SolverSettings(warm_start=True)


@dataclass(frozen=True, kw_only=True, eq=False)
class BoxLandingConfig(HoldTaskConfig):
    """The arguments of BoxLanding-v0 (table in the module docstring), validated."""

    default_half_extents: ClassVar[tuple[float, float, float]] = LANDING_HALF_EXTENTS
    default_mass: ClassVar[float] = 1.0
    body_shapes: ClassVar[tuple[type, ...] | None] = (sim.Box,)
    integrators: ClassVar[tuple[str, ...]] = sim.CONTACT_CAPABLE
    observation_parts: ClassVar[tuple[str, ...]] = tuple(OBSERVATION_BOUNDS)

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
    friction_range: tuple[float, float] | None = None
    restitution_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()

        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("restitution", unit_interval(self.restitution, "restitution"))
        friction = nonnegative_scalar(self.friction, "friction")
        put("friction", at_most(friction, "friction", MAX_FRICTION))
        reach = box_reach(self.rigid_body)
        put("height_range", scalar_range(self.height_range, "height_range", maximum=HEIGHT_LIMIT))
        if self.height_range[0] <= reach:
            raise ValueError(
                f"height_range must start above the box's reach {reach:.3f} m (its corners "
                f"would start in the ground), got {self.height_range!r}"
            )
        put(
            "vertical_velocity_range",
            scalar_range(
                self.vertical_velocity_range, "vertical_velocity_range", -MAX_SPEED, MAX_SPEED
            ),
        )
        put(
            "horizontal_speed_range",
            scalar_range(self.horizontal_speed_range, "horizontal_speed_range", maximum=MAX_SPEED),
        )
        put("tilt_range", scalar_range(self.tilt_range, "tilt_range"))
        if self.tilt_range[1] > math.pi:
            raise ValueError(f"tilt_range must lie within [0, π], got {self.tilt_range!r}")
        if self.target_face != "random":
            put("target_face", FACES[int(_face_index(self.target_face))])
        bounds = {
            "face_threshold": (math.pi, " rad"),
            "speed_threshold": (MAX_SPEED, " m/s"),
            "spin_threshold": (MAX_SPIN, " rad/s"),
            "contact_tolerance": (MAX_CONTACT_TOLERANCE, " m"),
        }
        for name, (maximum, unit) in bounds.items():
            put(name, at_most(positive_scalar(getattr(self, name), name), name, maximum, unit))
        for name in ("face_weight", "bounce_weight"):
            put(name, weight(getattr(self, name), name))
        if self.friction_range is not None:
            put(
                "friction_range",
                scalar_range(self.friction_range, "friction_range", maximum=MAX_FRICTION),
            )
        if self.restitution_range is not None:
            put(
                "restitution_range",
                scalar_range(self.restitution_range, "restitution_range", maximum=1.0),
            )
        if not isinstance(self.contact_solver, sim.SolverSettings):
            raise ValueError(
                f"contact_solver must be a rigid_env.sim.SolverSettings, got {self.contact_solver!r}"
            )


class BoxLandingTask(HoldTask):
    """Batched core of BoxLanding-v0; arguments as in the module docstring."""

    config_class = BoxLandingConfig
    config: BoxLandingConfig
    RANDOMISED = {
        **HoldTask.RANDOMISED,
        "friction_range": "friction",
        "restitution_range": "restitution",
    }
    observation_bounds = OBSERVATION_BOUNDS
    task_reward_terms = ("reward_angle", "reward_bounce")
    start_options = (*STATE_FIELDS, "target_face")
    env_name = "RigidEnv/BoxLanding-v0"

    def __init__(self, num_envs: int, config: BoxLandingConfig | None = None, **kwargs: Any):
        super().__init__(num_envs, config, **kwargs)
        cfg = self.config
        self.corners = np.array(self.body.shape.vertices)  # (8, 3) body axes
        self.reach = box_reach(self.body)
        self.random_face = cfg.target_face == "random"
        self.mesh = Mesh.from_shape(self.body.shape)

        n = self.num_envs
        self.state = self.scene.initial_state(
            position=(0.0, 0.0, cfg.height_range[0]), batch_shape=(n,)
        )
        self.face = np.full(n, FACES.index("-z" if self.random_face else str(cfg.target_face)))
        self._face_normal = FACE_NORMALS[self.face]
        self.touchdowns = np.zeros(n, dtype=np.int64)
        self.contact_capped = np.zeros(n, dtype=np.int64)  # capped action periods per episode
        self.warned_capped = False  # the once-per-env ContactCapWarning
        self._no_contact_report = np.zeros(n, dtype=bool)  # touched, for a scene without one
        self._touched = self._no_contact_report
        for key, nominal in (("friction", cfg.friction), ("restitution", cfg.restitution)):
            if key in self.episode_values:
                self.episode_values[key][:] = nominal
        self._params = np.array(  # what landing_measure reads, in its order
            [
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
        """The scene of the configured body and ground (an episode's randomised physics is a
        row of ``parameters``: :meth:`episode_parameters`)."""
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

    def episode_parameters(self, index: np.ndarray) -> dict[str, np.ndarray]:
        """The body's (``HoldTask.episode_parameters``), and the ground's friction and
        restitution of envs ``index`` this episode."""
        rows = super().episode_parameters(index)
        cfg = self.config
        for key, nominal in (("friction", cfg.friction), ("restitution", cfg.restitution)):
            values = self.episode_values.get(key)
            rows[key] = np.full(len(index), nominal) if values is None else values[index]
        return rows

    # --- resets ---------------------------------------------------------------------------------

    def draw_start(self, rng: np.random.Generator) -> np.ndarray:
        # Uniforms: [height, v_z, horizontal speed, its direction, spin, cos tilt, α, γ, face];
        # Gaussians: [spin direction (3)].
        return np.concatenate((rng.random(9), rng.standard_normal(3)))

    def reset_start(self, index: np.ndarray, draws: np.ndarray) -> None:
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
        hold timer, reward terms, touchdown and capped-solve counts and previous action are
        cleared, and a box placed touching the ground does not count a touchdown. A box whose
        lowest corner would lie deeper than ``contact_tolerance`` in the ground is refused."""
        index = np.asarray(index, dtype=np.intp)
        values = (position, orientation, linear_velocity, angular_velocity)
        self._set_state(index, values, target_face, trusted=False)

    def _check_value(self, name: str, value: Any, k: int, label: str) -> np.ndarray:
        if name != "target_face":
            return super()._check_value(name, value, k, label)
        try:
            return np.array(np.broadcast_to(_face_index(value, label), (k,)))
        except ValueError as e:
            if label in str(e):
                raise
            raise ValueError(f"{label} must broadcast to ({k},)") from None

    def check_start(self, options: Any, k: int) -> dict[str, Any]:
        """The reset options checked; a ``position`` without an ``orientation`` (which the
        reset draws) must be at least the box's reach above the ground."""
        start = super().check_start(options, k)
        if "position" in start and "orientation" not in start:
            low = float(np.min(start["position"][:, 2]))
            if low < self.reach:
                raise ValueError(
                    f"options['position'] must be at least the box's reach {self.reach:.3f} m "
                    f"above the ground when the orientation is drawn (or give "
                    f"options['orientation'] too), got a height of {low!r} m"
                )
        elif "position" in start:
            self._check_above_ground(start["position"], start["orientation"], "options")
        return start

    def _check_above_ground(
        self, position: np.ndarray, orientation: np.ndarray, label: str
    ) -> None:
        """``ValueError`` naming ``label`` if a pose ((k, 3) positions, (k, 4) unit quaternions)
        puts a corner of the box deeper in the ground than ``contact_tolerance``."""
        rot = kernels.rotation_matrices(np.ascontiguousarray(orientation))
        # A corner's height is z + (R c)_z: R's last row dotted with the corner.
        low = position[:, 2] + np.min(rot[:, 2, :] @ self.corners.T, axis=1)
        if np.any(low < -self.config.contact_tolerance):
            raise ValueError(
                f"{label}: the position and orientation put a corner of the box "
                f"{-float(np.min(low)):.3g} m deep in the ground (at most contact_tolerance "
                f"= {self.config.contact_tolerance:g} m)"
            )

    def _set_state(
        self, index: np.ndarray, values: tuple[Any, ...], target_face: Any, trusted: bool
    ) -> None:
        """:meth:`set_state` with ``values`` in ``STATE_FIELDS`` order; ``trusted``: they come
        from :meth:`reset_start` (no checks, see ``HoldTask._edited_state``)."""
        state = self._edited_state(index, trusted, **dict(zip(STATE_FIELDS, values, strict=True)))
        if not trusted and (values[0] is not None or values[1] is not None):
            pose = (state.position[index, 0], state.orientation[index, 0])
            self._check_above_ground(*pose, "position")
        if target_face is not None:
            face = _face_index(target_face)
            self.face[index] = np.broadcast_to(face, (len(index),))
            self._face_normal[index] = FACE_NORMALS[self.face[index]]  # changes only here
        self.state = state
        self._start_episode(index)
        self.touchdowns[index] = 0
        self.contact_capped[index] = 0
        self._measure(index)
        self.touching[index] = self._clearance[index] < self.config.contact_tolerance

    # --- stepping -------------------------------------------------------------------------------

    def _advance(self, torque: np.ndarray) -> None:
        """Step the physics for one action (``frame_skip`` steps, the torque fixed in the body
        frame, one simulator call) and keep which envs' contacts carried an impulse during
        the period (the returned state's ``ContactReport.touched``, merged over its physics steps: a bounce that
        begins and ends within one physics step counts) for :meth:`_step_events`. A period
        with a capped contact solve is counted per env (``contact_capped``) and warned once
        (:mod:`~rigid_env.envs.contact_caps`)."""
        self.state = contact_caps.step_quietly(
            self.scene,
            self.state,
            body_torque=torque[:, None, :],
            steps=self.frame_skip,
            parameters=self.parameters,
        )
        report = self.state.report.get("contacts")
        touched = None if report is None else report.touched
        capped = contact_caps.capped_mask(report)
        self._touched = self._no_contact_report if touched is None else touched
        if capped is not None:
            self.contact_capped += capped
            if not self.warned_capped:
                self.warned_capped = True
                contact_caps.warn_capped(self.env_name)

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
            self.masses,
            self.inertias,
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
            "contact_capped": self.contact_capped.copy(),
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
            "contact_capped": self.contact_capped.item(),
        }

    # --- rendering ------------------------------------------------------------------------------

    def view(self) -> View:
        return View(ground=True, ground_extent=2.0 + self.config.height_range[1], ground_cell=0.25)

    def default_camera(self) -> CameraConfig:
        """A camera that follows the box (``lookat`` unset) from a little above, at a
        distance of 8 of the box's reach: the box fills about a third of the frame's height."""
        return CameraConfig(
            distance=8.0 * self.reach, azimuth=125.0, elevation=-20.0, lookat=None, fov_deg=40.0
        )

    def camera_target(self, i: int) -> np.ndarray:
        return np.array(self.state.position[i, 0])

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
