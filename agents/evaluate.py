"""Evaluate a policy on seeded episodes.

    python -m agents.evaluate [--env ID] --policy {random,zero,analytic,PATH}
                              [--episodes K --seed S --json --gif PATH]

Episode ``i`` starts like a single env reset with seed ``S + i``; all ``K`` run at once in one
native vector env. Prints a table (mean ± std of the return, success rate, mean episode length,
final angle error / spin or landing outcome), or with ``--json`` one JSON object with
``episodes``, ``mean_return``, ``std_return``, ``success_rate`` (a fraction) and the rest.
``--gif`` writes a clip of episode 0 (atomically; the path is checked before evaluating).

A model (``.zip``) runs only on the env it was trained on: the env id and env settings come from
the ``run.json`` that ``agents.train`` wrote next to it (``--env`` may be left out; a different
one is refused). A model without ``run.json`` runs on ``--env`` only if its observation and
action spaces fit. A mistake in the arguments (``--episodes`` too many to fit in memory among
them) exits with status 2 and one line on stderr; a fault of the file system while writing,
with status 74 and one line naming the file.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rigid_env import cli, resources
from rigid_env.cli import UsageError
from rigid_env.files import atomic_open, write_json

from . import run_folder
from .policies import BUILTIN, make_policy
from .rollout import Policy, make_vec, run_episodes

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

DEFAULT_ENV = "RigidEnv/Reorient-v0"
DEFAULT_SEED = 1000  # the evaluation seeds agents.train uses: no training stream starts there
DEFAULT_EPISODES = 200


def trained_env(policy: str) -> str | None:
    """The env id in the ``run.json`` next to model ``policy`` (None for built-in policies or
    a model without one)."""
    if policy in BUILTIN or not (Path(policy).parent / run_folder.RUN_JSON).is_file():
        return None
    return run_folder.read(Path(policy).parent)["env_id"]


def load_policy(
    env_id: str, policy: str, seed: int = DEFAULT_SEED
) -> tuple[Callable[[Any], Policy], dict[str, Any]]:
    """``(factory, env_kwargs)``: ``factory(env)`` gives the batched policy for a vector env of
    ``env_id`` built with ``env_kwargs``. A model is loaded once, and only for its own env
    (:class:`UsageError` otherwise)."""
    if policy in BUILTIN:
        return (lambda env: make_policy(policy, env_id, env, seed)), {}
    path = Path(policy)
    if path.suffix != ".zip" or not path.is_file():
        raise UsageError(
            f"--policy: expected one of {BUILTIN} or an existing .zip file, got {policy!r}"
        )
    info = run_folder.read(path.parent) if (path.parent / run_folder.RUN_JSON).is_file() else {}
    trained_on = info.get("env_id")
    if trained_on is not None and trained_on != env_id:
        raise UsageError(
            f"--policy: {path} was trained on {trained_on} (its run.json), not {env_id}; "
            f"use --env {trained_on} or leave --env out"
        )
    model, _ = run_folder.load_model(path, "--policy")
    env_kwargs = dict(info.get("env_kwargs", {}))
    if trained_on is None:
        _check_spaces(model, path, env_id)
    return (lambda env: lambda obs: model.predict(obs, deterministic=True)[0]), env_kwargs


def _check_spaces(model: BaseAlgorithm, path: Path, env_id: str) -> None:
    """Without run.json the env is unknown: at least the spaces must be the model's."""
    env = make_vec(env_id, 1)
    obs, act = env.single_observation_space, env.single_action_space
    env.close()
    if model.observation_space.shape != obs.shape or model.action_space.shape != act.shape:
        raise UsageError(
            f"--policy: {path} takes observations of shape {model.observation_space.shape} and "
            f"gives actions of shape {model.action_space.shape}; {env_id} has {obs.shape} and "
            f"{act.shape}: the model was trained on another env"
        )
    print(
        f"note: no run.json next to {path}; its spaces fit {env_id}, so it runs there",
        file=sys.stderr,
    )


def evaluate(
    env_id: str, policy: str, episodes: int = DEFAULT_EPISODES, seed: int = DEFAULT_SEED
) -> dict[str, Any]:
    """Summary dict of ``policy`` on ``episodes`` seeded episodes of ``env_id``."""
    factory, kwargs = load_policy(env_id, policy, seed)
    result = run_episodes(env_id, factory, episodes, seed, kwargs, policy_needs_env=True)
    return {"env": env_id, "policy": policy, "seed": seed, **result.summary()}


CLIP_FPS = 15  # frames per second of a clip at most: GIF encoding dominates its cost


