"""User mistakes on every command line: one line on stderr, exit status 2, nothing written.

Most cases call the commands in process through :func:`rigid_env.cli.run` (the function the
``python -m`` entry points call); a few run the real entry points in subprocesses to check the
exit status and the absence of a traceback end to end.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from agents import evaluate, main_job, run_folder, train_cli
from agents.train import train
from rigid_env import cli
from rigid_env.bench import __main__ as bench_cli
from rigid_env.bench import env_speed

ID = "RigidEnv/Reorient-v0"
ROOT = Path(__file__).resolve().parents[2]
COMMANDS = {
    "train": (train_cli.main, train_cli.PROG),
    "evaluate": (evaluate.main, evaluate.PROG),
    "main_job": (main_job.main, main_job.PROG),
    "bench": (bench_cli.main, bench_cli.PROG),
    "env_speed": (env_speed.main, env_speed.PROG),
}


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def assert_usage_error(command: str, argv: list[str], expected: str, capsys, folder: Path):
    """``command argv`` exits 2 with one stderr line naming ``expected``; ``folder`` unchanged."""
    main, prog = COMMANDS[command]
    before = snapshot(folder)
    dirs_before = sorted(p for p in folder.rglob("*") if p.is_dir())
    capsys.readouterr()
    code = cli.run(main, prog, argv)
    out, err = capsys.readouterr()
    assert code == cli.EXIT_USAGE, (out, err)
    assert err.startswith(f"{prog}: error: ") and err.count("\n") == 1, err
    assert expected in err, err
    assert snapshot(folder) == before
    assert sorted(p for p in folder.rglob("*") if p.is_dir()) == dirs_before


@pytest.fixture()
def files(tmp_path, monkeypatch):
    """A working folder (the cwd) holding a plain file, a non-run folder and a finished run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file.txt").write_text("not a folder\n")
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "keep.txt").write_text("mine\n")
    (tmp_path / "done").mkdir()
    record = {"env_id": ID, "algo": "ppo", "status": "finished", "steps_done": 64}
    (tmp_path / "done" / "run.json").write_text(json.dumps(record))
    (tmp_path / "busy" / "speed.png").mkdir(parents=True)  # where a bench writes a file
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "run.json").write_text('{"env_id": ')
    (tmp_path / "broken" / "model.zip").write_bytes(b"")
    (tmp_path / "bad.zip").write_bytes(os.urandom(300))
    with zipfile.ZipFile(tmp_path / "nodata.zip", "w") as archive:
        archive.writestr("other", "x")
    with zipfile.ZipFile(tmp_path / "badjson.zip", "w") as archive:
        archive.writestr("data", "{not json")
    return tmp_path


TRAIN_CASES = [
    (["--timesteps", "0"], "--timesteps"),
    (["--timesteps", "-5"], "--timesteps"),
    (["--timesteps", "1e3"], "--timesteps"),
    (["--n-envs", "0"], "--n-envs"),
    (["--seed", "-1"], "--seed"),
    (["--checkpoint-every", "0"], "--checkpoint-every"),
    (["--env", "RigidEnv/NoSuch-v0"], "unknown env id"),
    (["--algo", "dqn"], "--algo"),
    (["--set", "n_steps"], "--set"),
    (["--set", "no_such_key=1"], "no_such_key"),
    (["--set", "n_steps=[1"], "--set n_steps"),
    (["--set", "learning_rate=lin_fast"], "learning_rate"),
    (["--set", "eval_freq=0"], "eval_freq"),
    (["--set", "n_steps=abc"], "PPO rejects"),
    (["--set", "env_kwargs={no_such_option: 1}"], "env_kwargs"),
    (["--out", "file.txt"], "file.txt is a file"),
    (["--out", "file.txt/run"], "file.txt"),
    (["--out", "notes"], "holds no run.json"),
    (["--out", "notes", "--overwrite"], "holds no run.json"),
    (["--out", "done"], "--resume done"),
    (["--resume", "done"], "is finished"),
    (["--resume", "nowhere"], "no run.json"),
    (["--resume", "broken"], "run.json: unreadable"),
    (["--resume", "done", "--timesteps", "10"], "drop ['--timesteps']"),
    (["--resume", "done", "--overwrite"], "not allowed with argument"),
]


