"""Step rates of an environment: single env, native vector env, and the physics share of each.

    python -m rigid_env.bench.env_speed RigidEnv/BoxLanding-v0 --num-envs 1024 --seconds 10

Both envs run random actions (with their resets) for about ``--seconds`` each. The simulator's
``Scene.step`` is timed by its public per-stage timer (``scene.timer = StageTimer()``), so the
report separates the physics from the environment's own overhead (observation, reward, info,
validation, resets). :func:`run` is the
one env-speed loop of the benchmarks (``rigid_env.bench.speed`` uses it too).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env import cli
from rigid_env.sim import StageTimer

PROG = "python -m rigid_env.bench.env_speed"
MIN_SECONDS = 0.01  # long enough for at least one step to be timed

ACTION_POOL = 64  # random actions drawn before timing and cycled, so drawing is not timed


@dataclass(frozen=True)
class EnvRate:
    """What :func:`run` measured: env steps (sub-env steps for a vector env) and times."""

    env_steps: int
    wall_s: float
    physics_s: float

    @property
    def steps_per_s(self) -> float:
        return self.env_steps / self.wall_s

    @property
    def physics_share(self) -> float:
        return self.physics_s / self.wall_s


def _timed_scene(env: Any) -> StageTimer:
    """Attach a public per-stage timer to the task's scene; its ``step_seconds`` is the physics."""
    timer = env.unwrapped.task.scene.timer = StageTimer()
    return timer


def run(
    env: gym.Env | gym.vector.VectorEnv,
    *,
    steps: int | None = None,
    seconds: float | None = None,
    seed: int = 0,
    warmup: int = 2,
) -> EnvRate:
    """Step ``env`` (single or native vector) with random actions for ``steps`` calls or about
    ``seconds``, resetting a single env when its episode ends (a vector env autoresets), after
    ``warmup`` untimed steps."""
    if (steps is None) == (seconds is None):
        raise ValueError("steps: give exactly one of steps and seconds")
    vector = isinstance(env, gym.vector.VectorEnv)
    n = env.num_envs if isinstance(env, gym.vector.VectorEnv) else 1
    space = env.action_space
    if not isinstance(space, gym.spaces.Box):
        raise ValueError(f"env must have a Box action space, got {space}")
    rng = np.random.default_rng(seed)
    actions = rng.uniform(space.low, space.high, (ACTION_POOL, *space.shape)).astype(space.dtype)
    env.reset(seed=seed)
    for a in actions[:warmup]:
        env.step(a)
    physics = _timed_scene(env)
    limit = np.inf if seconds is None else seconds
    count = 0
    start = time.perf_counter()
    while count != steps and time.perf_counter() - start < limit:
        _, _, terminated, truncated, _ = env.step(actions[count % ACTION_POOL])
        if not vector and (terminated or truncated):
            env.reset()
        count += 1
    return EnvRate(count * n, time.perf_counter() - start, physics.step_seconds)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("env_id", type=cli.env_id)
    parser.add_argument("--num-envs", type=cli.positive_int, default=1024)
    parser.add_argument("--seconds", type=cli.positive_float, default=10.0)
    parser.add_argument("--seed", type=cli.nonnegative_int, default=0)
    args = parser.parse_args(argv)
    if args.seconds < MIN_SECONDS:
        raise cli.UsageError(f"--seconds must be at least {MIN_SECONDS}, got {args.seconds}")

    single = run(gym.make(args.env_id), seconds=args.seconds, seed=args.seed)
    per_step = 1e3 * single.wall_s / single.env_steps
    print(
        f"single env      : {single.steps_per_s:10.1f} steps/s  ({per_step:.2f} ms/step, "
        f"physics {1e3 * single.physics_s / single.env_steps:.2f} ms = {single.physics_share:.0%})"
    )
    vec_env = gym.make_vec(
        args.env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point"
    )
    vec = run(vec_env, seconds=args.seconds, seed=args.seed)
    batch_ms = 1e3 * vec.wall_s * args.num_envs / vec.env_steps
    print(
        f"vector env x{args.num_envs:<5d}: {vec.steps_per_s:10.1f} env-steps/s  "
        f"({batch_ms:.1f} ms/batch step, physics {vec.physics_share:.0%})  "
        f"= {vec.steps_per_s / single.steps_per_s:.0f}x the single env"
    )
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
