"""End to end: a few hundred training steps, a saved model that agents.evaluate loads; configs."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest
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


@pytest.mark.parametrize("path", sorted(config.HYPERPARAMS_DIR.glob("*.yml")), ids=lambda p: p.name)
def test_config_files_load_and_build_models(path):
    import yaml

    blocks = yaml.safe_load(path.read_text())
    env_id = {
        config.config_path(i).name: i for i in ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0")
    }[path.name]
    assert set(blocks) <= set(config.ALGOS) and blocks
    for algo in blocks:
        loop, kwargs = config.load(env_id, algo)
        cls = {"ppo": PPO, "sac": SAC}[algo]
        assert set(kwargs) <= set(inspect.signature(cls.__init__).parameters), kwargs
        assert loop["n_timesteps"] > 0 and loop["n_envs"] > 0
        # Every argument is accepted by SB3 on the real (adapted) env.
        kwargs = {**kwargs, "buffer_size": 1000} if algo == "sac" else kwargs
        venv = GymVectorToSB3(make_vec(env_id, loop["n_envs"], **loop["env_kwargs"]))
        cls(env=venv, device="cpu", **kwargs)


def test_config_errors_name_the_parameter():
    with pytest.raises(ValueError, match="algo"):
        config.load(ID, "dqn")
    with pytest.raises(ValueError, match="env_id"):
        config.load("RigidEnv/NoSuchEnv-v0", "ppo")
    assert config.config_path("RigidEnv/BoxLanding-v0").name == "box_landing.yml"
    assert config.linear_schedule(2e-3)(0.25) == pytest.approx(5e-4)
