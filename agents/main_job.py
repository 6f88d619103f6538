"""The main job (``python -m agents``): train the default baseline and compare it.

1. train PPO on ``RigidEnv/Reorient-v0`` with ``agents/hyperparams/ppo.yml`` (progress bar,
   periodic seeded evaluation and checkpoints, best model kept);
2. evaluate random, zero-torque, the analytic controller and the learned policy on the same
   seeded episodes and print the table;
3. write the learning curve (by step 1) and a clip of the learned policy.

The training arguments are those of ``agents.train``: an existing run folder is refused unless
``--overwrite``; ``--resume RUN_DIR`` continues an interrupted main job's training and then runs
steps 2 and 3. Ctrl-C during training saves a checkpoint and exits with status 130; a mistake in
the arguments exits with status 2 and one line on stderr, before any work.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

from rigid_env import cli
from rigid_env.files import write_json

from . import run_folder
from .evaluate import (
    DEFAULT_EPISODES,
    DEFAULT_SEED,
    evaluate,
    print_table,
    table_document,
    write_gif,
)
from .train_cli import (
    EXIT_CODES,
    StopOnSignal,
    add_training_arguments,
    check_training_arguments,
    run_training,
)

PROG = "python -m agents"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=EXIT_CODES)
    add_training_arguments(parser)
    parser.add_argument("--episodes", type=cli.positive_int, default=DEFAULT_EPISODES)
    parser.add_argument("--eval-seed", type=cli.nonnegative_int, default=DEFAULT_SEED)
    args = parser.parse_args(argv)
    check_training_arguments(args)

    start = time.perf_counter()
    if args.resume is not None:
        record = run_folder.read(args.resume)
        print(f"== 1/3 resuming the training in {args.resume}", flush=True)
    else:
        record = {"env_id": args.env or "RigidEnv/Reorient-v0", "algo": args.algo or "ppo"}
        print(f"== 1/3 training {record['algo'].upper()} on {record['env_id']}", flush=True)
    env_id, algo = record["env_id"], record["algo"]
    with StopOnSignal() as stop:
        run = run_training(args, stop)
    if run.status == "interrupted":
        print(
            f"{PROG}: interrupted at {run.steps_done:,d} steps; resume with --resume {run.out}",
            file=sys.stderr,
        )
        return cli.EXIT_INTERRUPTED
    best = str(run.out / "best_model.zip")

    print(f"== 2/3 evaluating on {args.episodes} seeded episodes (seeds {args.eval_seed}…)")
    rows = []
    for policy in ("random", "zero", "analytic", best):
        print(f"   {policy} …", flush=True)
        row = evaluate(env_id, policy, args.episodes, args.eval_seed)
        if policy == best:
            row["policy"] = f"{algo.upper()} (best_model.zip)"
        rows.append(row)
    print_table(rows, f"{env_id}: {args.episodes} episodes from seed {args.eval_seed}")

    print("== 3/3 writing a clip of the learned policy", flush=True)
    clip = write_gif(env_id, best, run.out / "clip.gif", args.eval_seed)
    wall = time.perf_counter() - start
    summary = {
        **table_document(env_id, rows, args.episodes, args.eval_seed),
        "throughput": run.throughput,
        "wall_seconds": round(wall, 1),
    }
    write_json(run.out / "main_job.json", summary, indent=2)
    tp = run.throughput
    if tp:  # empty when a resumed run had nothing left to train
        print(
            f"training throughput {tp['steps_per_second']:,.0f} env steps/s "
            f"(simulator {tp['sim_share']:.1%} of the training time)"
        )
    print(f"learning curve: {run.out / 'learning_curve.png'}")
    print(f"clip:           {clip}")
    print(f"run folder:     {run.out}")
    print(f"main job done in {wall / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
