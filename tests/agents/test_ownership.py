"""A run folder belongs to one live process: a second training or resume on a live run is refused
naming its owner, a run whose owner died shows as stopped unexpectedly and ``--resume`` takes it
over; the same for main-job folders and sweep folders."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from contextlib import contextmanager
from pathlib import Path

import pytest
from tiny_budgets import TINY_SET
from training_processes import ROOT, start_training, wait_for_recorded_checkpoint

from agents import main_job, ownership, run_folder, sweep, train_cli
from agents.train import resume, train
from rigid_env import cli
from rigid_env.cli import UsageError

ID = "RigidEnv/Reorient-v0"
TINY = dict(n_envs=2, n_steps=32, batch_size=32, n_epochs=1, eval_freq=10**5, eval_episodes=2,
            policy_kwargs={"net_arch": [8]})  # fmt: skip


def one_line_error(capsys, main, prog, argv) -> str:
    """Run a command that must be refused: exit 2 and one line on stderr, returned."""
    capsys.readouterr()
    code = cli.run(main, prog, argv)
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE, err
    assert err.startswith(f"{prog}: error: ") and err.count("\n") == 1, err
    return err


def hold(folder: Path) -> subprocess.Popen:
    """Another live process that owns ``folder`` (until killed)."""
    code = (
        "import sys, time; from agents import ownership; "
        "ownership.claim(sys.argv[1], 'test'); print('held', flush=True); time.sleep(600)"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(folder)], env=env, stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline() == "held\n"
    return proc


def kill(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)


def test_a_live_run_is_refused_naming_its_owner_and_a_killed_one_is_taken_over(tmp_path, capsys):
    proc = start_training(tmp_path, ["--checkpoint-every", "64"])
    run = tmp_path / "run"
    try:
        wait_for_recorded_checkpoint(run, proc)
        assert json.loads((run / "run.json").read_text())["owner"]["pid"] == proc.pid
        for argv in (["--out", str(run)], ["--out", str(run), "--overwrite"],
                     ["--resume", str(run)]):  # fmt: skip
            err = one_line_error(capsys, train_cli.main, train_cli.PROG, argv)
            assert f"{run} is in use by pid {proc.pid} on " in err, err
            assert "python -m agents.train" in err  # the owner's command
        # The library refuses too.
        with pytest.raises(UsageError, match=f"in use by pid {proc.pid}"):
            resume(run, progress=False)
        with pytest.raises(UsageError, match=f"in use by pid {proc.pid}"):
            train(ID, timesteps=64, out=run, overrides=TINY, progress=False, overwrite=True)
    finally:
        kill(proc)  # as a lost machine or the OOM killer would: no chance to record anything
    record = json.loads((run / "run.json").read_text())
    assert record["status"] == "running"
    assert run_folder.state_of(run, "running") == run_folder.STOPPED == "stopped unexpectedly"
    err = one_line_error(capsys, train_cli.main, train_cli.PROG, ["--out", str(run)])
    assert "already holds a run (stopped unexpectedly)" in err and f"--resume {run}" in err

    # --resume takes it over from its last checkpoint (stopped again at once here).
    polls = [0]

    def stop() -> bool:
        polls[0] += 1
        return polls[0] >= 3

    logged: list[str] = []
    # The checkpoint file is written before the record naming it, so a kill between the two
    # leaves a checkpoint newer than run.json's: the resume starts from the file.
    with zipfile.ZipFile(run / run_folder.CHECKPOINT) as saved:
        steps = json.loads(saved.read("data"))["num_timesteps"]
    assert steps in (record["checkpoint"]["steps"], record["checkpoint"]["steps"] + 64)
    result = resume(run, progress=False, stop=stop, log=logged.append)
    assert result.status == "interrupted"
    assert any("stopped unexpectedly" in line and f"pid {proc.pid}" in line for line in logged)
    record = json.loads((run / "run.json").read_text())
    assert record["status"] == "interrupted" and record["resumed_at"] == [steps]
    assert record["owner"]["pid"] == os.getpid()
    assert not (run / ownership.LOCK_FILE).exists()  # released: the folder is as a run leaves it


def test_two_trainings_started_together_on_one_folder_one_is_refused(tmp_path):
    procs = [start_training(tmp_path, ["--checkpoint-every", "64"], name=str(k)) for k in range(2)]
    try:
        deadline = time.monotonic() + 180
        while all(p.poll() is None for p in procs):  # the refused one exits; the other trains
            assert time.monotonic() < deadline, "neither run was refused"
            time.sleep(0.1)
        (refused,) = [k for k, p in enumerate(procs) if p.poll() is not None]
        winner = procs[1 - refused]
        assert procs[refused].returncode == cli.EXIT_USAGE
        err = (tmp_path / f"stderr{refused}.txt").read_text()
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert f"in use by pid {winner.pid}" in err or "already holds a run" in err, err
        run = tmp_path / "run"
        wait_for_recorded_checkpoint(run, winner)
        assert json.loads((run / "run.json").read_text())["owner"]["pid"] == winner.pid
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                assert proc.wait(timeout=60) == cli.EXIT_INTERRUPTED
    # One run's log: one header, not two runs' lines interleaved.
    lines = (tmp_path / "run" / "monitor.csv").read_text().splitlines()
    assert sum(line.startswith("#") for line in lines) == 1
    assert json.loads((tmp_path / "run" / "run.json").read_text())["status"] == "interrupted"


def test_one_process_cannot_claim_a_folder_twice_and_release_removes_the_lock(tmp_path):
    folder = tmp_path / "f"
    with ownership.owning(folder, "--out") as held:
        assert held.owner.pid == os.getpid() and (folder / ownership.LOCK_FILE).is_file()
        assert ownership.owner_of(folder) is None  # this process's own claim is no other owner
        with pytest.raises(UsageError, match=f"--out: {folder} is in use by pid {os.getpid()}"):
            ownership.claim(folder, "--out")  # flock: a second open file conflicts, same process
    assert not (folder / ownership.LOCK_FILE).exists()
    ownership.claim(folder, "--out").release()  # free again


def test_a_stale_lock_file_of_a_dead_process_is_no_owner(tmp_path):
    proc = hold(tmp_path)
    owner = ownership.owner_of(tmp_path)
    assert owner is not None and owner.pid == proc.pid
    kill(proc)
    assert (tmp_path / ownership.LOCK_FILE).is_file()  # left behind: a SIGKILL cleans nothing
    assert ownership.owner_of(tmp_path) is None
    run_folder.check_new(tmp_path, overwrite=False)  # only the lock file: an empty folder
    with ownership.owning(tmp_path, "--out") as held:
        recorded = json.loads((tmp_path / ownership.LOCK_FILE).read_text())
        assert recorded["pid"] == os.getpid() == held.owner.pid


def test_without_file_locks_the_recorded_pid_decides(tmp_path, monkeypatch):
    """On a file system without flock (ENOLCK), a live recorded pid on this host owns the
    folder, a dead one does not."""
    proc = hold(tmp_path / "live")
    dead = hold(tmp_path / "dead")
    kill(dead)

    def no_locks(fd: int, operation: int) -> None:
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_locks)
    try:
        with pytest.raises(UsageError, match=f"in use by pid {proc.pid}"):
            ownership.claim(tmp_path / "live", "--out")
        assert ownership.owner_of(tmp_path / "live").pid == proc.pid
        assert ownership.owner_of(tmp_path / "dead") is None
        with ownership.owning(tmp_path / "dead", "--out"):
            recorded = json.loads((tmp_path / "dead" / ownership.LOCK_FILE).read_text())
            assert recorded["pid"] == os.getpid()
    finally:
        kill(proc)


def test_main_job_folder_in_use_is_refused_and_a_dead_one_taken_over(tmp_path, capsys, monkeypatch):
    out = tmp_path / "job"
    argv = ["--env", ID, "--timesteps", "64", "--n-envs", "2", *TINY_SET, "--episodes", "2",
            "--no-progress"]  # fmt: skip
    proc = hold(out)
    try:
        err = one_line_error(capsys, main_job.main, main_job.PROG, [*argv, "--out", str(out)])
        assert f"{out} is in use by pid {proc.pid}" in err
        record = {"envs": [ID], "status": "running", "owner": {"pid": proc.pid, "host": "h"},
                  "results": {}, "settings": {"algo": None, "timesteps": 64, "seed": 0,
                  "n_envs": 2, "overrides": {"n_steps": 32, "batch_size": 32, "n_epochs": 1,
                  "eval_freq": 10**5, "eval_episodes": 2}, "checkpoint_every": None}}  # fmt: skip
        (out / main_job.RECORD).write_text(json.dumps(record))
        resume_argv = ["--resume", str(out), "--episodes", "2", "--no-progress"]
        err = one_line_error(capsys, main_job.main, main_job.PROG, resume_argv)
        assert f"{out} is in use by pid {proc.pid}" in err
    finally:
        kill(proc)
    err = one_line_error(capsys, main_job.main, main_job.PROG, [*argv, "--out", str(out)])
    assert "already holds a run of the main job (stopped unexpectedly)" in err

    @contextmanager
    def stop_at_once():  # stands in for StopOnSignal: the training stops before its first step
        yield lambda: True

    monkeypatch.setattr(main_job, "StopOnSignal", stop_at_once)
    assert cli.run(main_job.main, main_job.PROG, resume_argv) == cli.EXIT_INTERRUPTED
    assert f"stopped unexpectedly (main_job.json says running; its owner, pid {proc.pid}" in (
        capsys.readouterr().out
    )
    record = json.loads((out / main_job.RECORD).read_text())
    assert record["status"] == "interrupted" and record["owner"]["pid"] == os.getpid()


def test_a_sweep_folder_in_use_is_refused_before_ray_starts(tmp_path, capsys, monkeypatch):
    def no_ray(*args, **kwargs):
        raise AssertionError("Ray was started")

    monkeypatch.setattr(sweep, "connect", no_ray)
    out = tmp_path / "sweep"
    proc = hold(out)
    try:  # a new sweep on a folder another sweep has just claimed, and a resume of a live one
        argv = ["--seeds", "1", "--set", "n_timesteps=64", "--out", str(out)]
        err = one_line_error(capsys, sweep.main, sweep.PROG, argv)
        assert f"{out} is in use by pid {proc.pid}" in err
        (out / sweep.SETTINGS_FILE).write_text("{}")
        err = one_line_error(capsys, sweep.main, sweep.PROG, ["--resume", str(out)])
        assert f"{out} is in use by pid {proc.pid}" in err
    finally:
        kill(proc)
