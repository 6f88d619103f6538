"""Training that loses nothing: interrupts, crashes, --resume, --overwrite, atomic files.

Real (tiny) training runs: 2 envs, an 8-unit network, 2 evaluation episodes.
"""

from __future__ import annotations

import csv
import json
import signal
import time
from pathlib import Path

import pytest
from training_processes import start_training, wait_for, wait_for_recorded_checkpoint

from agents import evaluate, run_folder, train_cli
from agents.train import resume, train
from rigid_env import cli
from rigid_env.cli import UsageError
from rigid_env.files import TEMP_SUFFIX, atomic_open, remove_partials, write_text

ID = "RigidEnv/Reorient-v0"
TINY = dict(
    n_envs=2,
    n_steps=32,
    batch_size=32,
    n_epochs=1,
    eval_freq=256,
    eval_episodes=2,
    policy_kwargs={"net_arch": [8]},
)


def stop_after(polls: int):
    """A ``stop`` callable that turns true at its ``polls``-th call: training polls it once before
    it starts, then once per vector step."""
    calls = [0]

    def stop() -> bool:
        calls[0] += 1
        return calls[0] >= polls

    return stop


def monitor_rows(path: Path) -> tuple[float, list[dict]]:
    lines = path.read_text().splitlines()
    assert lines[0].startswith("#") and sum(line.startswith("#") for line in lines) == 1
    return json.loads(lines[0][1:])["t_start"], list(csv.DictReader(lines[1:]))


