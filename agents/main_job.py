"""The main job (``python -m agents``): train a baseline on each env and compare it.

For each env of :data:`JOBS` in turn (``RigidEnv/Reorient-v0``, then ``RigidEnv/BoxLanding-v0``;
``--env`` picks one):

1. train its algorithm with ``agents/hyperparams/<algo>.yml`` into the run folder
   ``OUT/<env>`` (progress bar, periodic seeded evaluation and checkpoints, best model kept,
   ``learning_curve.png``);
2. evaluate random, zero-torque, the analytic controller and the learned policy on the same
   seeded episodes, print the table and write it to ``OUT/<env>/main_job.json``;
3. write a clip of the learned policy (``OUT/<env>/clip.gif``).

``OUT`` is ``--out`` (default a fresh ``runs/main-<time>``); its ``main_job.json`` records the
settings, the status and every env's table. The training arguments are those of
``agents.train`` and apply to every env. An existing main job folder is refused unless
``--overwrite``; ``--resume OUT`` continues an interrupted one with its own settings: an env
whose training finished keeps it, an interrupted one continues from its checkpoint, one not
started starts, and every env whose table is missing is then evaluated. Ctrl-C during training
saves a checkpoint and exits with status 130; a mistake in the arguments exits with status 2
and one line on stderr, before any work. The folder belongs to one live process: another job on
it is refused, naming that process; one whose ``main_job.json`` says ``running`` but whose
process is gone stopped unexpectedly, and ``--resume`` takes it over. A fault of the file system
ends the job with status 74 and one line naming the file, ``main_job.json`` marked ``failed``
where it can still be written.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rigid_env import cli, resources
from rigid_env.cli import UsageError
from rigid_env.files import write_json

from . import ownership, run_folder
from .evaluate import (
    DEFAULT_EPISODES,
    DEFAULT_SEED,
    evaluate,
    print_table,
    table_document,
    write_gif,
)
from .plan import make_plan
from .train import resume, train
from .train_cli import (
    EXIT_CODES,
    TRAINING_FLAGS,
    StopOnSignal,
    add_training_arguments,
    parse_overrides,
)

PROG = "python -m agents"
# The envs the main job trains, in order, with the algorithm of each (``--algo`` overrides).
JOBS = {"RigidEnv/Reorient-v0": "ppo", "RigidEnv/BoxLanding-v0": "ppo"}
RECORD = "main_job.json"  # in OUT (the job) and in each env's run folder (that env's table)
SETTINGS = ("timesteps", "seed", "n_envs", "overrides", "checkpoint_every", "algo")


def run_name(env_id: str) -> str:
    """The run folder of ``env_id`` inside the main job's folder: ``reorient-v0``."""
    return env_id.split("/")[-1].lower()


def default_out() -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    out, k = Path("runs") / f"main-{stamp}", 1
    while out.exists():
        out, k = Path("runs") / f"main-{stamp}-{k}", k + 1
    return out


def check_new(out: Path, overwrite: bool) -> None:
    """UsageError unless a new main job may be written to ``out``; changes nothing."""
    if out.is_dir():
        run_folder.refuse_if_in_use(out, "--out")
    if out.is_dir() and run_folder.contents(out):
        if (out / run_folder.RUN_JSON).is_file():
            raise UsageError(
                f"--out: {out} already holds a run of agents.train; expected a new or empty "
                "folder (or a main job's, with --overwrite)"
            )
        if not (out / RECORD).is_file():
            raise UsageError(
                f"--out: {out} is not empty and holds no {RECORD}; expected a new or empty folder"
            )
        if not overwrite:
            try:
                status = str(json.loads((out / RECORD).read_text())["status"])
            except (OSError, ValueError, TypeError, KeyError):
                status = "unreadable"
            raise UsageError(
                f"--out: {out} already holds a run of the main job "
                f"({run_folder.state_of(out, status)}); pass --resume {out} to continue it or "
                "--overwrite to replace it"
            )
        for env_id in JOBS:  # what --overwrite replaces must be the job's own runs
            run_folder.check_new(out / run_name(env_id), overwrite=True)
    else:
        run_folder.check_new(out, overwrite=False)  # a file, or a place that cannot be made


def read_record(out: str | Path) -> dict:
    """The job record of the main job folder ``out`` (UsageError when missing or unreadable)."""
    path = Path(out) / RECORD
    if not path.is_file():
        raise UsageError(f"--resume: {out} holds no {RECORD}; expected a main job's folder")
    try:
        record = json.loads(path.read_text())
        envs, settings = list(record["envs"]), dict(record["settings"])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as error:
        raise UsageError(f"--resume: {path} is unreadable ({error})") from None
    if not envs or any(e not in JOBS for e in envs) or set(SETTINGS) - set(settings):
        raise UsageError(f"--resume: {path} names no known envs or lacks settings")
    return record


