"""Training runs in subprocesses, as users start them (``python -m agents.train``), and waits on
what they write."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from tiny_budgets import TINY_SET

ROOT = Path(__file__).resolve().parents[2]


def start_training(
    folder: Path, extra: list[str], name: str = "", **popen: object
) -> subprocess.Popen:
    """``agents.train`` on a long tiny budget into ``folder/run``, its output in
    ``folder/stdout{name}.txt`` and ``folder/stderr{name}.txt``."""
    args = ["--timesteps", "100000", "--n-envs", "2", "--no-progress", "--out", "run"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-m", "agents.train", *args, *TINY_SET, *extra],
        cwd=folder,
        env=env,
        stdout=(folder / f"stdout{name}.txt").open("w"),
        stderr=(folder / f"stderr{name}.txt").open("w"),
        **popen,
    )


def wait_for(path: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, (path.parent.parent / "stderr.txt").read_text()
        assert time.monotonic() < deadline, f"no {path} after {timeout} s"
        time.sleep(0.05)


def wait_for_recorded_checkpoint(run: Path, proc: subprocess.Popen, timeout: float = 120.0):
    """Until ``run.json`` records a checkpoint: the checkpoint file is written (atomically)
    before the record that names it, so its mere existence is not enough."""
    deadline = time.monotonic() + timeout
    while True:
        record = run / "run.json"
        if record.exists() and json.loads(record.read_text()).get("checkpoint") is not None:
            return
        assert proc.poll() is None, (run.parent / "stderr.txt").read_text()
        assert time.monotonic() < deadline, f"no checkpoint recorded in {record} after {timeout} s"
        time.sleep(0.05)
