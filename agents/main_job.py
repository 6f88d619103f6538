"""The main job (``python -m agents``): train the default baseline and compare it.

1. train PPO on ``RigidEnv/Reorient-v0`` with ``agents/hyperparams/ppo.yml`` (progress bar,
   periodic seeded evaluation, best model kept);
2. evaluate random, zero-torque, the analytic controller and the learned policy on the same
   seeded episodes and print the table;
3. write the learning curve (by step 1) and a clip of the learned policy.
"""

from __future__ import annotations

import argparse
import json
import time

from .evaluate import DEFAULT_EPISODES, DEFAULT_SEED, evaluate, print_table, write_gif
from .train import train

DEFAULT_ENV = "RigidEnv/Reorient-v0"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m agents", description=__doc__.split("\n")[0])
    parser.add_argument("--env", default=DEFAULT_ENV)
    parser.add_argument("--algo", default="ppo", choices=("ppo", "sac"))
    parser.add_argument("--timesteps", type=int, default=None, help="default: the config file's")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=None, help="run folder (default: a fresh one in runs/)")
    parser.add_argument("--episodes", type=int, default=DEFAULT_EPISODES)
    parser.add_argument("--eval-seed", type=int, default=DEFAULT_SEED)
    args = parser.parse_args(argv)

    start = time.perf_counter()
    print(f"== 1/3 training {args.algo.upper()} on {args.env}", flush=True)
    run = train(args.env, args.algo, args.timesteps, args.seed, out=args.out)
    best = str(run.out / "best_model.zip")

    print(f"== 2/3 evaluating on {args.episodes} seeded episodes (seeds {args.eval_seed}…)")
    rows = []
    for policy in ("random", "zero", "analytic", best):
        print(f"   {policy} …", flush=True)
        row = evaluate(args.env, policy, args.episodes, args.eval_seed)
        if policy == best:
            row["policy"] = f"{args.algo.upper()} (best_model.zip)"
        rows.append(row)
    print_table(rows, f"{args.env}: {args.episodes} episodes from seed {args.eval_seed}")

    print("== 3/3 writing a clip of the learned policy", flush=True)
    clip = write_gif(args.env, best, run.out / "clip.gif", args.eval_seed)
    wall = time.perf_counter() - start
    summary = {"rows": rows, "throughput": run.throughput, "wall_seconds": round(wall, 1)}
    (run.out / "main_job.json").write_text(json.dumps(summary, indent=2))
    tp = run.throughput
    print(
        f"training throughput {tp['steps_per_second']:,.0f} env steps/s "
        f"(simulator {tp['sim_share']:.1%} of the training time)"
    )
    print(f"learning curve: {run.out / 'learning_curve.png'}")
    print(f"clip:           {clip}")
    print(f"run folder:     {run.out}")
    print(f"main job done in {wall / 60:.1f} min")


if __name__ == "__main__":
    main()
