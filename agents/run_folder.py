"""Run folders: what ``agents.train`` writes, when an existing one may be reused, and ``run.json``.

A run folder holds ``run.json`` from the first moment of training (status ``running``, then
``finished``, ``interrupted`` or ``failed``), so any folder that holds files but no ``run.json``
is not a run and is never written into. An existing run is replaced only with ``overwrite``
(and then only the files a run writes are removed) or continued with ``agents.train --resume``.
"""

from __future__ import annotations

import json
import os
import pickle
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

from rigid_env.cli import UsageError, writable_dir
from rigid_env.files import remove_partials, write_json

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.vec_env import VecEnv

RUN_JSON = "run.json"
CHECKPOINT = "checkpoint.zip"
REPLAY_BUFFER = "checkpoint_replay_buffer.pkl"  # SAC's replay buffer, saved with the checkpoint
RUN_FILES = (
    RUN_JSON,
    CHECKPOINT,
    REPLAY_BUFFER,
    "best_model.zip",
    "final_model.zip",
    "monitor.csv",
    "evaluations.csv",
    "learning_curve.png",
    "clip.gif",
    "main_job.json",
)
RESUMABLE = ("running", "interrupted", "failed")


def check_new(out: Path, overwrite: bool) -> None:
    """Raise :class:`UsageError` unless a new run may be written to ``out``; changes nothing."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out: {out} is a file; expected a new or empty folder")
    if not out.is_dir():
        parent = next(p for p in out.absolute().parents if p.exists())
        if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
            raise UsageError(f"--out: cannot create {out} in {parent}; expected a writable place")
        return
    if not any(out.iterdir()):
        return
    if not (out / RUN_JSON).is_file():
        raise UsageError(
            f"--out: {out} is not empty and holds no {RUN_JSON}; expected a new or empty folder"
        )
    if not overwrite:
        raise UsageError(
            f"--out: {out} already holds a run; pass --resume {out} to continue it "
            "or --overwrite to replace it"
        )


def prepare_new(out: Path, overwrite: bool) -> Path:
    """Create ``out`` (or clear the previous run's files from it when ``overwrite``)."""
    check_new(out, overwrite)
    writable_dir(out, "--out")
    for name in RUN_FILES:
        (out / name).unlink(missing_ok=True)
    remove_partials(out)
    return out


def read(run_dir: str | Path) -> dict:
    """The ``run.json`` of ``run_dir`` (UsageError when missing or unreadable)."""
    path = Path(run_dir) / RUN_JSON
    if not path.is_file():
        raise UsageError(f"{run_dir}: no {RUN_JSON}; expected a run folder written by agents.train")
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UsageError(
            f"{path}: unreadable ({error}); expected the JSON agents.train writes"
        ) from None
    if not isinstance(record, dict) or "env_id" not in record:
        raise UsageError(f"{path}: holds no env_id; expected the JSON agents.train writes")
    return record


def read_resumable(run_dir: str | Path) -> dict:
    """``run.json`` of a run that can be continued: not finished, with a checkpoint."""
    run_dir = Path(run_dir)
    record = read(run_dir)
    status = record.get("status", "finished")  # runs from before checkpoints were all finished
    if status not in RESUMABLE:
        raise UsageError(
            f"--resume: {run_dir} is {status} ({record.get('steps_done', '?')} steps); "
            "expected an interrupted run"
        )
    if not (run_dir / CHECKPOINT).is_file():
        raise UsageError(
            f"--resume: {run_dir} has no {CHECKPOINT} (stopped before its first checkpoint); "
            "start it again with --overwrite"
        )
    writable_dir(run_dir, "--resume")
    remove_partials(run_dir)
    return record


def write(run_dir: Path, record: dict) -> None:
    write_json(run_dir / RUN_JSON, record, indent=2, default=repr)


def load_model(path: str | Path, name: str, env: VecEnv | None = None) -> tuple[BaseAlgorithm, str]:
    """``(model, algo)`` from an SB3 zip (on CPU; ``env`` attached if given); a file that is not
    a readable PPO or SAC model is a :class:`UsageError` naming ``name``."""
    from .plan import algo_class
    from .policies import algo_of

    path = Path(path)
    if path.suffix != ".zip" or not path.is_file():
        raise UsageError(f"{name}: {path} is not an existing .zip file")
    try:
        algo = algo_of(path)
        return algo_class(algo).load(str(path), env=env, device="cpu"), algo
    except (zipfile.BadZipFile, KeyError, ValueError, OSError, EOFError, RuntimeError,
            pickle.UnpicklingError) as error:  # fmt: skip
        raise UsageError(
            f"{name}: cannot load {path} as a stable-baselines3 PPO or SAC model "
            f"({type(error).__name__}: {error})"
        ) from None
