"""One batched task core behind both the single and the native vector environment.

A :class:`BatchedTask` holds ``N`` copies of a task as numpy arrays with a leading env axis: the
scene is built once, stepping is one simulator call for all ``N``, and observation, reward,
termination and info are batched expressions. :class:`TaskEnv` is a Gymnasium ``Env`` over a
batch of one; :class:`TaskVectorEnv` a Gymnasium ``VectorEnv`` over a batch of ``N``. Because both
run the same code on the same arrays, a vector env equals ``N`` single envs bit for bit when each
sub-env draws its resets from its own generator:

* a single env draws from ``env.np_random`` (Gymnasium's ``seeding.np_random(seed)``);
* the vector env seeded with ``s`` gives sub-env ``i`` the generator ``seeding.np_random(s + i)``
  (or ``seeding.np_random(seed[i])`` for a list of seeds), so it matches single envs seeded
  ``s + i``.

Each reset draws a fixed-length vector of random numbers per env (:meth:`BatchedTask.draw`, the
only per-env Python loop, run only for the envs being reset) and turns the stacked draws into
states in one batched expression (:meth:`BatchedTask.reset_envs`).

Randomness after a reset comes from the same generator, in the same order: a task with
observation noise draws each observation's noise from it (:mod:`~rigid_env.envs.noise`), after
the reset's draws at a reset, so the equality holds with noise too.

The vector env follows Gymnasium 1.x ``AutoresetMode.NEXT_STEP``: the step after an episode ends
resets that sub-env, ignores its action and returns its reset observation and info with reward 0
and both flags ``False``. It truncates itself after ``max_episode_steps`` (``make_vec`` adds no
``TimeLimit``; the env's ``spec.max_episode_steps`` says this limit).

``reset(options=...)`` takes a dict of the task's start keys (``start_options``: parts of the
start state, each replacing what the reset drew; the draws are made all the same, so the
generator's stream does not depend on the options) and, for the vector env, ``reset_mask``.
Anything else raises ``ValueError`` naming it, before the env changes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .display import Display
from .noise import noisy_observation
from .rendering import CameraConfig, Frame, View
from .validation import action_batch, choice, positive_int


def _is_seed(value: Any) -> bool:
    """A seed Gymnasium's ``seeding.np_random`` accepts: an int >= 0 (not a bool)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and bool(value >= 0)