def test_overwrite_replaces_the_runs_files_and_nothing_else(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    old = {"env_id": ID, "algo": "ppo", "status": "interrupted", "steps_done": 4096}
    (out / "run.json").write_text(json.dumps(old))
    for name in ("checkpoint.zip", "best_model.zip", "clip.gif", "main_job.json"):
        (out / name).write_bytes(b"from the old run")
    (out / "notes.txt").write_text("mine\n")
    result = train(ID, timesteps=64, out=out, overrides=TINY, progress=False, overwrite=True)
    assert result.status == "finished" and result.steps_done == 64
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["timesteps"] == 64
    for name in ("checkpoint.zip", "clip.gif", "main_job.json"):
        assert not (out / name).exists(), name
    assert run_folder.load_model(out / "best_model.zip", "best")[0].num_timesteps == 64
    assert (out / "notes.txt").read_text() == "mine\n"


def test_crash_keeps_the_last_checkpoint_and_resume_finishes_the_run(tmp_path):
    out = tmp_path / "run"
    crash_step = 450  # after the checkpoint at 384 and the first episodes' end at 400

    def crash() -> bool:
        crash.calls += 1
        if 2 * (crash.calls - 1) >= crash_step:  # 2 envs; the first call is before learning
            raise RuntimeError("simulated crash")
        return False

    crash.calls = 0
    with pytest.raises(RuntimeError, match="simulated crash"):
        train(ID, timesteps=1000, out=out, overrides=TINY, progress=False, stop=crash,
              checkpoint_every=128)  # fmt: skip
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed" and record["steps_done"] == crash_step
    checkpoint = record["checkpoint"]
    assert checkpoint["steps"] == 384  # the work lost is less than --checkpoint-every
    monitor = out / "monitor.csv"
    assert monitor.stat().st_size > checkpoint["monitor_bytes"]  # episodes logged after it
    kept = monitor.read_bytes()[: checkpoint["monitor_bytes"]]

    # A resume that crashes again before its first checkpoint still points at the last one.
    crash.calls, crash_step = 0, 20
    with pytest.raises(RuntimeError, match="simulated crash"):
        resume(out, progress=False, stop=crash)
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed" and record["checkpoint"] == checkpoint

    resumed_at = time.time()  # now the command line: its settings come from run.json
    assert cli.run(train_cli.main, train_cli.PROG, ["--resume", str(out), "--no-progress"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["resumed_at"] == [384, 384]
    assert record["steps_done"] >= 1000 and record["n_envs"] == 2
    steps = [row["env_steps"] for row in record["evaluations"]]
    assert steps == sorted(set(steps)) and steps[-1] == record["steps_done"]
    # The log continues from the checkpoint: the episodes logged after it are gone, not doubled.
    assert monitor.read_bytes().startswith(kept)
    t_start, rows = monitor_rows(monitor)
    old = [r for r in rows if t_start + float(r["t"]) < resumed_at]
    assert len(old) == kept.count(b"\n") - 2  # the header lines
    assert len(rows) > len(old)
    for name in ("final_model.zip", "best_model.zip", "learning_curve.png", "evaluations.csv"):
        assert (out / name).is_file(), name
    assert not (out / "checkpoint.zip").exists()
    with pytest.raises(UsageError, match="finished"):
        resume(out, progress=False)


def test_sac_checkpoint_keeps_the_replay_buffer(tmp_path):
    from stable_baselines3 import SAC

    out = tmp_path / "run"
    overrides = dict(
        n_envs=2,
        eval_freq=10_000,
        eval_episodes=2,
        learning_starts=20,
        batch_size=16,
        buffer_size=500,
        gradient_steps=1,
        policy_kwargs={"net_arch": [8]},
    )
    result = train(
        ID, "sac", 200, out=out, overrides=overrides, progress=False, stop=stop_after(31)
    )
    assert result.status == "interrupted" and result.steps_done == 60
    model = SAC.load(out / "checkpoint.zip")
    model.load_replay_buffer(out / "checkpoint_replay_buffer.pkl")
    # One entry per vector step taken, except the last: SB3 stores a step's transition after
    # the callback that stopped the training has run.
    assert model.replay_buffer.size() == 30 - 1
    result = resume(out, progress=False)
    assert result.status == "finished" and result.steps_done == 200


def test_ctrl_c_saves_a_checkpoint_that_evaluate_then_runs(tmp_path, capsys):
    proc = start_training(tmp_path, ["--checkpoint-every", "64"])
    wait_for(tmp_path / "run" / "checkpoint.zip", proc)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130
    stderr = (tmp_path / "stderr.txt").read_text()
    assert "Traceback" not in stderr and "--resume run" in stderr
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["status"] == "interrupted"
    assert 64 <= record["steps_done"] == record["checkpoint"]["steps"] < 100_000
    model, _ = run_folder.load_model(tmp_path / "run" / "checkpoint.zip", "checkpoint")
    assert model.num_timesteps == record["steps_done"]

    capsys.readouterr()
    policy = str(tmp_path / "run" / "checkpoint.zip")
    assert (
        cli.run(evaluate.main, evaluate.PROG, ["--policy", policy, "--episodes", "2", "--json"])
        == 0
    )
    summary = json.loads(capsys.readouterr().out)
    assert summary["env"] == ID and summary["episodes"] == 2  # the env came from run.json


def test_sigterm_then_ctrl_c_exits_at_once_and_leaves_whole_files(tmp_path):
    proc = start_training(tmp_path, ["--checkpoint-every", "32"])
    wait_for_recorded_checkpoint(tmp_path / "run", proc)
    # Back to back, so the second arrives while the first is still being honoured (with a pause
    # between them a fast run could finish its graceful stop first and never see a second one).
    proc.send_signal(signal.SIGTERM)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130
    stderr = (tmp_path / "stderr.txt").read_text()
    assert "Traceback" not in stderr and "second interrupt: exiting now" in stderr
    # Whatever the second signal cut short, every file in place is whole.
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["status"] in ("running", "interrupted")
    model, _ = run_folder.load_model(tmp_path / "run" / "checkpoint.zip", "checkpoint")
    assert model.num_timesteps >= record["checkpoint"]["steps"] >= 32


def test_atomic_writes_leave_the_old_file_until_done(tmp_path):
    path = write_text(tmp_path / "a.json", "old")
    with pytest.raises(RuntimeError), atomic_open(path, "w") as f:
        f.write("new, half written")
        assert path.read_text() == "old"  # readers still see the old file
        raise RuntimeError("interrupted mid-write")
    assert path.read_text() == "old" and list(tmp_path.iterdir()) == [path]
    with atomic_open(path, "w") as f:
        f.write("new")
    assert path.read_text() == "new" and list(tmp_path.iterdir()) == [path]
    # What a hard exit mid-write leaves (a temporary file) is cleared before a resume.
    stale = tmp_path / f".checkpoint.zip.x1{TEMP_SUFFIX}"
    stale.write_bytes(b"partial")
    assert remove_partials(tmp_path) == [stale] and not stale.exists()
