"""End to end: a few hundred training steps, a saved model that agents.evaluate loads; configs."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC

from agents import config, evaluate, policies
from agents.rollout import make_vec, run_episodes
from agents.train import train
from agents.vec_adapter import GymVectorToSB3

ID = "RigidEnv/Reorient-v0"
TINY = {
    "ppo": dict(n_envs=4, eval_freq=256, eval_episodes=4, n_steps=64, batch_size=64, n_epochs=1),
    "sac": dict(
        n_envs=2,
        eval_freq=200,
        eval_episodes=4,
        learning_starts=50,
        batch_size=32,
        buffer_size=1000,
        gradient_steps=1,
    ),
}


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_short_training_saves_a_model_that_evaluate_loads(algo, tmp_path, capsys):
    out = tmp_path / "run"
    result = train(ID, algo, timesteps=400, seed=1, out=out, overrides=TINY[algo], progress=False)
    for name in (
        "best_model.zip",
        "final_model.zip",
        "monitor.csv",
        "learning_curve.png",
        "run.json",
        "evaluations.csv",
    ):
        assert (out / name).is_file(), name
    assert result.evaluations and result.evaluations[-1]["env_steps"] >= 400
    assert 0.0 < result.throughput["sim_share"] < result.throughput["env_share"] < 1.0
    assert policies.algo_of(out / "best_model.zip") == algo
    record = json.loads((out / "run.json").read_text())
    assert record["algo"] == algo and record["n_envs"] == TINY[algo]["n_envs"]

    capsys.readouterr()
    evaluate.main(
        ["--env", ID, "--policy", str(out / "best_model.zip"), "--episodes", "3", "--json"]
    )
    summary = json.loads(capsys.readouterr().out)
    assert summary["episodes"] == 3
    # The command's figures are those of the saved model run directly on the same seeded
    # episodes (deterministic actions, same seeds): the same episodes, so exactly the same.
    model = policies.load_model(out / "best_model.zip")
    direct = run_episodes(
        ID, lambda obs: model.predict(obs, deterministic=True)[0], 3, evaluate.DEFAULT_SEED
    )
    assert summary["success_rate"] == float(np.mean(direct.success))
    assert summary["mean_return"] == float(np.mean(direct.returns))
    assert summary["mean_length"] == float(np.mean(direct.lengths))


def test_evaluate_table_json_and_gif_for_builtin_policies(tmp_path, capsys):
    evaluate.main(
        ["--policy", "analytic", "--episodes", "4", "--json", "--gif", str(tmp_path / "clip.gif")]
    )
    summary = json.loads(capsys.readouterr().out)
    assert summary["success_rate"] == 1.0 and summary["episodes"] == 4
    import imageio.v2 as imageio

    frames = imageio.mimread(tmp_path / "clip.gif")
    assert len(frames) > 20 and frames[0].shape[-1] in (3, 4)
    evaluate.main(["--policy", "zero", "--episodes", "4"])
    table = capsys.readouterr().out
    assert "zero" in table and "0.0%" in table
    # The same seeds give the same figures; random draws its actions from the seed.
    a = evaluate.evaluate(ID, "random", 3, seed=5)
    b = evaluate.evaluate(ID, "random", 3, seed=5)
    assert a == b
    with pytest.raises(ValueError, match="policy"):
        evaluate.evaluate(ID, "no_such_policy", 2)


ENV_IDS = ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0")


@pytest.mark.parametrize("algo", config.ALGOS)
def test_config_files_load_and_build_models(algo):
    # Every shipped file covers both envs, and every argument is accepted by SB3 on the real
    # (adapted) env.
    assert sorted(config.env_ids(algo)) == sorted(ENV_IDS)
    cls = {"ppo": PPO, "sac": SAC}[algo]
    for env_id in ENV_IDS:
        loop, kwargs = config.load(env_id, algo)
        assert set(kwargs) <= set(inspect.signature(cls.__init__).parameters), kwargs
        assert loop["n_timesteps"] > 0 and loop["n_envs"] > 0
        assert loop["eval_freq"] > 0 and loop["eval_episodes"] > 0
        kwargs = {**kwargs, "buffer_size": 1000} if algo == "sac" else kwargs
        venv = GymVectorToSB3(make_vec(env_id, loop["n_envs"], **loop["env_kwargs"]))
        model = cls(env=venv, device="cpu", **kwargs)
        assert model.policy_kwargs["net_arch"] == [128, 128]


def test_config_errors_name_the_parameter():
    with pytest.raises(ValueError, match="algo"):
        config.load(ID, "dqn")
    with pytest.raises(ValueError, match="env_id"):
        config.load("RigidEnv/NoSuchEnv-v0", "ppo")
    with pytest.raises(ValueError, match="env_id"):
        config.load(config.EVALUATION, "ppo")
    assert config.config_path("sac").name == "sac.yml"
    assert config.linear_schedule(2e-3)(0.25) == pytest.approx(5e-4)
    # The Zoo's policy_kwargs expression resolves to classes, as the Zoo's own eval does.
    resolved = config.resolve({"policy_kwargs": "dict(net_arch=[8], activation_fn=nn.ReLU)"})
    assert resolved["policy_kwargs"] == {"net_arch": [8], "activation_fn": torch.nn.ReLU}


def test_rl_zoo_trains_both_envs_with_the_shipped_file(tmp_path):
    """``python -m rl_zoo3.train --gym-packages rigid_env --conf-file agents/hyperparams/ppo.yml``
    on a tiny budget (the Zoo's own --hyperparams overrides): it finds each env, accepts every
    key of the file and saves a model of the file's policy. In subprocesses, as users run it
    (importing rl_zoo3 also patches Gymnasium's TimeLimit for the whole process); the two envs
    train side by side (one per core)."""
    root = Path(config.__file__).resolve().parents[1]
    runs = {}
    for env_id in ENV_IDS:
        command = [
            *(sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", env_id),
            *("--gym-packages", "rigid_env", "--conf-file", str(config.config_path("ppo"))),
            *("-n", "256", "--seed", "0", "--eval-freq", "-1", "--device", "cpu"),
            *("--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"),
            *("--log-folder", str(tmp_path), "--num-threads", "1"),
        ]
        log = tmp_path / f"{env_id.replace('/', '-')}.log"
        with log.open("w") as out:  # a file, not a pipe: nothing blocks on a full buffer
            runs[env_id] = (subprocess.Popen(command, cwd=root, stdout=out, stderr=out), log)
    for env_id, (run, log) in runs.items():
        assert run.wait(timeout=300) == 0, (env_id, log.read_text()[-4000:])
        (saved,) = tmp_path.glob(f"ppo/*/{env_id.replace('/', '-')}.zip")
        # The saved model's record, read without unpickling it: its schedules are rl_zoo3
        # objects, and importing rl_zoo3 would patch this test process too.
        with zipfile.ZipFile(saved) as archive:
            data = json.loads(archive.read("data"))
            assert "policy.pth" in archive.namelist()
        assert data["num_timesteps"] == 256
        kwargs = data["policy_kwargs"]
        assert kwargs["net_arch"] == [128, 128] and kwargs["activation_fn"].endswith("Tanh'>")
    assert "rl_zoo3" not in sys.modules