def _options(options: Any, known: Sequence[str]) -> dict[str, Any]:
    """``options`` as a dict whose keys are all in ``known``; else a ``ValueError`` naming it."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"options must be a dict or None, got {options!r}")
    for key in options:
        if key not in known:
            raise ValueError(f"options: unknown key {key!r}; this env's reset takes {tuple(known)}")
    return dict(options)


class BatchedTask(ABC):
    """``num_envs`` copies of a task; every array has the env axis first.

    Subclasses set ``single_observation_space``, ``single_action_space`` and ``render_fps`` in
    ``__init__`` and implement the abstract methods. ``scene`` (a :class:`rigid_env.sim.Scene`)
    is rebuilt by :meth:`build_scene` after unpickling, since its force terms are closures.
    """

    num_envs: int
    observation_structure: dict[str, int]  # part name -> size, in order (Gymnasium v5 style)
    single_observation_space: spaces.Box
    single_action_space: spaces.Box
    render_fps: float
    # Observation noise: the flat observation's entries that get noise and their standard
    # deviations (None: none); :func:`noise.noisy_observation` applies them.
    noise_index: np.ndarray | None = None
    noise_std: np.ndarray | None = None
    start_options: tuple[str, ...] = ()  # the keys reset(options=...) takes

    @abstractmethod
    def build_scene(self) -> Any:
        """The task's :class:`rigid_env.sim.Scene`, built from the validated configuration (a
        task with randomised physics gives each env its row of ``sim.Parameters``)."""

    @abstractmethod
    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """The random numbers one env consumes at one reset, as a 1-D array of fixed length."""

    @abstractmethod
    def reset_envs(self, index: np.ndarray, draws: np.ndarray) -> None:
        """Reset the envs ``index`` from their stacked draws ``(len(index), D)``, batched."""

    @abstractmethod
    def set_state(self, index: Any, *args: Any, **state: Any) -> None:
        """Put envs ``index`` in a hand-built state (task-specific keywords), as at a reset."""

    def check_start(self, options: Mapping[str, Any], k: int) -> dict[str, Any]:
        """The ``reset`` options (keys of ``start_options``) for ``k`` envs, checked (a
        ``ValueError`` names ``options[key]``) before anything changes; :meth:`set_state`
        takes what this returns. Tasks with start options override it."""
        if options:
            raise ValueError(f"options: this env's reset takes no start keys, got {options!r}")
        return {}

    @abstractmethod
    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply validated actions ``(N, *action_shape)`` in [-1, 1]; return reward, terminated."""

    @abstractmethod
    def observation(self) -> np.ndarray:
        """Fresh ``(N, *obs_shape)`` float32 array."""

    @abstractmethod
    def info(self) -> dict[str, np.ndarray]:
        """Fresh arrays with the env axis first (what users plot), incl. ``is_success``."""

    def single_info(self) -> dict[str, Any]:
        """:meth:`info` of a batch of one as a single env returns it (Python scalars for
        per-env scalars, fresh arrays otherwise); tasks may override it with a cheaper path."""
        return _single_info(self.info())

    @abstractmethod
    def view(self) -> View:
        """Scenery (ground or not) for the renderer; the env sets its size."""

    @abstractmethod
    def default_camera(self) -> CameraConfig:
        """The camera of ``default_camera_config``'s keys that the user does not give."""

    def camera_target(self, i: int) -> np.ndarray:
        """The point a camera without ``lookat`` follows for env ``i``: the origin by default."""
        return np.zeros(3)

    @abstractmethod
    def frame(self, i: int) -> Frame:
        """What to draw for env ``i``: bodies, ghosts, text."""

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.pop("scene", None)
        if state.get("parameters") is not None:  # (they belong to the scene: rebuilt with it)
            state["_parameter_values"] = state["parameters"].values()
            state["parameters"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        values = state.pop("_parameter_values", None)
        self.__dict__.update(state)
        self.scene = self.build_scene()
        if values is not None:
            self.parameters = self.scene.parameters(**values)


def _single_info(info: dict[str, np.ndarray]) -> dict[str, Any]:
    """Element 0 of a batched info: Python scalars for per-env scalars, fresh arrays otherwise."""
    return {k: (v[0].item() if v.ndim == 1 else v[0]) for k, v in info.items()}


class TaskEnv(gym.Env):
    """A Gymnasium ``Env`` over a :class:`BatchedTask` with a batch of one.

    Subclasses set ``task_class``; keyword arguments other than ``render_mode``, ``width``,
    ``height`` and ``default_camera_config`` (see :mod:`~rigid_env.envs.display`) go to it.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}
    task_class: Callable[..., BatchedTask]

    def __init__(
        self,
        render_mode: str | None = None,
        width: int | None = None,
        height: int | None = None,
        default_camera_config: Mapping[str, Any] | None = None,
        **task_kwargs: Any,
    ):
        self.render_mode = choice(
            render_mode, "render_mode", (None, *self.metadata["render_modes"])
        )
        self.task = self.task_class(1, **task_kwargs)
        self._display = Display(self.task, self.render_mode, width, height, default_camera_config)
        self.observation_space = self.task.single_observation_space
        self.action_space = self.task.single_action_space
        self.observation_structure = dict(self.task.observation_structure)
        self.metadata = {**type(self).metadata, "render_fps": self.task.render_fps}
        self._action_shape = (1, *self.action_space.shape)
        self._index = np.zeros(1, dtype=np.intp)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        start = self.task.check_start(_options(options, self.task.start_options), 1)
        super().reset(seed=seed)
        self.task.reset_envs(self._index, self.task.draw(self.np_random)[None])
        if start:
            self.task.set_state(self._index, **start)
        return self._observe_and_render()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = action_batch(action, self._action_shape[1:], "action")[None]
        reward, terminated = self.task.step(action)
        obs, info = self._observe_and_render()
        return obs, float(reward[0]), bool(terminated[0]), False, info

    def _observe(self) -> tuple[np.ndarray, dict[str, Any]]:
        """The observation (noisy if the task has noise: then the clean one is in ``info``)."""
        task = self.task
        obs, info = task.observation(), task.single_info()
        if task.noise_index is not None:
            noise = self.np_random.standard_normal(len(task.noise_index))[None]
            info["observation_clean"] = obs[0]
            obs = noisy_observation(obs, noise, task)
        return obs[0], info

    def _observe_and_render(self) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def set_state(self, **state: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Put the env in a hand-built state (see the task's ``set_state``); returns obs, info.

        Counts as the start of an episode (hold timers and the previous action are cleared).
        """
        self.task.set_state(self._index, **state)
        return self._observe()

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode to make()")
            return None
        return self._display.draw(self.task, 0)

    def close(self) -> None:
        self._display.close()


class TaskVectorEnv(VectorEnv):
    """A native Gymnasium ``VectorEnv`` over a :class:`BatchedTask` of ``num_envs``.

    Subclasses set ``task_class`` and ``default_max_episode_steps``.
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 20,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }
    task_class: Callable[..., BatchedTask]
    default_max_episode_steps: int

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        width: int | None = None,
        height: int | None = None,
        default_camera_config: Mapping[str, Any] | None = None,
        **task_kwargs: Any,
    ):
        self.num_envs = positive_int(num_envs, "num_envs")
        if max_episode_steps is None:
            max_episode_steps = self.default_max_episode_steps
        self.max_episode_steps = positive_int(max_episode_steps, "max_episode_steps")
        self.render_mode = choice(
            render_mode, "render_mode", (None, *self.metadata["render_modes"])
        )
        self.task = self.task_class(self.num_envs, **task_kwargs)
        self._display = Display(self.task, self.render_mode, width, height, default_camera_config)
        self.single_observation_space = self.task.single_observation_space
        self.single_action_space = self.task.single_action_space
        self.observation_structure = dict(self.task.observation_structure)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {**type(self).metadata, "render_fps": self.task.render_fps}
        self._action_shape = (self.num_envs, *self.single_action_space.shape)
        self._rngs: list[np.random.Generator] | None = None
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._prev_done = np.zeros(self.num_envs, dtype=bool)
        self._all = np.arange(self.num_envs)
        # With observation noise: the observations last returned (a partial reset returns the
        # other sub-envs' as they were).
        self._noisy: np.ndarray | None = None

    # --- the spec -------------------------------------------------------------------------------

    @property
    def spec(self) -> EnvSpec | None:
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        """``make_vec`` sets the spec of the registered id; its ``max_episode_steps`` is then
        made this env's own limit (``make_vec(..., max_episode_steps=N)`` shows N)."""
        if value is not None and value.max_episode_steps != self.max_episode_steps:
            value = replace(value, max_episode_steps=self.max_episode_steps)
        self._spec = value

    _spec: EnvSpec | None = None

    # --- seeding and resets ---------------------------------------------------------------------

    def _seed(self, seed: Any, index: np.ndarray) -> None:
        """New generators for the sub-envs ``index`` (all others keep theirs), as Gymnasium's
        vector envs seed: ``None`` keeps them (fresh random ones on the first reset), an int
        ``s`` gives sub-env ``i`` the seed ``s + i``, a list gives one seed (or ``None``:
        random) per sub-env. Checked whole before any generator changes."""
        if seed is None:
            if self._rngs is None:
                self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
            return
        if _is_seed(seed):
            seeds: list[Any] = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed) if isinstance(seed, (list, tuple, np.ndarray)) else []
            if len(seeds) != self.num_envs or not all(s is None or _is_seed(s) for s in seeds):
                raise ValueError(
                    f"seed must be None, an int >= 0 or a list of {self.num_envs} such ints "
                    f"(or None for a random one), got {seed!r}"
                )
        rngs = self._rngs
        if rngs is None:
            rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        for i in index:
            rngs[i] = seeding.np_random(None if seeds[i] is None else int(seeds[i]))[0]
        self._rngs = rngs
        if seeds[0] is not None:
            self._np_random, self._np_random_seed = seeding.np_random(int(seeds[0]))

    def _reset_index(self, index: np.ndarray) -> None:
        rngs = self._rngs
        assert rngs is not None, "reset() seeds the generators first"
        draws = np.stack([self.task.draw(rngs[i]) for i in index])
        self.task.reset_envs(index, draws)
        self._steps[index] = 0
        self._prev_done[index] = False

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        opts = _options(options, ("reset_mask", *self.task.start_options))
        mask = opts.pop("reset_mask", None)
        if mask is None:
            index = self._all
        else:
            mask = np.asarray(mask)
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({self.num_envs},) "
                    "with at least one True"
                )
            index = np.flatnonzero(mask)
        start = self.task.check_start(opts, len(index))
        self._seed(seed, index)
        self._reset_index(index)
        if start:
            self.task.set_state(index, **start)
        return self._observe(index)

    def step(
        self, action: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        action = action_batch(action, self._action_shape, "action")
        reward, terminated = self.task.step(action)
        self._steps += 1
        truncated = self._steps >= self.max_episode_steps
        if self._prev_done.any():
            # NEXT_STEP autoreset: these envs ended last step; their action was ignored.
            index = np.flatnonzero(self._prev_done)
            self._reset_index(index)
            reward[index] = 0.0
            terminated[index] = False
            truncated[index] = False
        self._prev_done = terminated | truncated
        obs, info = self._observe(self._all)
        return obs, reward, terminated, truncated, info

    def _observe(self, index: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Observations and info; the sub-envs ``index`` have new observations (with noise,
        each drawn from the sub-env's generator; the clean ones are in ``info``)."""
        task = self.task
        obs, info = task.observation(), task.info()
        if task.noise_index is not None:
            if self._rngs is None:  # a hand-built state before any reset
                self._seed(None, index)
            rngs = self._rngs
            assert rngs is not None
            m = len(task.noise_index)
            noise = np.stack([rngs[i].standard_normal(m) for i in index])
            if self._noisy is None:
                self._noisy = obs.copy()
            self._noisy[index] = noisy_observation(obs[index], noise, task)
            info["observation_clean"] = obs
            obs = self._noisy.copy()
        mask = np.ones(self.num_envs, dtype=bool)
        info.update({"_" + k: mask for k in list(info)})
        return obs, info

    def set_state(
        self, index: Any = None, **state: Any
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Put sub-envs ``index`` (default all) in a hand-built state; returns obs, info."""
        index = self._all if index is None else self._index(index)
        self.task.set_state(index, **state)
        self._steps[index] = 0
        self._prev_done[index] = False
        return self._observe(index)

    def _index(self, index: Any) -> np.ndarray:
        arr = np.atleast_1d(np.asarray(index))
        if (
            arr.ndim != 1
            or arr.size == 0
            or arr.dtype.kind not in "iu"
            or arr.min() < 0
            or arr.max() >= self.num_envs
        ):
            raise ValueError(
                f"index must be a sub-env number or a 1-D array of them in [0, {self.num_envs}), "
                f"got {index!r}"
            )
        return arr.astype(np.intp)

    # --- rendering ------------------------------------------------------------------------------

    def render(self) -> tuple[np.ndarray | None, ...] | None:  # type: ignore[override]
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode to make_vec()")
            return None
        return tuple(self._display.draw(self.task, i) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        self._display.close()
