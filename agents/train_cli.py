"""The command line of ``agents.train`` (and the training half of ``python -m agents``).

Arguments are checked in full before any work (:func:`check_training_arguments`); the first
SIGINT or SIGTERM asks the training to stop at its next step, which saves a checkpoint
(:class:`StopOnSignal`); :func:`rigid_env.cli.run` turns a mistake into exit status 2.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from rigid_env import cli
from rigid_env.cli import UsageError

from . import config, run_folder
from .plan import DEFAULT_ENV, make_plan
from .train import RunResult, resume, train


class StopOnSignal:
    """While active, the first SIGINT (Ctrl-C) or SIGTERM makes ``stop()`` true, so the training
    saves a checkpoint and returns; a second one exits at once with status 130. Every file is
    written atomically, so exiting there leaves each one whole (old or new)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested = False
        self._previous: dict[int, Any] = {}  # signal -> the handler it had (signal's own type)

    def __call__(self) -> bool:
        return self.requested

    def __enter__(self) -> StopOnSignal:
        for sig in self.SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        # os.write, not print: the handler may run while the main thread is inside a print.
        if self.requested:
            os.write(2, b"\nsecond interrupt: exiting now\n")
            os._exit(cli.EXIT_INTERRUPTED)
        self.requested = True
        name = signal.Signals(signum).name
        os.write(
            2,
            f"\n{name}: stopping at the next env step and saving a checkpoint "
            "(Ctrl-C again to quit at once)\n".encode(),
        )


def parse_overrides(items: list[str]) -> dict:
    """``["n_steps=128", "policy_kwargs={net_arch: [8]}"]`` → a dict of YAML values."""
    import yaml

    overrides = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            overrides[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as error:
            problem = getattr(error, "problem", None) or "invalid YAML"
            raise UsageError(f"--set {key}: {problem} in {value!r}") from None
    return overrides


TRAINING_FLAGS = ("env", "algo", "timesteps", "seed", "n_envs", "out", "set", "checkpoint_every")


def add_training_arguments(parser: cli.Parser) -> None:
    """The arguments ``agents.train`` and the main job share (defaults: None = not given)."""
    parser.add_argument("--env", type=cli.env_id, help=f"Gymnasium id (default {DEFAULT_ENV})")
    parser.add_argument("--algo", choices=config.ALGOS, help="default ppo")
    parser.add_argument("--timesteps", type=cli.positive_int, help="default: the config file's")
    parser.add_argument("--seed", type=cli.nonnegative_int, help="default 0")
    parser.add_argument("--n-envs", type=cli.positive_int, help="default: the config file's")
    parser.add_argument("--out", help="new run folder (default: a fresh one in runs/)")
    parser.add_argument(
        "--set",
        nargs="+",
        metavar="KEY=YAML",
        help="override hyperparameters, e.g. --set n_steps=128 learning_rate=lin_3e-4",
    )
    parser.add_argument(
        "--checkpoint-every",
        type=cli.positive_int,
        metavar="STEPS",
        help="env steps between checkpoints (default: at each evaluation)",
    )
    existing = parser.add_mutually_exclusive_group()
    existing.add_argument(
        "--overwrite", action="store_true", help="replace the run already in --out"
    )
    existing.add_argument(
        "--resume",
        metavar="RUN_DIR",
        help="continue an interrupted run from its last checkpoint, with its settings",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def check_training_arguments(args: argparse.Namespace) -> None:
    """Every check :func:`train` or :func:`resume` will make, done now (UsageError)."""
    if args.resume is not None:
        given = [f"--{f.replace('_', '-')}" for f in TRAINING_FLAGS if getattr(args, f) is not None]
        if given:
            raise UsageError(
                f"--resume continues RUN_DIR with the settings in its run.json; drop {given}"
            )
        run_folder.read_resumable(args.resume)
        return
    args.overrides = parse_overrides(args.set or [])
    if args.out is not None:
        run_folder.check_new(Path(args.out), args.overwrite)
    make_plan(
        args.env or DEFAULT_ENV,
        args.algo or "ppo",
        args.timesteps,
        0 if args.seed is None else args.seed,
        args.n_envs,
        args.overrides,
        checkpoint_every=args.checkpoint_every,
    )


def run_training(args: argparse.Namespace, stop: Callable[[], bool]) -> RunResult:
    if args.resume is not None:
        return resume(args.resume, progress=not args.no_progress, stop=stop)
    return train(
        args.env or DEFAULT_ENV,
        args.algo or "ppo",
        args.timesteps,
        0 if args.seed is None else args.seed,
        args.n_envs,
        args.out,
        args.overrides,
        progress=not args.no_progress,
        checkpoint_every=args.checkpoint_every,
        overwrite=args.overwrite,
        stop=stop,
    )


PROG = "python -m agents.train"
EXIT_CODES = cli.EXIT_STATUSES


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=EXIT_CODES)
    add_training_arguments(parser)
    args = parser.parse_args(argv)
    check_training_arguments(args)
    with StopOnSignal() as stop:
        result = run_training(args, stop)
    if result.status == "interrupted":
        print(
            f"{PROG}: interrupted at {result.steps_done:,d} steps; "
            f"resume with --resume {result.out}",
            file=sys.stderr,
        )
        return cli.EXIT_INTERRUPTED
    return 0
