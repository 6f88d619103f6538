"""Evaluate a policy on seeded episodes.

    python -m agents.evaluate --env RigidEnv/Reorient-v0 --policy {random,zero,analytic,PATH}
                              [--episodes K --seed S --json --gif PATH]

Episode ``i`` starts like a single env reset with seed ``S + i``; all ``K`` run at once in one
native vector env. Prints a table (mean ± std of the return, success rate, mean episode length,
final angle error / spin or landing outcome), or with ``--json`` one JSON object with
``episodes``, ``mean_return``, ``std_return``, ``success_rate`` (a fraction) and the rest.
``--gif`` writes a clip of episode 0. A model's env settings are read from the ``run.json``
that ``agents.train`` wrote next to it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .policies import BUILTIN, make_policy, run_info
from .rollout import run_episodes

DEFAULT_SEED = 1000  # the evaluation seeds agents.train uses: no training stream starts there
DEFAULT_EPISODES = 200


def env_kwargs_for(policy: str) -> dict:
    return {} if policy in BUILTIN else dict(run_info(policy).get("env_kwargs", {}))


def evaluate(env_id: str, policy: str, episodes: int = DEFAULT_EPISODES, seed: int = DEFAULT_SEED):
    """Summary dict of ``policy`` on ``episodes`` seeded episodes of ``env_id``."""
    kwargs = env_kwargs_for(policy)
    result = run_episodes(
        env_id,
        lambda e: make_policy(policy, env_id, e, seed),
        episodes,
        seed,
        kwargs,
        policy_needs_env=True,
    )
    return {"env": env_id, "policy": policy, "seed": seed, **result.summary()}


def write_gif(env_id: str, policy: str, path: str | Path, seed: int = DEFAULT_SEED) -> Path:
    """A clip of the episode seeded ``seed`` (the first evaluation episode)."""
    import gymnasium as gym
    from PIL import Image

    env = gym.make(env_id, render_mode="rgb_array", **env_kwargs_for(policy))
    act = make_policy(policy, env_id, env, seed)
    obs, _ = env.reset(seed=seed)
    frames = [env.render()]
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(act(obs[None])[0])
        frames.append(env.render())
        done = terminated or truncated
    frames += [frames[-1]] * int(env.metadata["render_fps"])  # hold the last frame for 1 s
    env.close()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Pillow's fast octree palette: ~5x quicker than imageio's default GIF quantiser here.
    images = [Image.fromarray(f).quantize(128, method=Image.Quantize.FASTOCTREE) for f in frames]
    duration_ms = round(1000 / env.metadata["render_fps"])
    images[0].save(path, save_all=True, append_images=images[1:], duration=duration_ms, loop=0)
    return path


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


def print_table(rows: list[dict], title: str | None = None) -> None:
    """A rich table of evaluation summaries; extra ``final_*`` columns as they come."""
    from rich.console import Console
    from rich.table import Table

    columns = COLUMNS + tuple(c for c in EXTRA_COLUMNS if c[1] in rows[0])
    table = Table(title=title)
    for name, _, _ in columns:
        table.add_column(name, justify="left" if name == "policy" else "right")
    for row in rows:
        table.add_row(*(fmt.format(row.get(key, np.nan)) for _, key, fmt in columns))
    Console(width=120).print(table)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluate", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--env", default="RigidEnv/Reorient-v0")
    parser.add_argument("--policy", default="analytic", help="random, zero, analytic or a .zip")
    parser.add_argument("--episodes", type=int, default=DEFAULT_EPISODES)
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead")
    parser.add_argument("--gif", default=None, help="write a clip of episode 0 here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be at least 1")
    summary = evaluate(args.env, args.policy, args.episodes, args.seed)
    if args.gif:
        summary["gif"] = str(write_gif(args.env, args.policy, args.gif, args.seed))
    if args.json:
        print(json.dumps(summary))
    else:
        print_table([summary], f"{args.env}: {args.episodes} episodes from seed {args.seed}")
        if args.gif:
            print(f"clip: {summary['gif']}")


if __name__ == "__main__":
    main()
