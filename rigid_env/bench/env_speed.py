"""Step rates of an environment: single env, native vector env, and the physics share of each.

    python -m rigid_env.bench.env_speed RigidEnv/BoxLanding-v0 --num-envs 1024 --seconds 10

Both envs run random actions (with their resets) for about ``--seconds`` each. The simulator's
``Scene.step`` is timed by its public per-stage timer (``scene.timer = StageTimer()``), so the
report separates the physics from the environment's own overhead (observation, reward, info,
validation, resets).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env.sim import StageTimer


def _timed_scene(env) -> StageTimer:
    """Attach a public per-stage timer to the task's scene; its ``step_seconds`` is the physics."""
    timer = env.unwrapped.task.scene.timer = StageTimer()
    return timer


def _run(env, action_space, seconds: float, seed: int) -> tuple[int, float, float]:
    physics = _timed_scene(env)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        action = rng.uniform(action_space.low, action_space.high).astype(action_space.dtype)
        _, _, terminated, truncated, _ = env.step(action)
        if np.ndim(terminated) == 0 and (terminated or truncated):
            env.reset()
        steps += 1
    return steps, time.perf_counter() - start, physics.step_seconds


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env_id")
    parser.add_argument("--num-envs", type=int, default=1024)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    single = gym.make(args.env_id)
    steps, wall, physics = _run(single, single.action_space, args.seconds, args.seed)
    single_rate = steps / wall
    print(
        f"single env      : {single_rate:10.1f} steps/s  ({1e3 * wall / steps:.2f} ms/step, "
        f"physics {1e3 * physics / steps:.2f} ms = {physics / wall:.0%})"
    )
    vec = gym.make_vec(args.env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point")
    steps, wall, physics = _run(vec, vec.action_space, args.seconds, args.seed)
    vec_rate = steps * args.num_envs / wall
    print(
        f"vector env x{args.num_envs:<5d}: {vec_rate:10.1f} env-steps/s  "
        f"({1e3 * wall / steps:.1f} ms/batch step, physics {physics / wall:.0%})  "
        f"= {vec_rate / single_rate:.0f}x the single env"
    )


if __name__ == "__main__":
    main()
