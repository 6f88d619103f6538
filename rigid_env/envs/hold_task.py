"""The shared core of body-torque tasks with a hold-time goal (Reorient, BoxLanding).

One rigid body, driven by a saturated torque about its own axes (reaction wheels, thrusters),
must reach a goal region of its state and stay there for ``hold_time``. What every such task
shares lives here: the configuration and its validation (:class:`HoldTaskConfig`), stepping with
a body-fixed torque, the hold timer, success and termination, the reward terms common to all
(spin, control effort, success bonus), the named observation layout, ``info`` and the frame's
status text. A task subclasses :class:`HoldTask` (and its config) and supplies only what differs:
the start distribution, the measurements, the observation parts, its own reward terms and the
goal region.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from .. import sim
from . import kernels
from .bodies import MAX_MASS, make_body
from .core import BatchedTask
from .noise import noise_entries
from .observations import observation_slices
from .validation import (
    at_most,
    choice,
    finite_array,
    nonnegative_scalar,
    positive_int,
    positive_scalar,
    positive_vector,
    quaternions,
    scalar_range,
)

OBS_LIMIT = 5.0  # scaled velocities in an observation are clipped to ± this
STATE_FIELDS = sim.state.FIELDS  # State.arrays()

# Bounds of the arguments (documented in the envs' argument tables). Past them an episode's
# numbers stop meaning anything (spins of 1e300 rad/s give rewards of -inf), so they are refused.
MAX_DT = 1.0  # s: the contact step keeps its energy guarantee up to here
MAX_FRAME_SKIP = 10_000
MAX_TORQUE = 1e4  # N m, also the top of a randomised episode's limit
MAX_SPIN = 1e3  # rad/s: initial spins and the observation's spin scale
MAX_HOLD_TIME = 1e4  # s
MAX_WEIGHT = 1e6  # every reward weight and the success bonus
MAX_NOISE_STD = 10.0  # observation units (the parts are scaled to within about ±5)
MAX_SCALE = 1e3  # the top of a randomised mass or inertia scale (and 1/it the bottom)

Bounds = tuple[float | tuple[float, ...], float | tuple[float, ...]]


def weight(value: Any, name: str) -> float:
    """A reward weight: non-negative, at most :data:`MAX_WEIGHT`."""
    return at_most(nonnegative_scalar(value, name), name, MAX_WEIGHT)


def unit_quaternions(q: Any) -> np.ndarray:
    """``q / |q|`` along the last axis: the arithmetic of ``validation.quaternions`` without its
    checks, for values a task computed itself."""
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@dataclass(frozen=True, kw_only=True, eq=False)
class HoldTaskConfig:
    """Arguments every body-torque hold task takes, validated when the config is built.

    Each bad value raises ``ValueError`` naming the argument. Subclasses add their own fields
    (and may change the defaults) and extend :meth:`__post_init__`. ``rigid_body`` is the body
    the task simulates, built from ``body``/``half_extents``/``mass``/``inertia``.
    """

    # Class-level defaults of the body and the integrators the task's scene accepts.
    default_half_extents: ClassVar[tuple[float, float, float]] = (0.3, 0.2, 0.1)
    default_mass: ClassVar[float] = 1.0
    body_shapes: ClassVar[tuple[type, ...] | None] = None
    integrators: ClassVar[tuple[str, ...]] = sim.INTEGRATORS
    observation_parts: ClassVar[tuple[str, ...]] = ()  # what observation_noise may name

    body: sim.Body | None = None
    half_extents: Any = None
    mass: float | None = None
    inertia: Any = None
    integrator: str = sim.DEFAULT_INTEGRATOR
    dt: float = 0.025
    frame_skip: int = 2
    max_torque: Any = 1.0
    spin_range: tuple[float, float] = (0.0, 2.0)
    hold_time: float = 1.0
    terminate_on_success: bool = True
    spin_weight: float = 0.1
    action_weight: float = 0.01
    success_bonus: float = 10.0
    spin_scale: float | None = None
    backend: str | None = None
    # Randomisation and noise (off by default). Each range is drawn once per episode from the
    # reset's generator, after the start state's draws, so a default episode is unchanged.
    torque_scale_range: tuple[float, float] | None = None
    mass_scale_range: tuple[float, float] | None = None
    inertia_scale_range: tuple[float, float] | None = None
    observation_noise: Mapping[str, float] | None = None
    rigid_body: sim.Body = field(init=False, repr=False)

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put(
            "rigid_body",
            make_body(
                self.body,
                self.half_extents,
                self.mass,
                self.inertia,
                default_half_extents=self.default_half_extents,
                default_mass=self.default_mass,
                shapes=self.body_shapes,
            ),
        )
        put("integrator", choice(self.integrator, "integrator", self.integrators))
        put("dt", at_most(positive_scalar(self.dt, "dt"), "dt", MAX_DT, " s"))
        frame_skip = positive_int(self.frame_skip, "frame_skip")
        put("frame_skip", int(at_most(frame_skip, "frame_skip", MAX_FRAME_SKIP)))
        torque = positive_vector(self.max_torque, "max_torque", maximum=MAX_TORQUE)
        put("max_torque", tuple(torque.tolist()))
        put("spin_range", scalar_range(self.spin_range, "spin_range", maximum=MAX_SPIN))
        hold_time = nonnegative_scalar(self.hold_time, "hold_time")
        put("hold_time", at_most(hold_time, "hold_time", MAX_HOLD_TIME, " s"))
        if not isinstance(self.terminate_on_success, (bool, np.bool_)):
            raise ValueError(
                f"terminate_on_success must be a bool, got {self.terminate_on_success!r}"
            )
        put("terminate_on_success", bool(self.terminate_on_success))
        for name in ("spin_weight", "action_weight", "success_bonus"):
            put(name, weight(getattr(self, name), name))
        if self.spin_scale is not None:
            scale = positive_scalar(self.spin_scale, "spin_scale")
            put("spin_scale", at_most(scale, "spin_scale", MAX_SPIN, " rad/s"))
        if self.backend is not None:
            put("backend", choice(self.backend, "backend", sim.BACKENDS))
        if self.torque_scale_range is not None:
            low, high = scalar_range(self.torque_scale_range, "torque_scale_range")
            if low <= 0:
                raise ValueError(
                    f"torque_scale_range must start above 0, got {self.torque_scale_range!r}"
                )
            if max(self.max_torque) * high > MAX_TORQUE:
                raise ValueError(
                    f"torque_scale_range: max_torque × its high end must be at most "
                    f"{MAX_TORQUE:g} N m, got {self.torque_scale_range!r}"
                )
            put("torque_scale_range", (low, high))
        for name in ("mass_scale_range", "inertia_scale_range"):
            value = getattr(self, name)
            if value is None:
                continue
            low, high = scalar_range(value, name, maximum=MAX_SCALE)
            if low < 1 / MAX_SCALE:
                raise ValueError(f"{name} must start at {1 / MAX_SCALE:g} or above, got {value!r}")
            put(name, (low, high))
        if self.mass_scale_range is not None:
            at_most(
                self.rigid_body.mass * self.mass_scale_range[1],
                "mass_scale_range (mass × its high end)",
                MAX_MASS,
                " kg",
            )
        if self.observation_noise is not None:
            put("observation_noise", self._noise(self.observation_noise))

    def _noise(self, value: Any) -> dict[str, float]:
        """``observation_noise`` as ``part -> std`` in the observation's order."""
        if not isinstance(value, Mapping):
            raise ValueError(
                f"observation_noise must be a dict of observation part -> standard deviation "
                f"(parts {self.observation_parts}), got {value!r}"
            )
        for part in value:
            if part not in self.observation_parts:
                raise ValueError(
                    f"observation_noise: unknown observation part {part!r}; the parts are "
                    f"{self.observation_parts}"
                )
        stds = {}
        for part in self.observation_parts:
            if part in value:
                name = f"observation_noise[{part!r}]"
                std = nonnegative_scalar(value[part], name)
                stds[part] = at_most(std, name, MAX_NOISE_STD)
        return stds

    @property
    def observed_spin_scale(self) -> float:
        """Ω is observed as Ω / this: ``spin_scale``, or by default the fastest initial spin
        (the top of ``spin_range``) but at least 1 rad/s, so the spin starts within ±1."""
        return self.spin_scale if self.spin_scale is not None else max(self.spin_range[1], 1.0)

    @property
    def action_period(self) -> float:
        return self.dt * self.frame_skip

    @property
    def hold_steps(self) -> int:
        """Steps within the goal before success; at least one, so success needs the state."""
        return max(1, math.ceil(self.hold_time / self.action_period - 1e-9))


