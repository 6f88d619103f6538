"""User mistakes on every command line: one line on stderr, exit status 2, nothing written.

Most cases call the commands in process through :func:`rigid_env.cli.run` (the function the
``python -m`` entry points call); a few run the real entry points in subprocesses to check the
exit status and the absence of a traceback end to end.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from agents import evaluate, main_job, run_folder, train_cli
from agents.train import resume, train
from rigid_env import cli
from rigid_env.bench import __main__ as bench_cli
from rigid_env.bench import (
    contact_solve,
    env_speed,
    landing_cost,
    landing_episode,
    readme,
    reorient_frame,
    step_cost,
)
from rigid_env.cli import UsageError

ID = "RigidEnv/Reorient-v0"
ROOT = Path(__file__).resolve().parents[2]
COMMANDS = {
    "train": (train_cli.main, train_cli.PROG),
    "evaluate": (evaluate.main, evaluate.PROG),
    "main_job": (main_job.main, main_job.PROG),
    "bench": (bench_cli.main, bench_cli.PROG),
    "env_speed": (env_speed.main, env_speed.PROG),
    "contact_solve": (contact_solve.main, contact_solve.PROG),
    "landing_cost": (landing_cost.main, landing_cost.PROG),
    "landing_episode": (landing_episode.main, landing_episode.PROG),
    "step_cost": (step_cost.main, step_cost.PROG),
    "reorient_frame": (reorient_frame.main, reorient_frame.PROG),
    "readme": (readme.main, readme.PROG),
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
    (["--set", "n_steps=abc"], "n_steps must be an integer >= 1, got 'abc'"),
    (["--set", "policy_kwargs={no_such_option: 1}"], "PPO rejects"),
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
    # Values stable-baselines3 accepts but cannot train with, refused naming the parameter.
    (["--set", "gamma=1.5"], "gamma must be a number in (0, 1], got 1.5"),
    (["--set", "gamma=0"], "gamma must be a number in (0, 1], got 0"),
    (["--set", "n_epochs=0"], "n_epochs must be an integer >= 1, got 0"),
    (["--set", "policy_kwargs={net_arch: [-8]}"], "policy_kwargs net_arch must be a list"),
    (["--set", "policy_kwargs={net_arch: {pi: [8], vf: [0]}}"], "policy_kwargs net_arch"),
    (["--set", "policy_kwargs={activation_fn: Nope}"], "policy_kwargs activation_fn"),
    (["--set", "learning_rate=0"], "learning_rate must be a finite number > 0"),
    (["--set", "learning_rate=.inf"], "learning_rate must be a finite number > 0"),
    (["--set", "learning_rate=lin_-1e-3"], "learning_rate must be"),
    (["--set", "clip_range=0"], "clip_range must be"),
    (["--set", "gae_lambda=2"], "gae_lambda must be a number in [0, 1]"),
    (["--set", "ent_coef=-1"], "ent_coef must be a finite number >= 0"),
    (["--set", "max_grad_norm=0"], "max_grad_norm must be a finite number > 0"),
    (["--set", "batch_size=1"], "batch_size must be >= 2"),
    (["--set", "n_steps=1", "--n-envs", "1"], "n_steps x n_envs must be > 1"),
    (["--set", "n_steps=2.5"], "n_steps must be an integer >= 1, got 2.5"),
    (["--set", "policy=CnnPolicy"], 'policy must be "MlpPolicy"'),
    (["--algo", "sac", "--set", "tau=0"], "tau must be a number in (0, 1]"),
    (["--algo", "sac", "--set", "buffer_size=0"], "buffer_size must be an integer >= 1"),
    (["--algo", "sac", "--set", "train_freq=[1, hour]"], "train_freq must be"),
    (["--algo", "sac", "--set", "gradient_steps=0"], "gradient_steps must be"),
    (["--algo", "sac", "--set", "ent_coef=auto_-1"], "ent_coef must be"),
    # Sizes that cannot fit in memory, refused with an estimate.
    (["--n-envs", "1000000000"], "needs ~"),
    (["--set", "eval_episodes=1000000000"], "needs ~"),
    (["--set", "policy_kwargs={net_arch: [1000000, 1000000]}"], "networks"),
    (
        ["--algo", "sac", "--set", "buffer_size=100000000000", "--timesteps", "100000000000"],
        "buffer",
    ),  # fmt: skip
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
    (["--episodes", "1000000000"], "--episodes 1000000000 (RigidEnv/Reorient-v0) needs ~"),
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
    (["--episodes", "1000000000"], "needs ~"),
    (["--set", "gamma=2"], "gamma must be a number in (0, 1]"),
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
    ("env_speed", [ID, "--num-envs", "1000000000000"], "--num-envs 1000000000000"),
    ("contact_solve", ["--dt", "0"], "--dt"),
    ("contact_solve", ["--dt", "-0.01"], "--dt"),
    ("contact_solve", ["--dt", "nan"], "--dt"),
    ("contact_solve", ["--dt", "inf"], "--dt"),
    (
        "contact_solve",
        ["--dt", "1e300", "--steps", "5", "--only", "landing", "--starts", "particle"],
        "--dt 1e+300: the step diverged",
    ),  # fmt: skip
    ("contact_solve", ["--steps", "-1"], "--steps"),
    ("contact_solve", ["--steps", "0"], "--steps"),
    ("contact_solve", ["--steps", "100000000000000"], "needs ~"),
    ("contact_solve", ["--landing-batch", "0"], "--landing-batch"),
    ("contact_solve", ["--landing-batch", "1000000000000"], "--landing-batch 1000000000000"),
    ("contact_solve", ["--rollout", "boxlanding", "--episodes", "0"], "--episodes"),
    ("contact_solve", ["--rollout", "boxlanding", "--episodes", "10000000000"], "needs ~"),
    ("contact_solve", ["--rollout", "boxlanding", "--newton-after", "0"], "--newton-after"),
    ("contact_solve", ["--rollout", "boxlanding", "--newton-steps", "-1"], "--newton-steps"),
    ("contact_solve", ["--rollout", "boxlanding", "--policy", "missing.zip"], "no such file"),
    ("contact_solve", ["--rollout", "boxlanding", "--policy", "bad.zip"], "cannot load"),
    ("landing_cost", ["--batch", "0"], "--batch"),
    ("landing_cost", ["--batch", "1000000000000"], "--batch 1000000000000 needs ~"),
    ("landing_cost", ["--repeats", "0"], "--repeats"),
    ("landing_cost", ["--block", "0"], "--block"),
    ("landing_cost", ["--block", "nan"], "--block"),
    ("landing_episode", ["--batch", "0"], "--batch"),
    ("landing_episode", ["--batch", "1000000000"], "--batch 1000000000 --actions 120 needs ~"),
    ("landing_episode", ["--actions", "0"], "--actions"),
    ("landing_episode", ["--repeats", "-1"], "--repeats"),
    ("step_cost", ["--repeats", "0"], "--repeats"),
    ("step_cost", ["--repeats", "-3"], "--repeats"),
    ("step_cost", ["--block", "-1"], "--block"),
    ("reorient_frame", ["--episodes", "0"], "--episodes"),
    ("reorient_frame", ["--num-envs", "0"], "--num-envs"),
    ("reorient_frame", ["--num-envs", "1000000000000"], "needs ~"),
    ("reorient_frame", ["--seconds", "0"], "--seconds"),
    ("readme", ["nowhere.md"], "nowhere.md is not a file"),
    (
        "readme",
        [str(ROOT / "README.md"), "--check", "--results", "notes"],
        "--results: cannot render",
    ),  # fmt: skip
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
    (["rigid_env.bench.landing_cost", "--repeats", "0"], "--repeats"),
    (["rigid_env.bench.contact_solve", "--dt", "0"], "--dt"),
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


# --- hyperparameters from the Zoo-format files ----------------------------------------------------


@pytest.mark.parametrize(
    "line, expected",
    [
        ("  gamma: 0.99\n", "  gamma: 1.5\n"),
        ("  n_epochs: 10\n", "  n_epochs: 0\n"),
        ("net_arch=[128, 128]", "net_arch=[128, -128]"),
        ("  learning_rate: lin_1e-3\n", "  learning_rate: -1.0e-3\n"),
    ],
)
def test_a_bad_value_in_a_hyperparameter_file_is_one_line_naming_file_env_and_key(
    files, capsys, monkeypatch, line, expected
):
    from agents import config

    folder = files / "hyperparams"
    folder.mkdir()
    text = config.config_path("ppo").read_text()
    reorient = text.index("RigidEnv/Reorient-v0:")
    block_end = text.index("RigidEnv/BoxLanding-v0:")
    block = text[reorient:block_end]
    assert line in block
    (folder / "ppo.yml").write_text(
        text[:reorient] + block.replace(line, expected) + text[block_end:]
    )
    monkeypatch.setattr(config, "HYPERPARAMS_DIR", folder)
    key = expected.split(":")[0].split("=")[0].strip()
    err = f"ppo.yml (RigidEnv/Reorient-v0): {'policy_kwargs ' if key == 'net_arch' else ''}{key}"
    assert_usage_error("train", ["--out", "new_run", "--timesteps", "64"], err, capsys, files)
    # The other env's block is fine, and trains from the same file.
    from agents.plan import make_plan

    make_plan("RigidEnv/BoxLanding-v0", "ppo")


GOOD_VALUES = [
    ("ppo", {"learning_rate": "lin_3e-4", "clip_range": "lin_0.2", "clip_range_vf": None,
             "target_kl": 0.02, "gamma": 1, "gae_lambda": 0, "normalize_advantage": False,
             "batch_size": 1, "policy_kwargs": "dict(net_arch=dict(pi=[8], vf=[16, 16]), "
             "activation_fn=nn.ReLU, ortho_init=False)"}),
    ("sac", {"learning_rate": 3e-4, "ent_coef": "auto_0.1", "train_freq": [1, "episode"],
             "gradient_steps": -1, "target_entropy": -3.0, "learning_starts": 0, "tau": 1.0,
             "policy_kwargs": {"net_arch": {"pi": [8], "qf": [8]}, "n_critics": 1}}),
]  # fmt: skip


@pytest.mark.parametrize("algo, overrides", GOOD_VALUES, ids=[a for a, _ in GOOD_VALUES])
def test_values_that_train_are_accepted(algo, overrides):
    """The checks refuse only what cannot train: SB3's own edge values pass (and SB3 builds
    the model from them)."""
    from agents.plan import make_plan
    from agents.train import check_model

    plan = make_plan(ID, algo, 64, n_envs=2, overrides={**overrides, "buffer_size": 100}
                     if algo == "sac" else overrides)  # fmt: skip
    check_model(plan)


# --- a hand-edited run.json on --resume -----------------------------------------------------------


@pytest.fixture(scope="module")
def interrupted_run(tmp_path_factory) -> Path:
    """A tiny run stopped after a few steps: resumable (checkpoint.zip, status interrupted)."""
    out = tmp_path_factory.mktemp("interrupted") / "run"
    polls = [0]

    def stop() -> bool:
        polls[0] += 1
        return polls[0] > 4

    overrides = dict(n_envs=2, n_steps=32, batch_size=32, n_epochs=1, eval_freq=10**5,
                     eval_episodes=2, policy_kwargs={"net_arch": [8]})  # fmt: skip
    result = train(ID, timesteps=256, out=out, overrides=overrides, progress=False, stop=stop)
    assert result.status == "interrupted" and (out / "checkpoint.zip").is_file()
    return out


RECORD_EDITS = [
    ({"status": "paused"}, "status must be one of"),
    ({"evaluations": "none"}, "evaluations must be a list of rows"),
    (
        {
            "evaluations": [
                {"env_steps": "10", "mean_return": 1, "std_return": 0, "success_rate": 0}
            ]
        },
        "evaluations must be",
    ),  # fmt: skip
    ({"best_mean_return": "high"}, "best_mean_return must be null or a finite number"),
    ({"resumed_at": 5}, "resumed_at must be a list of step counts"),
    ({"checkpoint": {"steps": 8}}, "checkpoint must be null or"),
    ({"analytic": {"mean_return": "x"}}, "analytic must be null or a summary"),
    ({"steps_done": -1}, "steps_done must be a step count"),
    ({"loop": [1]}, "loop must be a mapping"),
    ({"env_kwargs": "fast"}, "env_kwargs must be a mapping"),
    ({"env_kwargs": {"no_such_option": 1}}, "env_kwargs: RigidEnv/Reorient-v0 rejects"),
    ({"timesteps": -1}, "timesteps must be an integer >= 1"),
    ({"n_envs": "2"}, "n_envs must be an integer >= 1"),
    ({"seed": 2**40}, "seed must be an integer <="),
    ({"eval_freq": None}, "eval_freq"),
    ({"algo": "dqn"}, "algo must be one of"),
    ({"env_id": "RigidEnv/NoSuch-v0"}, "unknown env id"),
    ({"env_id": ["RigidEnv/Reorient-v0"]}, "unknown env id"),
    ({"n_envs": 10**9}, "needs ~"),
]


@pytest.mark.parametrize("edit, expected", RECORD_EDITS, ids=[str(e)[:50] for e, _ in RECORD_EDITS])
def test_a_hand_edited_run_json_on_resume_is_one_line(interrupted_run, tmp_path, capsys, edit,
                                                      expected):  # fmt: skip
    run = tmp_path / "run"
    run.mkdir()
    for path in interrupted_run.iterdir():
        (run / path.name).write_bytes(path.read_bytes())
    record = json.loads((run / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({**record, **edit}))
    assert_usage_error("train", ["--resume", str(run)], expected, capsys, tmp_path)
    with pytest.raises(UsageError, match=re.escape(expected)):  # the library refuses alike
        resume(run, progress=False)


def test_memory_estimates_count_the_process_limit(monkeypatch):
    """``ulimit -v`` (RLIMIT_AS) lowers what is available below the machine's memory."""
    import resource

    from rigid_env import resources

    resources.check_envs(ID, 200_000, "--episodes")  # ~200 MB: fits a test machine
    real = resource.getrlimit
    limit = 64 * 2**20
    monkeypatch.setattr(
        resource,
        "getrlimit",
        lambda which: (
            (limit, resource.RLIM_INFINITY) if which == resource.RLIMIT_AS else real(which)
        ),
    )
    assert resources.available_memory() == limit
    with pytest.raises(UsageError, match=r"--episodes 200000 \(RigidEnv/Reorient-v0\) needs ~"
                       r"195 MiB, this machine has 64 MiB available"):  # fmt: skip
        resources.check_envs(ID, 200_000, "--episodes")
