"""The one env-speed loop (rigid_env.bench.env_speed.run), as bench.speed uses it.

Rates are machine noise and never asserted; what the loop counts and times is.
"""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

from rigid_env.bench import env_speed, peers, speed

ID = "RigidEnv/Reorient-v0"


def test_run_counts_env_steps_and_times_the_physics_inside_the_wall_time():
    single = env_speed.run(gym.make(ID, max_episode_steps=3), steps=7)  # resets on the way
    assert single.env_steps == 7
    assert 0.0 < single.physics_s < single.wall_s
    vec = gym.make_vec(ID, num_envs=4, vectorization_mode="vector_entry_point")
    batched = env_speed.run(vec, steps=5)
    assert batched.env_steps == 20 and batched.steps_per_s == 20 / batched.wall_s
    assert 0.0 < batched.physics_share < 1.0
    with pytest.raises(ValueError, match="steps"):
        env_speed.run(vec, steps=5, seconds=1.0)


def test_speed_reports_every_env_single_and_vector_with_the_same_loop():
    rows = speed.env_speed({"env_steps": 2, "env_batches": (1, 3)})
    ours = [r for r in rows if r["env"].startswith("RigidEnv/")]
    assert {(r["env"], r["mode"], r["num_envs"]) for r in ours} == {
        (env_id, mode, n)
        for env_id in ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0")
        for mode, n in (("single", 1), ("vector", 1), ("vector", 3))
    }
    assert all(r["env_steps_per_s"] > 0 and 0 < r["physics_share"] < 1 for r in ours)
    # Hopper-v5 beside them exactly when MuJoCo is there, without a physics share to report.
    peer = [r for r in rows if r not in ours]
    expected = [("Hopper-v5", "single (peer)", 1)] if peers.available() else []
    assert [(r["env"], r["mode"], r["num_envs"]) for r in peer] == expected
    assert all(r["env_steps_per_s"] > 0 and "physics_share" not in r for r in peer)


def test_a_peer_env_is_timed_by_the_same_loop_without_a_physics_figure():
    # Pendulum-v1 stands in for Hopper-v5 (no MuJoCo needed): not a rigid_env task, so the
    # loop has no scene to time and reports the physics as NaN rather than a made-up share.
    rate = env_speed.run(gym.make("Pendulum-v1"), steps=4)
    assert rate.env_steps == 4 and rate.wall_s > 0
    assert math.isnan(rate.physics_s)


def test_main_prints_each_env_and_its_ratio_to_the_peer(capsys):
    argv = [ID, "--seconds", "0.05", "--num-envs", "2", "--peer", "Pendulum-v1"]
    assert env_speed.main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("single env      :") == 2 and out.count("vector env x2") == 1
    assert f"{ID} single / Pendulum-v1 single:" in out
    assert env_speed.main([ID, "--seconds", "0.05", "--num-envs", "2", "--peer", "none"]) == 0
    assert "single /" not in capsys.readouterr().out


def test_main_passes_the_backend_to_both_envs(monkeypatch):
    made = []
    real_make, real_make_vec = gym.make, gym.make_vec

    def make(env_id, **kwargs):
        made.append(("single", kwargs.get("backend")))
        return real_make(env_id, **kwargs)

    def make_vec(env_id, **kwargs):
        made.append(("vector", kwargs.get("backend")))
        return real_make_vec(env_id, **kwargs)

    monkeypatch.setattr(env_speed.gym, "make", make)
    monkeypatch.setattr(env_speed.gym, "make_vec", make_vec)
    argv = [ID, "--seconds", "0.02", "--num-envs", "2", "--peer", "none"]
    assert env_speed.main([*argv, "--backend", "compiled-threads"]) == 0
    assert env_speed.main(argv) == 0
    threads = "compiled-threads"
    assert made == [("single", threads), ("vector", threads), ("single", None), ("vector", None)]


def test_randomise_gives_both_envs_the_randomised_physics(monkeypatch, capsys):
    made = []
    real_make, real_make_vec = gym.make, gym.make_vec

    def make(env_id, **kwargs):
        made.append((env_id, "single", kwargs))
        return real_make(env_id, **kwargs)

    def make_vec(env_id, **kwargs):
        made.append((env_id, "vector", kwargs))
        return real_make_vec(env_id, **kwargs)

    monkeypatch.setattr(env_speed.gym, "make", make)
    monkeypatch.setattr(env_speed.gym, "make_vec", make_vec)
    argv = ["--seconds", "0.02", "--num-envs", "2", "--peer", "none", "--randomise"]
    assert env_speed.main(argv) == 0
    assert capsys.readouterr().out.count("(randomised physics)") == 2
    assert [(e, mode) for e, mode, _ in made] == [
        (env_id, mode) for env_id in env_speed.RIGID_ENVS for mode in ("single", "vector")
    ]
    for env_id, _, kwargs in made:
        assert {k: kwargs[k] for k in env_speed.RANDOMISED[env_id]} == env_speed.RANDOMISED[env_id]
    for env_id in env_speed.RIGID_ENVS:  # and such an env steps with per-env parameters
        vec = real_make_vec(
            env_id,
            num_envs=2,
            vectorization_mode="vector_entry_point",
            **env_speed.RANDOMISED[env_id],
        )
        vec.reset(seed=0)
        task = vec.unwrapped.task
        assert task.parameters is not None and task.parameters.rows == 2
