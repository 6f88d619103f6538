"""A native Gymnasium ``VectorEnv`` seen as a stable-baselines3 ``VecEnv``, without copies.

SB3 and Gymnasium 1.x disagree on what a step that ends an episode returns:

* SB3 (``VecEnv.step_wait``) resets a finished sub-env *within the same step*: it returns the
  reset observation and puts the final one in ``info["terminal_observation"]`` (and
  ``info["TimeLimit.truncated"] = truncated and not terminated``), so the next action already
  acts in the new episode;
* Gymnasium's ``AutoresetMode.NEXT_STEP`` returns the final observation and resets on the *next*
  step, ignoring that step's action and returning reward 0 with both flags ``False``. Fed to SB3
  as is, that extra step would be a fake transition from the final state to the reset state.

The bridge uses the vector env's partial reset: after a step, the envs that finished are reset
at once with ``reset(options={"reset_mask": done})``. That clears their pending autoreset, so the
next step is a normal step of the new episode and no transition across a reset ever reaches the
learner. ``RigidEnv`` vector envs support it (:class:`rigid_env.envs.core.TaskVectorEnv`); the
adapter checks for the mode it needs at construction.

Seeding follows SB3: ``seed(s)`` gives sub-env ``i`` the seed ``s + i`` at the next ``reset()``,
which is exactly what the native vector env does with ``reset(seed=s)``.

The adapter also times what happens inside the vector env (``env_seconds``), so training can
report the share of wall time spent in the environment and simulator.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn


class GymVectorToSB3(VecEnv):
    """Wrap ``venv`` (a Gymnasium ``VectorEnv`` with ``NEXT_STEP`` autoreset and
    ``reset(options={"reset_mask": mask})``) as an SB3 ``VecEnv``.

    Infos are a list of per-env dicts, built from the vector env's dict of arrays (keys starting
    with ``_`` dropped, per-env scalars as Python scalars).
    """

    def __init__(self, venv: gym.vector.VectorEnv):
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.NEXT_STEP:
            raise ValueError(f"venv: needs autoreset_mode NEXT_STEP with reset_mask, got {mode!r}")
        self.venv = venv
        self.env_seconds = 0.0  # wall time spent inside venv.step / venv.reset
        self.env_steps = 0
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    # --- the VecEnv protocol ---------------------------------------------------------------------

    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        if seeds is not None and any(s is None for s in seeds):
            raise ValueError("seed: give every sub-env a seed or none")
        options = self._options[0] or None
        start = time.perf_counter()
        # Gymnasium's base VectorEnv.reset is typed seed: int, but vector envs with reset_mask
        # (Gymnasium's Sync/Async, RigidEnv's) take a list, one seed per sub-env.
        obs, info = self.venv.reset(seed=seeds, options=options)  # type: ignore[arg-type]
        self.env_seconds += time.perf_counter() - start
        self.reset_infos = self._split(info)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        start = time.perf_counter()
        obs, reward, terminated, truncated, info = self.venv.step(self._actions)
        done = terminated | truncated
        infos = self._split(info)
        if done.any():
            index = np.flatnonzero(done)
            reset_obs, reset_info = self.venv.reset(options={"reset_mask": done})
            reset_split = self._split(reset_info)
            for i in index:
                infos[i]["terminal_observation"] = obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                self.reset_infos[i] = reset_split[i]
            obs = np.array(obs)
            obs[index] = reset_obs[index]
        self.env_seconds += time.perf_counter() - start
        self.env_steps += self.num_envs
        return obs, np.asarray(reward, dtype=np.float32), done, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        # rgb_array frames; Gymnasium types render() with an unbound RenderFrame.
        frames = cast("tuple[np.ndarray, ...] | None", self.venv.render())
        return list(frames) if frames is not None else [None] * self.num_envs

    # The sub-envs are rows of one batched env: attributes belong to the vector env as a whole.
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if indices is not None and len(list(self._get_indices(indices))) != self.num_envs:
            raise ValueError("indices: a batched env's attributes are shared by all sub-envs")
        setattr(self.venv, attr_name, value)

    def env_method(
        self, method_name: str, *args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        if indices is not None and len(list(self._get_indices(indices))) != self.num_envs:
            raise ValueError("indices: a batched env's methods act on all sub-envs at once")
        return [getattr(self.venv, method_name)(*args, **kwargs)]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    # --- helpers ---------------------------------------------------------------------------------

    def _split(self, info: dict[str, Any]) -> list[dict[str, Any]]:
        keys = [k for k in info if not k.startswith("_")]
        columns = [(k, np.asarray(info[k])) for k in keys]
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for k, v in columns:
            rows = v.tolist() if v.ndim == 1 else list(v)
            for i in range(self.num_envs):
                out[i][k] = rows[i]
        return out
