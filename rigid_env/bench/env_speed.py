"""Step rates of environments: single env, native vector env, and the physics share of each.

    python -m rigid_env.bench.env_speed RigidEnv/BoxLanding-v0 --num-envs 1024 --seconds 10
    python -m rigid_env.bench.env_speed --seconds 5      # both RigidEnv envs beside Hopper-v5
    python -m rigid_env.bench.env_speed --backend compiled-threads   # the batch over the cores
    python -m rigid_env.bench.env_speed --randomise --num-envs 64   # per-env physics drawn

Every env runs random actions (with its resets) for about ``--seconds`` per measurement. The
simulator's ``Scene.step`` is timed by its public per-stage timer (``scene.timer =
StageTimer()``), so the report separates the physics from the environment's own overhead
(observation, reward, info, validation, resets). ``--peer`` (default ``Hopper-v5``, Gymnasium's
MuJoCo env, when ``gymnasium[mujoco]`` is installed; ``none`` to skip) is run the same way as a
single env in the same process, and each env's single rate is printed as a ratio to it.
:func:`run` is the one env-speed loop of the benchmarks (``rigid_env.bench.speed`` uses it too).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env import cli, resources
from rigid_env.sim import BACKENDS, StageTimer

PROG = "python -m rigid_env.bench.env_speed"
MIN_SECONDS = 0.01  # long enough for at least one step to be timed

ACTION_POOL = 64  # random actions drawn before timing and cycled, so drawing is not timed
RIGID_ENVS = ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0")
PEER = "Hopper-v5"  # Gymnasium's MuJoCo v5 hopper: the reference single-env rate
# ``--randomise``: every physical parameter each env draws per episode (its mass, inertia and
# ground), over the ranges a domain-randomised training would use.
RANDOMISED = {
    "RigidEnv/Reorient-v0": dict(mass_scale_range=(0.5, 2.0), inertia_scale_range=(0.8, 1.25)),
    "RigidEnv/BoxLanding-v0": dict(
        mass_scale_range=(0.5, 2.0),
        inertia_scale_range=(0.8, 1.25),
        friction_range=(0.2, 1.0),
        restitution_range=(0.0, 0.6),
    ),
}


@dataclass(frozen=True)
class EnvRate:
    """What :func:`run` measured: env steps (sub-env steps for a vector env) and times."""

    env_steps: int
    wall_s: float
    physics_s: float  # NaN for an env that is not a rigid_env task (a peer)

    @property
    def steps_per_s(self) -> float:
        return self.env_steps / self.wall_s

    @property
    def physics_share(self) -> float:
        return self.physics_s / self.wall_s


def _timed_scene(env: Any) -> StageTimer | None:
    """Attach a public per-stage timer to the task's scene; its ``step_seconds`` is the physics.
    None for an env without a rigid_env task (a peer such as Hopper-v5)."""
    task = getattr(env.unwrapped, "task", None)
    if task is None:
        return None
    timer = task.scene.timer = StageTimer()
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
    wall = time.perf_counter() - start
    return EnvRate(count * n, wall, math.nan if physics is None else physics.step_seconds)


def peer_env(env_id: str) -> gym.Env | None:
    """``gymnasium.make(env_id)``, or None when it cannot be made here (e.g. Hopper-v5 without
    ``gymnasium[mujoco]``); the reason is printed."""
    try:
        return gym.make(env_id)
    except (gym.error.Error, ImportError) as err:
        print(f"peer {env_id}: not run ({type(err).__name__}: {err})")
        return None


def _peer_engine() -> str:
    try:
        import mujoco
    except ImportError:
        return f"gymnasium {gym.__version__}"
    return f"gymnasium {gym.__version__}, MuJoCo {mujoco.__version__}"


def _single_line(rate: EnvRate) -> str:
    per_step = 1e6 * rate.wall_s / rate.env_steps
    physics = ""
    if not math.isnan(rate.physics_s):
        own = 1e6 * (rate.wall_s - rate.physics_s) / rate.env_steps  # the env layer's own cost
        physics = (
            f", physics {1e6 * rate.physics_s / rate.env_steps:.1f} µs = {rate.physics_share:.0%}"
            f", env layer {own:.1f} µs"
        )
    return f"single env      : {rate.steps_per_s:10.1f} steps/s  ({per_step:.1f} µs/step{physics})"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument(
        "env_id", type=cli.env_id, nargs="*", help=f"default: {' and '.join(RIGID_ENVS)}"
    )
    parser.add_argument("--num-envs", type=cli.positive_int, default=1024)
    parser.add_argument("--seconds", type=cli.positive_float, default=10.0)
    parser.add_argument("--seed", type=cli.nonnegative_int, default=0)
    parser.add_argument(
        "--peer", default=PEER, help=f"single env measured beside, default {PEER}; none: skip"
    )
    parser.add_argument(
        "--backend",
        choices=BACKENDS,
        help="the RigidEnv envs' backend argument (default: RIGID_ENV_BACKEND, else compiled)",
    )
    parser.add_argument(
        "--randomise",
        action="store_true",
        help="draw each env's mass, inertia and ground per episode (RANDOMISED)",
    )
    args = parser.parse_args(argv)
    if args.seconds < MIN_SECONDS:
        raise cli.UsageError(f"--seconds must be at least {MIN_SECONDS}, got {args.seconds}")
    for env_id in args.env_id or RIGID_ENVS:
        resources.check_envs(env_id, args.num_envs, "--num-envs")

    singles = {}
    kwargs = {} if args.backend is None else {"backend": args.backend}
    for env_id in args.env_id or RIGID_ENVS:
        if args.randomise and env_id not in RANDOMISED:
            raise cli.UsageError(f"--randomise: no randomised physics defined for {env_id}")
    for env_id in args.env_id or RIGID_ENVS:
        print(env_id + (" (randomised physics)" if args.randomise else ""))
        made = dict(kwargs, **RANDOMISED[env_id]) if args.randomise else kwargs
        single = run(gym.make(env_id, **made), seconds=args.seconds, seed=args.seed)
        singles[env_id] = single
        print(_single_line(single))
        vec_env = gym.make_vec(
            env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point", **made
        )
        vec = run(vec_env, seconds=args.seconds, seed=args.seed)
        batch_ms = 1e3 * vec.wall_s * args.num_envs / vec.env_steps
        print(
            f"vector env x{args.num_envs:<5d}: {vec.steps_per_s:10.1f} env-steps/s  "
            f"({batch_ms:.1f} ms/batch step, physics {vec.physics_share:.0%})  "
            f"= {vec.steps_per_s / single.steps_per_s:.0f}x the single env"
        )
    peer = None if args.peer.lower() == "none" else peer_env(args.peer)
    if peer is not None:
        print(f"{args.peer} (peer: {_peer_engine()}, single env)")
        rate = run(peer, seconds=args.seconds, seed=args.seed)
        print(_single_line(rate))
        for env_id, single in singles.items():
            print(
                f"{env_id} single / {args.peer} single: "
                f"{single.steps_per_s / rate.steps_per_s:.2f}x"
            )
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
