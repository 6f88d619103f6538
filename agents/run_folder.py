"""Run folders: what ``agents.train`` writes, when an existing one may be reused, and ``run.json``.

A run folder holds ``run.json`` from the first moment of training (status ``running``, then
``finished``, ``interrupted`` or ``failed``), so any folder that holds files but no ``run.json``
is not a run and is never written into. An existing run is replaced only with ``overwrite``
(and then only the files a run writes are removed) or continued with ``agents.train --resume``.

A run belongs to the one live process that trains it (:mod:`agents.ownership`): a run in use is
neither replaced nor resumed, and one whose ``run.json`` says ``running`` with no live owner
stopped unexpectedly (a SIGKILL, a lost machine) and may be resumed.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import pickle
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rigid_env.cli import UsageError, writable_dir
from rigid_env.files import remove_partials, write_json

from . import ownership

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
STATUSES = ("running", "finished", "interrupted", "failed")
RESUMABLE = ("running", "interrupted", "failed")
STOPPED = "stopped unexpectedly"  # how a running record without a live owner is reported


def contents(folder: Path) -> list[Path]:
    """What ``folder`` holds besides its owner's lock file."""
    return [p for p in folder.iterdir() if p.name != ownership.LOCK_FILE]


def refuse_if_in_use(folder: Path, name: str) -> None:
    """UsageError naming the owner when another live process works in ``folder``."""
    owner = ownership.owner_of(folder)
    if owner is not None:
        raise UsageError(
            f"{name}: {folder} is in use by {owner.describe()}; wait for it to end or stop it first"
        )


def state_of(folder: Path, status: str) -> str:
    """``status`` as it stands: a ``running`` one with no live owner stopped unexpectedly."""
    if status == "running" and ownership.owner_of(folder) is None:
        return STOPPED
    return status


def check_new(out: Path, overwrite: bool) -> None:
    """Raise :class:`UsageError` unless a new run may be written to ``out``; changes nothing."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out: {out} is a file; expected a new or empty folder")
    if not out.is_dir():
        parent = next(p for p in out.absolute().parents if p.exists())
        if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
            raise UsageError(f"--out: cannot create {out} in {parent}; expected a writable place")
        return
    refuse_if_in_use(out, "--out")
    if not contents(out):
        return
    if not (out / RUN_JSON).is_file():
        raise UsageError(
            f"--out: {out} is not empty and holds no {RUN_JSON}; expected a new or empty folder"
        )
    if not overwrite:
        try:
            status = state_of(out, str(json.loads((out / RUN_JSON).read_text())["status"]))
        except (OSError, ValueError, TypeError, KeyError):
            status = "unreadable"
        raise UsageError(
            f"--out: {out} already holds a run ({status}); pass --resume {out} to continue it "
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
    """``run.json`` of a run that can be continued: not finished, not in use by another live
    process, with a checkpoint, and every entry a resume reads of the kind it should be."""
    from .plan import plan_of_record

    run_dir = Path(run_dir)
    record = read(run_dir)
    refuse_if_in_use(run_dir, "--resume")
    status = record.get("status", "finished")  # runs from before checkpoints were all finished
    if status not in STATUSES:
        raise UsageError(
            f"--resume: {run_dir / RUN_JSON}: status must be one of {STATUSES}, got {status!r}"
        )
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
    check_record(record, run_dir / RUN_JSON)
    plan_of_record(record)
    writable_dir(run_dir, "--resume")
    remove_partials(run_dir)
    return record


def _number(value: Any) -> bool:
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def check_record(record: dict, path: Path) -> None:
    """UsageError naming the first entry of ``record`` that a resume cannot use (a hand-edited
    or damaged ``run.json``); the settings themselves are checked by ``plan_of_record``."""

    def bad(key: str, expected: str) -> UsageError:
        return UsageError(
            f"--resume: {path}: {key} must be {expected}, got {record.get(key)!r}; "
            "expected the JSON agents.train writes"
        )

    for key in ("env_kwargs", "loop", "overrides"):
        if not isinstance(record.get(key, {}), dict):
            raise bad(key, "a mapping")
    rows = record.get("evaluations", [])
    metrics = ("mean_return", "std_return", "success_rate")
    if not isinstance(rows, list) or not all(
        isinstance(r, dict)
        and _count(r.get("env_steps"))
        and all(_number(r.get(m)) for m in metrics)
        and set(r) == set(rows[0])
        for r in rows
    ):
        raise bad("evaluations", f"a list of rows with env_steps and {', '.join(metrics)}")
    best = record.get("best_mean_return")
    if best is not None and not _number(best):
        raise bad("best_mean_return", "null or a finite number")
    resumed = record.get("resumed_at", [])
    if not isinstance(resumed, list) or not all(_count(s) for s in resumed):
        raise bad("resumed_at", "a list of step counts")
    checkpoint = record.get("checkpoint")
    if checkpoint is not None and not (
        isinstance(checkpoint, dict)
        and _count(checkpoint.get("steps"))
        and _count(checkpoint.get("monitor_bytes"))
    ):
        raise bad("checkpoint", "null or {steps: N, monitor_bytes: N}")
    analytic = record.get("analytic")
    if analytic is not None and not (
        isinstance(analytic, dict) and all(_number(analytic.get(m)) for m in metrics)
    ):
        raise bad("analytic", f"null or a summary with {', '.join(metrics)}")
    if not _count(record.get("steps_done", 0)):
        raise bad("steps_done", "a step count")


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