def check_arguments(args: argparse.Namespace) -> dict:
    """Every check the job will make, done now (UsageError); returns the job record to run."""
    if args.resume is not None:
        given = [f"--{f.replace('_', '-')}" for f in TRAINING_FLAGS if getattr(args, f) is not None]
        if given:
            raise UsageError(
                f"--resume continues OUT with the settings in its {RECORD}; drop {given}"
            )
        record = read_record(args.resume)
        run_folder.refuse_if_in_use(Path(args.resume), "--resume")
        if record.get("status") == "finished":
            raise UsageError(f"--resume: {args.resume} is finished; expected an interrupted job")
        cli.writable_dir(args.resume, "--resume")
        for env_id in record["envs"]:  # an interrupted run must be resumable from its files
            folder = Path(args.resume) / run_name(env_id)
            status = _run_status(folder)
            if status in run_folder.RESUMABLE and (folder / run_folder.CHECKPOINT).is_file():
                run_folder.read_resumable(folder)
        record["out"] = str(args.resume)
        return record
    out = Path(args.out) if args.out is not None else default_out()
    check_new(out, args.overwrite)
    envs = [args.env] if args.env is not None else list(JOBS)
    settings = {
        "algo": args.algo,
        "timesteps": args.timesteps,
        "seed": 0 if args.seed is None else args.seed,
        "n_envs": args.n_envs,
        "overrides": parse_overrides(args.set or []),
        "checkpoint_every": args.checkpoint_every,
    }
    for env_id in envs:
        resources.check_envs(env_id, args.episodes, "--episodes")  # each evaluation at once
        make_plan(
            env_id,
            _algo(settings, env_id),
            settings["timesteps"],
            settings["seed"],
            settings["n_envs"],
            settings["overrides"],
            checkpoint_every=settings["checkpoint_every"],
        )
    return {"out": str(out), "envs": envs, "settings": settings, "status": "new"}


def _algo(settings: dict, env_id: str) -> str:
    return settings["algo"] or JOBS.get(env_id, "ppo")


def _run_status(folder: Path) -> str | None:
    """The status in ``folder``'s run.json (None when no run was started there)."""
    if not (folder / run_folder.RUN_JSON).is_file():
        return None
    return run_folder.read(folder).get("status", "finished")


def _write_record(out: Path, record: dict) -> None:
    write_json(out / RECORD, {k: v for k, v in record.items() if k != "out"}, indent=2)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=EXIT_CODES)
    add_training_arguments(parser)
    parser.add_argument("--episodes", type=cli.positive_int, default=DEFAULT_EPISODES)
    parser.add_argument("--eval-seed", type=cli.nonnegative_int, default=DEFAULT_SEED)
    args = parser.parse_args(argv)
    record = check_arguments(args)
    if args.resume is None:
        args.out = record["out"]  # the default one, if none was given: the same below
    with ownership.owning(record["out"], "--resume" if args.resume else "--out") as claim:
        record = check_arguments(args)  # again: no other process can start on it now
        return _run_job(args, record, claim.owner.as_record())


def _run_job(args: argparse.Namespace, record: dict, owner: dict) -> int:
    start = time.perf_counter()
    out = Path(record["out"])
    resuming = record["status"] != "new"
    print(f"main job folder: {out}  ({', '.join(record['envs'])})", flush=True)
    if record["status"] == "running":  # its owner is gone (or the claim would have failed)
        dead = record.get("owner") or {}
        print(
            f"{out} stopped unexpectedly (main_job.json says running; its owner, pid "
            f"{dead.get('pid', '?')} on {dead.get('host', '?')}, is gone): taking it over",
            flush=True,
        )
    record.update(status="running", owner=owner, episodes=args.episodes, eval_seed=args.eval_seed)
    record.setdefault("results", {})
    _write_record(out, record)
    n = len(record["envs"])
    try:
        for k, env_id in enumerate(record["envs"], 1):
            code = _one_env(args, record, env_id, f"[{k}/{n}]", overwrite=not resuming)
            if code:
                record["status"] = "interrupted"
                _write_record(out, record)
                return code
            _write_record(out, record)
    except BaseException as error:  # recorded where it can still be written, then reported
        record["status"] = "interrupted" if isinstance(error, KeyboardInterrupt) else "failed"
        with contextlib.suppress(OSError):
            _write_record(out, record)
        raise
    wall = time.perf_counter() - start
    record.update(status="finished", wall_seconds=round(wall, 1))
    _write_record(out, record)
    for env_id in record["envs"]:
        result = record["results"][env_id]
        print(
            f"{env_id}: learning curve {out / run_name(env_id) / 'learning_curve.png'}, "
            f"clip {out / run_name(env_id) / 'clip.gif'}"
        )
        tp = result.get("throughput") or {}
        if tp:
            print(
                f"   trained {tp['env_steps']:,d} env steps in {tp['learn_seconds'] / 60:.1f} min "
                f"({tp['steps_per_second']:,.0f} env steps/s, simulator "
                f"{tp['sim_share']:.1%} of the training time, {result['backend']} physics)"
            )
    print(f"main job folder: {out}")
    print(f"main job done in {wall / 60:.1f} min")
    return 0