@pytest.mark.parametrize("argv, expected", TRAIN_CASES, ids=[" ".join(a) for a, _ in TRAIN_CASES])
def test_train_mistakes_exit_2_before_any_work(files, capsys, argv, expected):
    if "--out" not in argv and "--resume" not in argv:
        argv = [*argv, "--out", "new_run"]
    assert_usage_error("train", argv, expected, capsys, files)
    assert not (files / "new_run").exists()


@pytest.fixture(scope="module")
def model_zip(tmp_path_factory) -> Path:
    """An untrained tiny PPO model for Reorient (saved without a run.json)."""
    from stable_baselines3 import PPO

    from agents.rollout import make_vec
    from agents.vec_adapter import GymVectorToSB3

    env = GymVectorToSB3(make_vec(ID, 1))
    model = PPO("MlpPolicy", env, n_steps=8, batch_size=8, policy_kwargs={"net_arch": [8]})
    path = tmp_path_factory.mktemp("model") / "model.zip"
    model.save(path)
    return path


def in_run(model_zip: Path, folder: Path, env_id: str) -> Path:
    """A copy of the model in a run folder whose run.json names ``env_id``."""
    folder.mkdir()
    (folder / "model.zip").write_bytes(model_zip.read_bytes())
    (folder / "run.json").write_text(json.dumps({"env_id": env_id, "env_kwargs": {}}))
    return folder / "model.zip"


EVALUATE_CASES = [
    (["--episodes", "0"], "--episodes"),
    (["--seed", "-3"], "--seed"),
    (["--env", "NoSuch-v0"], "unknown env id"),
    (["--policy", "missing.zip"], "--policy"),
    (["--policy", "file.txt"], "--policy"),
    (["--policy", "bad.zip"], "BadZipFile"),
    (["--policy", "nodata.zip"], "KeyError"),
    (["--policy", "badjson.zip"], "JSONDecodeError"),
    (["--policy", "broken/model.zip"], "run.json: unreadable"),
    (["--gif", "file.txt/clip.gif"], "--gif"),
    (["--gif", "notes"], "is a directory"),
    (["--gif", "clip.png"], "should end in .gif"),
]


@pytest.mark.parametrize(
    "argv, expected", EVALUATE_CASES, ids=[" ".join(a) for a, _ in EVALUATE_CASES]
)
def test_evaluate_mistakes_exit_2_before_any_work(files, capsys, argv, expected):
    assert_usage_error("evaluate", ["--episodes", "2", *argv], expected, capsys, files)


def test_evaluate_refuses_a_model_on_another_env_than_its_run(files, capsys, model_zip):
    model = in_run(model_zip, files / "run", ID)
    argv = ["--policy", str(model), "--env", "RigidEnv/BoxLanding-v0", "--episodes", "2"]
    assert_usage_error("evaluate", argv, f"was trained on {ID}", capsys, files)
    # Without --env the run's env is used.
    assert cli.run(evaluate.main, evaluate.PROG, ["--policy", str(model), "--episodes", "2"]) == 0
    assert ID in capsys.readouterr().out


def test_evaluate_without_run_json_checks_the_spaces(files, capsys, model_zip):
    argv = ["--policy", str(model_zip), "--env", "RigidEnv/BoxLanding-v0", "--episodes", "2"]
    assert_usage_error("evaluate", argv, "trained on another env", capsys, files)
    argv = ["--policy", str(model_zip), "--env", ID, "--episodes", "2", "--json"]
    assert cli.run(evaluate.main, evaluate.PROG, argv) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["episodes"] == 2 and "no run.json" in err


MAIN_JOB_CASES = [
    (["--episodes", "0"], "--episodes"),
    (["--eval-seed", "-1"], "--eval-seed"),
    (["--out", "done"], "already holds a run"),
    (["--out", "notes"], "holds no main_job.json"),
    (["--env", "RigidEnv/NoSuch-v0"], "unknown env id"),
    (["--set", "no_such_key=1"], "no_such_key"),
    (["--resume", "done"], "holds no main_job.json"),  # a run of agents.train, not a main job
    (["--resume", "done", "--seed", "3"], "drop ['--seed']"),
]


@pytest.mark.parametrize(
    "argv, expected", MAIN_JOB_CASES, ids=[" ".join(a) for a, _ in MAIN_JOB_CASES]
)
def test_main_job_mistakes_exit_2_before_any_work(files, capsys, argv, expected):
    assert_usage_error("main_job", argv, expected, capsys, files)


