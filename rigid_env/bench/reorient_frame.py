"""Reorient-v0 with the exact integrator at one physics step per frame against finer stepping.

    python -m rigid_env.bench.reorient_frame [--episodes 16] [--num-envs 256] [--seconds 5]

For each configuration (integrator, dt, frame_skip; the frame is 0.05 s in all of them) it
prints

* the orientation error over a 200-frame episode (10 s), the worst frame of each episode,
  median and max over the episodes, against a reference: for the torque-free tumble (action 0)
  the closed form ``reference.torque_free_exact``; under random actions (uniform, held for a
  frame, body-fixed as the env documents: the torque turns with the body) a DOP853 solve of
  Euler's equations with the body torque, rtol = atol = 1e-12, frame by frame;
* env steps per second of one ``gym.make`` env and of a native vector env of ``--num-envs``.

The episodes start from the env's own reset distribution (a quarter of them tumbling near the
intermediate axis). Every configuration steps as the env does: the torque is a body-frame
torque (``Scene.step(..., body_torque=)``) that each integrator turns into the world at each
of its load evaluations, ``frame_skip`` steps in one call. For comparison, the rows marked
"held in world" step the former way: the torque turned into the world at the start of each
physics step and held there over the step (``step_body_torque`` below, one call per
physics step), a first-order load error whatever the integrator.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.integrate import solve_ivp

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env import cli, resources, sim
from rigid_env.envs import kernels
from rigid_env.envs.reorient import ReorientTask
from rigid_env.sim.rotation import quat_angle, quat_multiply, quat_to_matrix, rotate_inverse

from . import env_speed
from .reference import torque_free_exact

FRAMES = 200
Config = tuple[str, float, int]  # (integrator, dt, frame_skip)
Start = tuple[np.ndarray, np.ndarray]  # (q0, ω0 world) per episode
CONFIGS: tuple[Config, ...] = (
    ("exact", 0.05, 1),
    ("exact4", 0.05, 1),
    ("splitting", 0.01, 5),
    ("splitting", 0.025, 2),  # the env's defaults
)
# Configurations also run with the former load model (torque held in world over each step).
HELD: tuple[Config, ...] = (("exact", 0.05, 1), ("splitting", 0.01, 5))


def step_body_torque(
    scene: sim.Scene, state: sim.State, torque: np.ndarray, frame_skip: int
) -> sim.State:
    """``frame_skip`` physics steps, one simulator call each, with the body torque ``torque``
    (N, 3) turned into the world at the start of each step and held there over it."""
    world = np.empty((torque.shape[0], 1, 3))
    for _ in range(frame_skip):
        kernels.world_torque(state.orientation, torque, world)
        state = scene.step(state, torque=world)
    return state


class _HeldTorqueTask(ReorientTask):
    """Reorient stepped the former way: the body torque turned into the world at the start of
    each physics step and held there over it, one simulator call per physics step."""

    def _advance(self, torque: np.ndarray) -> None:
        self.state = step_body_torque(self.scene, self.state, torque, self.frame_skip)


def _episodes(
    config: Config,
    n: int,
    seed: int,
    actions: np.ndarray | None,
    frames: int = FRAMES,
    held: bool = False,
) -> tuple[np.ndarray, Start, ReorientTask]:
    """Orientation (frames + 1, n, 4), start (q0, ω0 world) and the task, for n episodes."""
    integrator, dt, skip = config
    task = (_HeldTorqueTask if held else ReorientTask)(
        n, integrator=integrator, dt=dt, frame_skip=skip, terminate_on_success=False
    )
    rng = np.random.default_rng(seed)
    task.reset_envs(np.arange(n), np.stack([task.draw(rng) for _ in range(n)]))
    q = [task.state.orientation[:, 0].copy()]
    start = (q[0].copy(), task.state.angular_velocity[:, 0].copy())
    for k in range(frames):
        task.step(np.zeros((n, 3)) if actions is None else actions[k])
        q.append(task.state.orientation[:, 0].copy())
    return np.array(q), start, task


def _reference_free(task: ReorientTask, start: Start, frames: int) -> np.ndarray:
    times = np.arange(frames + 1) * task.config.action_period
    moments = np.array(task.principal_moments)
    if not np.allclose(task.body.inertia, np.diag(moments)):
        raise ValueError("the reference assumes a body with diagonal inertia")
    out = [torque_free_exact(moments, q0, w0, times)[0] for q0, w0 in zip(*start, strict=True)]
    return np.stack(out, axis=1)


def _reference_driven(task: ReorientTask, start: Start, actions: np.ndarray) -> np.ndarray:
    moments = np.diag(task.body.inertia).copy()
    period = task.config.action_period
    out = []
    for i, (q0, w0) in enumerate(zip(*start, strict=True)):
        q = q0.copy()
        pi = moments * rotate_inverse(quat_to_matrix(q), w0)
        qs = [q]
        for k in range(actions.shape[0]):
            tau = actions[k, i] * task.max_torque  # body frame, held for the frame

            def rhs(_t: float, y: np.ndarray, tau: np.ndarray = tau) -> np.ndarray:
                om = y[4:] / moments
                dq = 0.5 * quat_multiply(y[:4] / np.linalg.norm(y[:4]), np.append(om, 0.0))
                return np.concatenate((dq, np.cross(y[4:], om) + tau))

            sol = solve_ivp(
                rhs, (0, period), np.concatenate((q, pi)), "DOP853", rtol=1e-12, atol=1e-12
            )
            q = sol.y[:4, -1] / np.linalg.norm(sol.y[:4, -1])
            pi = sol.y[4:, -1]
            qs.append(q)
        out.append(np.array(qs))
    return np.stack(out, axis=1)


def accuracy(
    n: int,
    seed: int,
    frames: int = FRAMES,
    configs: Sequence[Config] = CONFIGS,
    held: Sequence[Config] = HELD,
) -> list[dict[str, Any]]:
    """Rows of worst-frame orientation errors: every config in ``configs`` as the env steps,
    and under random actions every config in ``held`` with the former world-held torque."""
    rows = []
    rng = np.random.default_rng(seed + 1)
    actions = rng.uniform(-1, 1, (frames, n, 3))
    for label, acts in (("tumble (action 0)", None), ("random actions", actions)):
        reference = None
        runs = [(config, False) for config in configs]
        if acts is not None:
            runs += [(config, True) for config in held]
        for config, is_held in runs:
            q, start, task = _episodes(config, n, seed, acts, frames, is_held)
            if reference is None:
                reference = (
                    _reference_free(task, start, frames)
                    if acts is None
                    else _reference_driven(task, start, acts)
                )
            worst = quat_angle(q, reference).max(axis=0)
            rows.append(
                {
                    "case": label + (", held in world (former)" if is_held else ""),
                    "config": config,
                    "median": float(np.median(worst)),
                    "max": float(worst.max()),
                }
            )
    return rows


def speed(config: Config, num_envs: int, seconds: float, seed: int) -> tuple[float, float]:
    integrator, dt, skip = config
    kwargs: dict[str, Any] = dict(integrator=integrator, dt=dt, frame_skip=skip)
    single = gym.make("RigidEnv/Reorient-v0", **kwargs)
    vec = gym.make_vec(
        "RigidEnv/Reorient-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        **kwargs,
    )
    return (
        env_speed.run(single, seconds=seconds, seed=seed).steps_per_s,
        env_speed.run(vec, seconds=seconds, seed=seed).steps_per_s,
    )


PROG = "python -m rigid_env.bench.reorient_frame"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=cli.positive_int, default=16)
    parser.add_argument("--num-envs", type=cli.positive_int, default=256)
    parser.add_argument("--seconds", type=cli.positive_float, default=5.0)
    parser.add_argument("--seed", type=cli.nonnegative_int, default=0)
    args = parser.parse_args(argv)
    resources.check_envs("RigidEnv/Reorient-v0", args.num_envs, "--num-envs")
    resources.check_envs("RigidEnv/Reorient-v0", args.episodes, "--episodes")
    print(
        f"Orientation error over {FRAMES} frames (10 s), worst frame per episode, "
        f"{args.episodes} episodes:"
    )
    print("| case | integrator | dt (s) | steps/frame | median (rad) | max (rad) |")
    print("|---|---|---|---|---|---|")
    for r in accuracy(args.episodes, args.seed):
        name, dt, skip = r["config"]
        print(f"| {r['case']} | {name} | {dt:g} | {skip} | {r['median']:.1e} | {r['max']:.1e} |")
    print(f"\nEnv steps per second (random actions; vector env of {args.num_envs}):")
    print("| integrator | dt (s) | steps/frame | single env | vector env |")
    print("|---|---|---|---|---|")
    for config in CONFIGS:
        single, vec = speed(config, args.num_envs, args.seconds, args.seed)
        name, dt, skip = config
        print(f"| {name} | {dt:g} | {skip} | {single:,.0f} | {vec:,.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