def write_gif(env_id: str, policy: str, path: str | Path, seed: int = DEFAULT_SEED) -> Path:
    """A clip of the episode seeded ``seed`` (the first evaluation episode), in real time at no
    more than :data:`CLIP_FPS` frames per second; the last frame is held for 1 s."""
    import gymnasium as gym
    from PIL import Image

    factory, kwargs = load_policy(env_id, policy, seed)
    env = gym.make(env_id, render_mode="rgb_array", **kwargs)
    act = factory(env)
    fps = float(env.metadata["render_fps"])
    every = max(1, math.ceil(fps / CLIP_FPS))  # render every this many env steps
    obs, _ = env.reset(seed=seed)
    frames = [_rgb(env)]
    done, steps = False, 0
    while not done:
        obs, _, terminated, truncated, _ = env.step(act(obs[None])[0])
        steps += 1
        done = terminated or truncated
        if done or steps % every == 0:
            frames.append(_rgb(env))
    env.close()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Pillow's fast octree palette: ~5x quicker than imageio's default GIF quantiser here.
    images = [Image.fromarray(f).quantize(128, method=Image.Quantize.FASTOCTREE) for f in frames]
    durations = [round(1000 * every / fps)] * len(images)
    durations[-1] = 1000
    with atomic_open(path) as f:
        images[0].save(
            f, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0
        )
    return path


def _rgb(env: Any) -> np.ndarray:
    frame = env.render()
    if not isinstance(frame, np.ndarray):  # render_mode="rgb_array" gives one (H, W, 3) array
        raise TypeError(f"{env}.render() gave {type(frame).__name__}, expected an RGB array")
    return frame


COLUMNS = (
    ("policy", "policy", "{}"),
    ("return", "mean_return", "{:.2f}"),
    ("± std", "std_return", "{:.2f}"),
    ("success", "success_rate", "{:.1%}"),
    ("length", "mean_length", "{:.1f}"),
)


# Outcome columns, when the env reports them (all figures are in the JSON).
EXTRA_COLUMNS = (
    ("final angle error", "final_angle_error_mean", "{:.4f}"),
    ("final spin", "final_spin_mean", "{:.4f}"),
    ("bounces", "final_bounces_mean", "{:.2f}"),
    ("on target face", "on_target_face_rate", "{:.1%}"),
)


def table_columns(rows: list[dict]) -> tuple[tuple[str, str, str], ...]:
    """(header, key, format) of the columns the rows carry: the common ones, then outcomes."""
    return COLUMNS + tuple(c for c in EXTRA_COLUMNS if c[1] in rows[0])


def table_document(env_id: str, rows: list[dict], episodes: int, seed: int) -> dict:
    """The rows with their columns as (header, key, format spec): tables are made from it."""
    columns = [(h, k, f[2:-1]) for h, k, f in table_columns(rows)]
    return {
        "env_id": env_id,
        "episodes": episodes,
        "eval_seed": seed,
        "columns": columns,
        "rows": rows,
    }


def print_table(rows: list[dict], title: str | None = None) -> None:
    """A rich table of evaluation summaries; extra ``final_*`` columns as they come."""
    from rich.console import Console
    from rich.table import Table

    columns = table_columns(rows)
    table = Table(title=title)
    for name, _, _ in columns:
        table.add_column(name, justify="left" if name == "policy" else "right")
    for row in rows:
        table.add_row(*(fmt.format(row.get(key, np.nan)) for _, key, fmt in columns))
    Console(width=120).print(table)


PROG = "python -m agents.evaluate"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(
        prog=PROG,
        description=__doc__.split("\n")[0],
        epilog=cli.EXIT_STATUSES,
    )
    parser.add_argument(
        "--env", type=cli.env_id, help=f"default: the model's (run.json), else {DEFAULT_ENV}"
    )
    parser.add_argument(
        "--policy",
        nargs="+",
        default=["analytic"],
        help="one or more of random, zero, analytic or a .zip (same seeded episodes for each)",
    )
    parser.add_argument("--episodes", type=cli.positive_int, default=DEFAULT_EPISODES)
    parser.add_argument("--seed", type=cli.nonnegative_int, default=DEFAULT_SEED)
    parser.add_argument("--json", action="store_true", help="print one JSON object per policy")
    parser.add_argument("--gif", help="write a clip of episode 0 to this .gif file (one policy)")
    parser.add_argument(
        "--out", help="also write the table as JSON (rows and their columns) to this .json file"
    )
    args = parser.parse_args(argv)
    env_id = args.env or trained_env(args.policy[0]) or DEFAULT_ENV
    resources.check_envs(env_id, args.episodes, "--episodes")  # all episodes run at once
    if args.gif:
        if len(args.policy) > 1:
            raise cli.UsageError("--gif: give one --policy to film, not several")
        cli.writable_file(args.gif, "--gif", (".gif",))
    if args.out:
        cli.writable_file(args.out, "--out", (".json",))
    rows = [evaluate(env_id, policy, args.episodes, args.seed) for policy in args.policy]
    if args.json:
        for summary in rows:
            if args.gif:
                summary["gif"] = str(write_gif(env_id, summary["policy"], args.gif, args.seed))
            print(json.dumps(summary))
    else:
        print_table(rows, f"{env_id}: {args.episodes} episodes from seed {args.seed}")
        if args.gif:
            print(f"clip: {write_gif(env_id, args.policy[0], args.gif, args.seed)}")
    if args.out:
        write_json(Path(args.out), table_document(env_id, rows, args.episodes, args.seed), indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