BENCH_CASES = [
    ("bench", ["accuracy", "--preset", "tiny", "--out", "file.txt"], "file.txt is a file"),
    ("bench", ["accuracy", "--preset", "tiny", "--out", "file.txt/sub"], "cannot write"),
    ("bench", ["all", "--preset", "tiny", "--out", "busy"], "speed.png is a directory"),
    ("bench", ["nothing"], "invalid choice"),
    ("bench", ["speed", "--preset", "huge"], "--preset"),
    ("env_speed", [ID, "--seconds", "-1"], "--seconds"),
    ("env_speed", [ID, "--seconds", "nan"], "--seconds"),
    ("env_speed", [ID, "--seconds", "0.001"], "--seconds"),
    ("env_speed", [ID, "--num-envs", "0"], "--num-envs"),
    ("env_speed", [ID, "--seed", "-1"], "--seed"),
    ("env_speed", ["NoSuch-v0"], "unknown env id"),
]


@pytest.mark.parametrize(
    "command, argv, expected", BENCH_CASES, ids=[f"{c} {' '.join(a)}" for c, a, _ in BENCH_CASES]
)
def test_bench_mistakes_exit_2_before_any_work(files, capsys, command, argv, expected):
    assert_usage_error(command, argv, expected, capsys, files)


def test_bugs_keep_their_traceback(monkeypatch):
    """Only UsageError becomes exit 2: any other error, even a ValueError, propagates."""

    def broken(*args, **kwargs):
        raise ValueError("a bug inside the package")

    monkeypatch.setattr(evaluate, "evaluate", broken)
    with pytest.raises(ValueError, match="a bug inside"):
        cli.run(evaluate.main, evaluate.PROG, ["--policy", "zero", "--episodes", "1"])
    monkeypatch.setattr(train_cli, "run_training", broken)
    with pytest.raises(ValueError, match="a bug inside"):
        cli.run(train_cli.main, train_cli.PROG, ["--out", "unused", "--timesteps", "8"])


SUBPROCESS_CASES = [  # one per entry point; each a mistake found before torch is imported
    (["agents.train", "--timesteps", "-5"], "--timesteps"),
    (["agents.evaluate", "--episodes", "0"], "--episodes"),
    (["agents", "--out", "done"], "already holds a run"),
    (["rigid_env.bench", "accuracy", "--out", "file.txt"], "--out"),
    (["rigid_env.bench.env_speed", ID, "--seconds", "-1"], "--seconds"),
]


@pytest.mark.parametrize(
    "argv, expected", SUBPROCESS_CASES, ids=[a[0] for a, _ in SUBPROCESS_CASES]
)
def test_entry_points_exit_2_without_traceback(files, argv, expected):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-m", *argv], cwd=files, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert expected in proc.stderr


def test_run_folder_policy_without_the_command_line(tmp_path):
    """The library checks too (UsageError is a ValueError naming the parameter)."""
    (tmp_path / "run.json").write_text(json.dumps({"env_id": ID}))
    with pytest.raises(ValueError, match="--out"):
        run_folder.check_new(tmp_path, overwrite=False)
    run_folder.check_new(tmp_path, overwrite=True)
    run_folder.check_new(tmp_path / "fresh", overwrite=False)
    with pytest.raises(ValueError, match="timesteps"):
        train(ID, timesteps=0, out=tmp_path / "x")
    with pytest.raises(ValueError, match="seed"):
        train(ID, seed=-1, out=tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_sigterm_stops_any_command_with_status_130_without_traceback(tmp_path):
    """Outside training too (here a benchmark), SIGTERM ends a command like Ctrl-C does."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    argv = ["rigid_env.bench.env_speed", ID, "--seconds", "2", "--num-envs", "4"]
    out = tmp_path / "stdout.txt"
    with out.open("w") as stdout:
        proc = subprocess.Popen(
            [sys.executable, "-m", *argv], env=env, stdout=stdout, stderr=subprocess.PIPE, text=True
        )
        deadline = time.monotonic() + 60
        while "single env" not in out.read_text():  # printed after the first 2 s of stepping
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == cli.EXIT_INTERRUPTED
    stderr = proc.stderr.read()
    assert "Traceback" not in stderr and "interrupted" in stderr
