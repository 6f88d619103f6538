"""Seeded, batched evaluation episodes: all episodes run side by side in one native vector env.

Episode ``i`` of a run seeded ``s`` is the first episode of sub-env ``i`` of a vector env seeded
``s``, which equals a single env reset with seed ``s + i`` (the vector env's contract), so the
figures do not depend on how many episodes run at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import gymnasium as gym
import numpy as np

import rigid_env  # noqa: F401  (registers the ids)

Policy = Callable[[np.ndarray], np.ndarray]  # (N, obs_dim) -> (N, act_dim)


@dataclass
class Episodes:
    """Per-episode results, each an array over episodes."""

    returns: np.ndarray
    lengths: np.ndarray
    success: np.ndarray  # is_success at the episode's last step
    final_info: dict[str, np.ndarray]  # every info entry at the episode's last step

    def summary(self) -> dict[str, float]:
        out = {
            "episodes": int(len(self.returns)),
            "mean_return": float(np.mean(self.returns)),
            "std_return": float(np.std(self.returns)),
            "success_rate": float(np.mean(self.success)),
            "mean_length": float(np.mean(self.lengths)),
        }
        for key, value in self.final_info.items():
            if value.ndim == 1 and value.dtype.kind in "fiu" and key != "is_success":
                out[f"final_{key}_mean"] = float(np.mean(value))
        if "down_face" in self.final_info and "target_face" in self.final_info:  # BoxLanding
            on_target = self.final_info["down_face"] == self.final_info["target_face"]
            out["on_target_face_rate"] = float(np.mean(on_target))
        return out


def make_vec(env_id: str, num_envs: int, **env_kwargs: Any) -> gym.vector.VectorEnv:
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **env_kwargs
    )


def run_episodes(
    env_id: str,
    policy: Policy | Callable[[gym.vector.VectorEnv], Policy],
    episodes: int,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    policy_needs_env: bool = False,
) -> Episodes:
    """Run ``episodes`` seeded episodes of ``policy`` at once; ``policy_needs_env``: ``policy`` is
    a factory called with the vector env (e.g. to read its action space or constants)."""
    envs = make_vec(env_id, episodes, **(env_kwargs or {}))
    try:
        if policy_needs_env:
            act = cast(Callable[[gym.vector.VectorEnv], Policy], policy)(envs)
        else:
            act = cast(Policy, policy)
        obs, _ = envs.reset(seed=seed)
        returns = np.zeros(episodes)
        lengths = np.zeros(episodes, dtype=np.int64)
        running = np.ones(episodes, dtype=bool)
        final: dict[str, np.ndarray] = {}
        while running.any():
            obs, reward, terminated, truncated, info = envs.step(act(obs))
            returns += np.where(running, reward, 0.0)
            lengths += running
            done = running & (terminated | truncated)
            for key, value in info.items():
                if key.startswith("_"):
                    continue
                value = np.asarray(value)
                if key not in final:
                    final[key] = np.zeros_like(value)
                final[key][done] = value[done]
            running &= ~done
        return Episodes(returns, lengths, final["is_success"].astype(bool), final)
    finally:
        envs.close()