def _one_env(
    args: argparse.Namespace, record: dict, env_id: str, tag: str, overwrite: bool
) -> int | None:
    """Train (or resume), evaluate and film ``env_id``; its table goes into ``record``.
    Returns an exit status when interrupted, else None."""
    out, settings = Path(record["out"]), record["settings"]
    folder = out / run_name(env_id)
    algo = _algo(settings, env_id)
    if env_id in record["results"] and (folder / RECORD).is_file():
        print(f"== {tag} {env_id}: done before (table in {folder / RECORD})", flush=True)
        print_table(record["results"][env_id]["rows"], env_id)
        return None
    start = time.perf_counter()
    status = _run_status(folder)
    with StopOnSignal() as stop:
        if status == "finished":
            print(f"== {tag} {env_id}: training finished before ({folder})", flush=True)
            throughput = run_folder.read(folder).get("throughput") or {}
        elif status in run_folder.RESUMABLE and (folder / run_folder.CHECKPOINT).is_file():
            print(f"== {tag} resuming the training of {algo.upper()} on {env_id}", flush=True)
            run = resume(folder, progress=not args.no_progress, stop=stop)
            if run.status == "interrupted":
                return _interrupted(out, run.steps_done)
            throughput = run.throughput
        else:
            print(f"== {tag} training {algo.upper()} on {env_id}", flush=True)
            run = train(
                env_id,
                algo,
                settings["timesteps"],
                settings["seed"],
                settings["n_envs"],
                folder,
                settings["overrides"],
                args.eval_seed,
                progress=not args.no_progress,
                checkpoint_every=settings["checkpoint_every"],
                overwrite=overwrite or status is not None,  # a run stopped before a checkpoint
                stop=stop,
            )
            if run.status == "interrupted":
                return _interrupted(out, run.steps_done)
            throughput = run.throughput
    train_seconds = time.perf_counter() - start
    best = str(folder / "best_model.zip")

    print(f"== {tag} evaluating on {args.episodes} seeded episodes (seeds {args.eval_seed}…)")
    rows = []
    for policy in ("random", "zero", "analytic", best):
        print(f"   {policy} …", flush=True)
        row = evaluate(env_id, policy, args.episodes, args.eval_seed)
        if policy == best:
            row["policy"] = f"{algo.upper()} (best_model.zip)"
        rows.append(row)
    print_table(rows, f"{env_id}: {args.episodes} episodes from seed {args.eval_seed}")
    print(f"== {tag} writing a clip of the learned policy", flush=True)
    write_gif(env_id, best, folder / "clip.gif", args.eval_seed)
    summary = {
        **table_document(env_id, rows, args.episodes, args.eval_seed),
        "algo": algo,
        "backend": _backend(env_id, run_folder.read(folder).get("env_kwargs", {})),
        "throughput": throughput,
        "train_seconds": round(train_seconds, 1),
        "wall_seconds": round(time.perf_counter() - start, 1),
    }
    write_json(folder / RECORD, summary, indent=2)
    record["results"][env_id] = summary
    return None


def _backend(env_id: str, env_kwargs: dict) -> str:
    """Which physics the training ran on: the scene's step implementation, built with the
    training's env arguments (``"compiled-threads"`` when its config splits the batch)."""
    from .rollout import make_vec

    env: Any = make_vec(env_id, 1, **env_kwargs)  # a rigid_env vector env: a task with a scene
    task = env.unwrapped.task
    backend = str(task.scene.backend)
    if backend == "compiled" and getattr(task.config, "backend", None) == "compiled-threads":
        backend = "compiled-threads"
    env.close()
    return backend


def _interrupted(out: Path, steps: int) -> int:
    print(f"{PROG}: interrupted at {steps:,d} steps; resume with --resume {out}", file=sys.stderr)
    return cli.EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