class HoldTask(BatchedTask):
    """Batched core of a body-torque task with a hold-time goal.

    Subclasses set ``config_class``, ``observation_bounds`` (an ordered ``name -> (low, high)``
    per part; a part's size is that of its bounds), ``task_reward_terms`` and
    ``start_options``, and implement :meth:`build_scene`, :meth:`draw_start`,
    :meth:`reset_start`, :meth:`set_state`, :meth:`_measure`, :meth:`_task_info`,
    :meth:`_task_single_info`, :meth:`view`, :meth:`default_camera` and :meth:`frame`, and may
    override :meth:`_step_events` and :meth:`_check_value`; the task allocates ``_meas`` (its
    width is its own) and :meth:`set_state` ends with :meth:`_start_episode`, then
    ``_measure(index)``.

    A reset draws the start state (:meth:`draw_start`), then the episode's randomised
    parameters (one uniform each, in the order of ``RANDOMISED`` among those configured),
    from the env's generator; with no randomisation nothing more is drawn, so the default
    episodes do not depend on it. The torque limit scales the action. A physical parameter
    (mass, inertia, the ground's friction and restitution) makes the env's physics its own:
    the scene then steps every env with its own row of ``sim.Parameters`` (``parameters``),
    rewritten for the envs a reset draws for, still one simulator call for the batch.

    The per-step work is compiled (``kernels``): the task's :meth:`_measure` reads everything
    off the state in one call, and the shared hold timer and reward terms are one more. Its
    buffers are allocated once; :meth:`observation` and :meth:`info` return copies, so nothing
    a step returns is overwritten by the next.
    """

    config_class: ClassVar[type[HoldTaskConfig]] = HoldTaskConfig
    # Config range → the ``info`` key of its per-episode value, in the order they are drawn.
    RANDOMISED: ClassVar[dict[str, str]] = {
        "torque_scale_range": "torque_limit",
        "mass_scale_range": "mass_scale",
        "inertia_scale_range": "inertia_scale",
    }
    observation_bounds: ClassVar[Mapping[str, Bounds]]
    task_reward_terms: ClassVar[tuple[str, ...]]

    config: HoldTaskConfig
    state: sim.State
    # What _measure(index) writes, rows index (buffers allocated once, in __init__; what leaves
    # the task is a copy):
    _rot: np.ndarray  # (N, 3, 3) R(q)
    _meas: np.ndarray  # (N, M): Ω (body axes, 3), angle error, |Ω|, then the task's own
    _obs: np.ndarray  # (N, obs size) float32, in the order of observation_bounds
    _within_goal: np.ndarray  # (N,) bool
    _task_terms: np.ndarray  # (N, len(task_reward_terms)), the task's own reward terms

    def __init__(self, num_envs: int, config: HoldTaskConfig | None = None, **kwargs: Any):
        self.num_envs = positive_int(num_envs, "num_envs")
        if config is None:
            config = self.config_class(**kwargs)
        elif kwargs:
            raise ValueError(f"config: give either config or keyword arguments, not both {kwargs}")
        elif not isinstance(config, self.config_class):
            raise ValueError(f"config must be a {self.config_class.__name__}, got {config!r}")
        self.config = config
        self.body = config.rigid_body
        self.inertia = np.array(self.body.inertia)  # body axes, symmetric
        self.dt, self.frame_skip = config.dt, config.frame_skip
        self.max_torque = np.array(config.max_torque)  # the nominal limit, N m per body axis
        self.spin_scale = config.observed_spin_scale
        self.hold_steps = config.hold_steps
        self.render_fps = 1.0 / config.action_period
        self.scene = self.build_scene()

        self.observation_structure = self.structure()
        self._slices = observation_slices(self.observation_structure)
        size = sum(self.observation_structure.values())
        low, high = np.empty(size, np.float32), np.empty(size, np.float32)
        for name, (lo, hi) in self.observation_bounds.items():
            low[self._slices[name]], high[self._slices[name]] = lo, hi
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        if config.observation_noise is not None:
            entries = noise_entries(config.observation_noise, self._slices)
            if entries is not None:
                self.noise_index, self.noise_std = entries
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.reward_terms = (
            *self.task_reward_terms,
            "reward_spin",
            "reward_ctrl",
            "reward_success",
        )
        # What kernels.hold_step reads: hold_steps, then the shared terms' coefficients
        # (-spin_coef |Ω|, -ctrl_coef |a|², the success bonus).
        self._hold_params = np.array(
            [
                self.hold_steps,
                config.spin_weight / self.spin_scale,
                config.action_weight / 3.0,
                config.success_bonus,
            ],
            dtype=float,
        )

        n = self.num_envs
        # This episode's torque limit per env (N m per body axis): max_torque unless randomised.
        self.torque_limit = np.tile(self.max_torque, (n, 1))
        # This episode's mass properties per env (what the measurements read).
        self.masses = np.full(n, self.body.mass)
        self.inertias = np.tile(self.inertia, (n, 1, 1))
        self.randomised = [name for name in self.RANDOMISED if getattr(config, name) is not None]
        self._random_draws = len(self.randomised)
        self.episode_values: dict[str, np.ndarray] = {  # the physical draws, per env
            self.RANDOMISED[name]: np.ones(n)
            for name in self.randomised
            if name != "torque_scale_range"
        }
        # Per-env model parameters when a physical parameter is randomised (``reset_envs``
        # writes the drawn envs' rows; built at the first reset, which draws for every env).
        self.parameters: sim.Parameters | None = None
        self.prev_action = np.zeros((n, 3))
        self.hold = np.zeros(n, dtype=np.int64)
        self.terms = np.zeros((n, len(self.reward_terms)))  # columns in reward_terms' order
        self._all = np.arange(n)  # _measure's index for every env
        self._rot = np.empty((n, 3, 3))
        self._obs = np.empty((n, size), np.float32)
        self._within_goal = np.empty(n, dtype=bool)
        self._task_terms = np.zeros((n, len(self.task_reward_terms)))

    @classmethod
    def structure(cls) -> dict[str, int]:
        """The observation's named parts, ``name -> size`` in order (``observation_structure``)."""
        return {name: int(np.size(low)) for name, (low, _) in cls.observation_bounds.items()}

    # --- what a task supplies -------------------------------------------------------------------

    @abstractmethod
    def draw_start(self, rng: np.random.Generator) -> np.ndarray:
        """The random numbers one env's start state consumes, as a 1-D array of fixed length."""

    @abstractmethod
    def reset_start(self, index: np.ndarray, draws: np.ndarray) -> None:
        """Put the envs ``index`` in their start states from the stacked draws of
        :meth:`draw_start`, batched (ends as :meth:`set_state` does)."""

    @abstractmethod
    def _measure(self, index: np.ndarray) -> None:
        """Read everything off ``self.state`` (and ``prev_action``) for the envs ``index`` (an
        intp array), writing their rows of the buffers listed on the class: ``_rot``,
        ``_meas``, ``_obs`` (each part clipped to its bounds), ``_within_goal`` and
        ``_task_terms`` (its own reward terms). Other rows keep their values: they belong to
        states that did not change."""

    def _step_events(self) -> None:
        """After a step's :meth:`_measure`: what the task counts per action period (events
        that depend on the previous period as well as on the state); none by default."""

    @abstractmethod
    def _task_info(self) -> dict[str, np.ndarray]:
        """The task's own ``info`` entries (fresh arrays)."""

    @abstractmethod
    def _task_single_info(self) -> dict[str, Any]:
        """Element 0 of :meth:`_task_info` for a batch of one: Python scalars for per-env
        scalars, fresh arrays otherwise (the cheap path of a single env's step)."""

    def _advance(self, torque: np.ndarray) -> None:
        """Step the physics for one action: ``frame_skip`` steps in one simulator call, the
        torque fixed in the body frame (the integrator turns it into the world at each of its
        load evaluations). Tasks with sensors to latch at every physics step override this."""
        self.state = self.scene.step(
            self.state,
            body_torque=torque[:, None, :],
            steps=self.frame_skip,
            parameters=self.parameters,
        )

    def episode_parameters(self, index: np.ndarray) -> dict[str, np.ndarray]:
        """The model parameters of envs ``index`` this episode (``Scene.parameters``' arrays,
        one row per env): the mass scale s makes the body s times denser (mass and inertia
        × s), the inertia scale k moves mass outward (inertia × k). Tasks with a ground add
        its material."""
        return {"mass": self.masses[index, None], "inertia": self.inertias[index, None]}

    # --- shared ---------------------------------------------------------------------------------

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """The start state's draws, then one uniform per randomised parameter."""
        start = self.draw_start(rng)
        if not self._random_draws:
            return start
        return np.concatenate((start, rng.random(self._random_draws)))

    def reset_envs(self, index: np.ndarray, draws: np.ndarray) -> None:
        if self._random_draws:
            u = draws[:, -self._random_draws :]
            draws = draws[:, : -self._random_draws]
            for k, name in enumerate(self.randomised):
                low, high = getattr(self.config, name)
                value = low + (high - low) * u[:, k]
                if name == "torque_scale_range":
                    self.torque_limit[index] = value[:, None] * self.max_torque
                else:
                    self.episode_values[self.RANDOMISED[name]][index] = value
            if self.episode_values:
                values = self.episode_values
                mass = values.get("mass_scale", np.ones(self.num_envs))[index]
                inertia = values.get("inertia_scale", np.ones(self.num_envs))[index]
                self.masses[index] = mass * self.body.mass
                self.inertias[index] = (mass * inertia)[:, None, None] * self.inertia
                if self.parameters is None:
                    self.parameters = self.scene.parameters(**self.episode_parameters(self._all))
                else:
                    self.parameters.update(index, **self.episode_parameters(index))
        self.reset_start(index, draws)

    def check_start(self, options: Mapping[str, Any], k: int) -> dict[str, Any]:
        """Each start option checked by :meth:`_check_value` (named ``options[key]``), as the
        value :meth:`set_state` takes for ``k`` envs."""
        return {
            name: self._check_value(name, value, k, f"options[{name!r}]")
            for name, value in options.items()
        }

    def _check_value(self, name: str, value: Any, k: int, label: str) -> np.ndarray:
        """A hand-built state value for ``k`` envs, checked (``ValueError`` naming ``label``)
        and broadcast to ``(k, width)``: a state field of :data:`STATE_FIELDS` (orientation
        normalised). Tasks extend it with their own keys."""
        width = 4 if name == "orientation" else 3
        arr = quaternions(value, label) if name == "orientation" else finite_array(value, label)
        try:
            return np.array(np.broadcast_to(arr, (k, width)))
        except ValueError:
            raise ValueError(f"{label} must broadcast to ({k}, {width})") from None

    # Views of _meas taken on use (a view kept as an attribute would not survive pickling).
    @property
    def _omega(self) -> np.ndarray:
        """(N, 3) body angular velocity Ω, rad/s."""
        return self._meas[:, 0:3]

    @property
    def _angle(self) -> np.ndarray:
        """(N,) the task's angle error, rad."""
        return self._meas[:, 3]

    @property
    def _spin(self) -> np.ndarray:
        """(N,) |Ω|, rad/s."""
        return self._meas[:, 4]

    def _start_episode(self, index: np.ndarray) -> None:
        """Clear the per-episode memory of envs ``index`` (after a reset or a hand-built state)."""
        self.prev_action[index] = 0.0
        self.hold[index] = 0
        self.terms[index] = 0.0

    def _edited_state(self, index: np.ndarray, trusted: bool = False, **values: Any) -> sim.State:
        """The current state with ``values`` (position, orientation, linear_velocity,
        angular_velocity; ``None`` keeps it) put into envs ``index``, each broadcast over them.
        ``trusted``: the values come from the task's own reset, finite float64 arrays of shape
        ``(len(index), width)``, so only the orientation's normalisation is applied."""
        k = len(index)
        copies = (np.array(a) for a in self.state.arrays())  # copies: states are values
        arrays = dict(zip(STATE_FIELDS, copies, strict=True))
        for name, value in values.items():
            if value is None:
                continue
            if trusted:
                arrays[name][index, 0] = unit_quaternions(value) if name == "orientation" else value
                continue
            arrays[name][index, 0] = self._check_value(name, value, k, name)
        # The other envs keep the contact impulses their next step warm-starts from.
        return self.state.edited(index, **arrays)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply validated ``action`` (N, 3), which the task keeps as ``prev_action`` (the
        caller passes its own copy); reward and terminated are fresh arrays."""
        self._advance(action * self.torque_limit)  # body-frame torque, (N, 3)
        self.prev_action = action
        self._measure(self._all)
        self._step_events()
        n = self.num_envs
        reward, success = np.empty(n), np.empty(n, dtype=bool)
        kernels.hold_step(
            self._within_goal,
            self.hold,
            self._spin,
            action,
            self._hold_params,
            self._task_terms,
            self.terms,
            reward,
            success,
        )
        terminated = success if self.config.terminate_on_success else np.zeros(n, bool)
        return reward, terminated

    def observation(self) -> np.ndarray:
        return self._obs.copy()

    def info(self) -> dict[str, np.ndarray]:
        info = {
            **self._task_info(),
            **{name: self.terms[:, k].copy() for k, name in enumerate(self.reward_terms)},
            "is_success": self.hold >= self.hold_steps,
        }
        if self.config.torque_scale_range is not None:
            info["torque_limit"] = self.torque_limit.copy()
        for key, values in self.episode_values.items():
            info[key] = values.copy()
        return info

    def single_info(self) -> dict[str, Any]:
        info = self._task_single_info()
        info.update(zip(self.reward_terms, self.terms[0].tolist(), strict=True))
        info["is_success"] = bool(self.hold[0] >= self.hold_steps)
        if self.config.torque_scale_range is not None:
            info["torque_limit"] = self.torque_limit[0].copy()
        for key, values in self.episode_values.items():
            info[key] = float(values[0])
        return info

    def status(self, i: int) -> str:
        """Env ``i``'s goal status for the frame's text."""
        if self.hold[i] >= self.hold_steps:
            return "success"
        return "holding" if self.hold[i] else ""
