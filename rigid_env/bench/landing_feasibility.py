"""Is BoxLanding-v0 feasible but not trivial? Success rates of a PD law, zero and random torque.

    python -m rigid_env.bench.landing_feasibility --episodes 100 --seed 0 [key=value ...]

Runs the first episode of ``--episodes`` sub-envs of the native vector env (sub-env i is the
single env seeded ``seed + i``) under three policies and prints the share that succeed, their
mean bounces and mean return. Extra ``key=value`` arguments go to ``make_vec`` (numbers are
parsed, e.g. ``max_torque=0.5``). The PD law is a sanity check of the task, not a tuned
controller: it turns the target face's normal n onto the down direction d (both in body axes,
from the observation) about n × d, critically damped per principal axis, and saturates.
"""

from __future__ import annotations

import ast
import sys

import gymnasium as gym
import numpy as np

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env import cli

ID = "RigidEnv/BoxLanding-v0"
PROG = "python -m rigid_env.bench.landing_feasibility"


def face_pd_action(obs: np.ndarray, task, natural_frequency: float = 10.0) -> np.ndarray:
    """Saturated PD torque (actions in [-1, 1]) that turns the target face down and damps spin.

    τ = I (ω_n² θ â − 2 ω_n Ω) per principal axis, with θ the face error and â the unit axis of
    n × d (any axis across n when the box is upside down on its target, θ = π).
    """
    normal, down = obs[:, 11:14].astype(float), -obs[:, 5:8].astype(float)
    axis = np.cross(normal, down)
    sin = np.linalg.norm(axis, axis=1, keepdims=True)
    theta = np.arctan2(sin, np.sum(normal * down, axis=1, keepdims=True))
    axis = np.where(sin > 1e-6, axis / np.maximum(sin, 1e-12), np.roll(normal, 1, axis=1))
    omega = obs[:, 8:11].astype(float) * task.spin_scale
    inertia = np.diag(task._inertia)
    wn = natural_frequency
    torque = inertia * (wn**2 * theta * axis - 2 * wn * omega)
    return np.clip(torque / task.max_torque, -1.0, 1.0)


def first_episodes(policy, episodes: int, seed: int, **kwargs) -> dict[str, float]:
    """Success share, mean bounces and mean return of each sub-env's first episode."""
    env = gym.make_vec(ID, num_envs=episodes, vectorization_mode="vector_entry_point", **kwargs)
    task = env.unwrapped.task
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    done = np.zeros(episodes, bool)
    success = np.zeros(episodes, bool)
    bounces = np.zeros(episodes)
    returns = np.zeros(episodes)
    while not done.all():
        obs, reward, terminated, truncated, info = env.step(
            policy(obs, task, rng).astype(np.float32)
        )
        returns += np.where(done, 0.0, reward)
        bounces = np.where(done, bounces, info["bounces"])
        success |= terminated & ~done
        done |= terminated | truncated
    env.close()
    return {"success": success.mean(), "bounces": bounces.mean(), "return": returns.mean()}


POLICIES = {
    "pd": lambda obs, task, rng: face_pd_action(obs, task),
    "zero": lambda obs, task, rng: np.zeros((len(obs), 3)),
    "random": lambda obs, task, rng: rng.uniform(-1.0, 1.0, (len(obs), 3)),
}


def main(argv=None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=cli.positive_int, default=100)
    parser.add_argument("--seed", type=cli.nonnegative_int, default=0)
    parser.add_argument("kwargs", nargs="*", help="key=value arguments for make_vec")
    args = parser.parse_args(argv)
    kwargs = {}
    for item in args.kwargs:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise cli.UsageError(f"expected key=value arguments for make_vec, got {item!r}")
        try:
            kwargs[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            kwargs[key] = value
    try:  # the env checks its own arguments: try them once on a one-env instance
        gym.make_vec(ID, num_envs=1, vectorization_mode="vector_entry_point", **kwargs).close()
    except (TypeError, ValueError) as error:
        raise cli.UsageError(f"{ID} rejects {kwargs}: {error}") from None
    for name, policy in POLICIES.items():
        r = first_episodes(policy, args.episodes, args.seed, **kwargs)
        print(
            f"{name:6s}: success {r['success']:5.1%}  mean bounces {r['bounces']:4.2f}  "
            f"mean return {r['return']:7.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
