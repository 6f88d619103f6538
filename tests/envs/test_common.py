"""Both environments: registration, the ``rigid_env:`` prefix, and the env checkers."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from env_testing import (
    BAD_ACTIONS,
    assert_bad_action_rejected,
    assert_checkers_pass,
    make_vec,
    part,
)
from gymnasium.vector import AutoresetMode

import rigid_env
from rigid_env.envs import ENV_SPECS, box_landing, reorient
from rigid_env.envs.box_landing import BoxLandingConfig, BoxLandingEnv, BoxLandingVectorEnv
from rigid_env.envs.reorient import ReorientConfig, ReorientEnv, ReorientVectorEnv

ROOT = Path(rigid_env.__file__).resolve().parents[1]
ENVS = {
    "RigidEnv/Reorient-v0": (ReorientEnv, ReorientVectorEnv),
    "RigidEnv/BoxLanding-v0": (BoxLandingEnv, BoxLandingVectorEnv),
}
MODULES = {"RigidEnv/Reorient-v0": reorient, "RigidEnv/BoxLanding-v0": box_landing}
CONFIGS = {"RigidEnv/Reorient-v0": ReorientConfig, "RigidEnv/BoxLanding-v0": BoxLandingConfig}
# Short BoxLanding drops, so the episodes below touch down (contact, bounces) within a few steps.
FAST = {"RigidEnv/Reorient-v0": {}, "RigidEnv/BoxLanding-v0": dict(height_range=(0.3, 0.5))}


def test_every_registered_env_is_covered():
    assert set(ENV_SPECS) == set(ENVS)


@pytest.mark.parametrize("env_id", ENVS)
def test_registered_with_time_limit_and_vector_entry_point(env_id):
    single, vector = ENVS[env_id]
    spec = gym.spec(env_id)
    # The registered limit is the env module's own constant, and the vector env's default.
    assert spec.max_episode_steps == MODULES[env_id].MAX_EPISODE_STEPS
    assert vector.default_max_episode_steps == MODULES[env_id].MAX_EPISODE_STEPS
    assert isinstance(gym.make(env_id).unwrapped, single)
    vec = make_vec(env_id, 3)
    assert isinstance(vec.unwrapped, vector)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert vec.unwrapped.max_episode_steps == spec.max_episode_steps


@pytest.mark.parametrize("env_id", ENVS)
def test_a_given_episode_limit_shows_in_the_spec(env_id):
    # make_vec passes max_episode_steps to the vector env, which truncates there; its spec
    # says so (make's TimeLimit already did).
    registered = gym.spec(env_id).max_episode_steps
    vec = make_vec(env_id, 2, max_episode_steps=7)
    assert vec.spec.max_episode_steps == vec.unwrapped.max_episode_steps == 7
    assert vec.spec.kwargs["max_episode_steps"] == 7 and gym.spec(env_id).max_episode_steps == (
        registered
    )
    vec.reset(seed=0)
    truncated = [vec.step(np.zeros((2, 3), np.float32))[3].all() for _ in range(7)]
    assert truncated == [False] * 6 + [True]
    assert make_vec(env_id, 2).spec.max_episode_steps == registered
    assert gym.make(env_id, max_episode_steps=7).spec.max_episode_steps == 7


@pytest.mark.parametrize("env_id", ENVS)
def test_make_with_module_prefix_needs_no_import(env_id):
    code = f"import gymnasium as g; e = g.make('rigid_env:{env_id}'); e.reset(seed=0)"
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=60)


@pytest.mark.parametrize(
    "code",
    [
        # The simulator loads without Gymnasium.
        "import sys, rigid_env.sim; assert 'gymnasium' not in sys.modules",
        # Importing the package before Gymnasium still registers the ids once Gymnasium loads,
        # and importing the simulator first does not stop the prefix form from finding them.
        "import rigid_env, gymnasium as g; g.make('RigidEnv/Reorient-v0').reset(seed=0)",
        "import rigid_env.sim, gymnasium as g; g.make('rigid_env:RigidEnv/BoxLanding-v0')",
        # Gymnasium first, then the package: registered at import.
        "import gymnasium as g, rigid_env; g.make_vec('RigidEnv/BoxLanding-v0', 2,"
        " vectorization_mode='vector_entry_point')",
    ],
    ids=["sim-without-gymnasium", "package-then-gymnasium", "sim-then-prefix", "gymnasium-first"],
)
def test_imports_and_registration_orders(code):
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=60)


@pytest.mark.parametrize("render_mode", [None, "rgb_array", "human"])
@pytest.mark.parametrize("env_id", ENVS)
def test_gymnasium_and_sb3_checkers_pass_without_warnings(env_id, render_mode):
    assert_checkers_pass(env_id, render_mode=render_mode)


# --- native vector env: autoreset, seeding, masks ------------------------------------------------

# Info entries that a reset zeroes, per env (besides the cleared previous action).
RESET_INFO_ZERO = {"RigidEnv/Reorient-v0": (), "RigidEnv/BoxLanding-v0": ("touchdowns",)}


@pytest.mark.parametrize("env_id", ENVS)
def test_autoreset_ignores_the_action_and_returns_reset_values(env_id):
    envs = [make_vec(env_id, 2, max_episode_steps=3) for _ in range(2)]
    for env in envs:
        env.reset(seed=7)
        for _ in range(3):
            _, _, _, truncated, _ = env.step(np.zeros((2, 3), np.float32))
        assert truncated.all()
    a = envs[0].step(np.ones((2, 3), np.float32))
    b = envs[1].step(-np.ones((2, 3), np.float32))
    assert np.array_equal(a[0], b[0]), "the action on the autoreset step must be ignored"
    assert not a[1].any() and not a[2].any() and not a[3].any()
    assert np.all(part(envs[0], a[0], "previous_action") == 0), "cleared at reset"
    for key in RESET_INFO_ZERO[env_id]:
        assert np.all(a[4][key] == 0)


@pytest.mark.parametrize("env_id", ENVS)
def test_vector_reset_seed_list_and_reset_mask(env_id):
    env = make_vec(env_id, 3)
    obs, _ = env.reset(seed=[5, 6, 7])
    ref, _ = make_vec(env_id, 3).reset(seed=5)
    assert np.array_equal(obs, ref)
    moved, *_ = env.step(0.5 * np.ones((3, 3), np.float32))
    partial, _ = env.reset(options={"reset_mask": np.array([False, True, False])})
    assert np.array_equal(partial[[0, 2]], moved[[0, 2]])
    assert not np.array_equal(partial[1], moved[1])
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_mask": np.array([False, False, False])})


# --- bad actions ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", BAD_ACTIONS)
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_actions_raise_and_leave_env_usable(env_id, kind):
    assert_bad_action_rejected(env_id, kind)


@pytest.mark.parametrize(
    "bad", [np.full((2, 3), np.nan), np.full((2, 3), np.inf), np.zeros(3), np.zeros((3, 2))]
)
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_vector_action_raises_and_leaves_env_usable(env_id, bad):
    env, twin = make_vec(env_id, 2), make_vec(env_id, 2)
    env.reset(seed=1)
    twin.reset(seed=1)
    with pytest.raises(ValueError, match="action"):
        env.step(bad)
    good = 0.2 * np.ones((2, 3), np.float32)
    assert np.array_equal(env.step(good)[0], twin.step(good)[0])


# --- named observation parts, reward terms, configuration ----------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_observation_structure_names_every_entry_and_matches_the_state(env_id):
    env = gym.make(env_id)
    structure = env.unwrapped.observation_structure
    assert sum(structure.values()) == env.observation_space.shape[0]
    assert make_vec(env_id, 2).unwrapped.observation_structure == structure
    obs, _ = env.reset(seed=3)
    action = np.array([0.5, -0.25, 1.0], np.float32)
    obs, *_ = env.step(action)
    task = env.unwrapped.task
    # Parts read back what they name: the previous action and the scaled body angular velocity.
    assert np.array_equal(part(env, obs, "previous_action"), action)
    omega = task.state.body_angular_velocity[0, 0] / task.spin_scale
    np.testing.assert_allclose(part(env, obs, "angular_velocity"), omega, rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="obs"):
        part(env, obs[:-1], "previous_action")


@pytest.mark.parametrize("env_id", ENVS)
def test_reward_terms_in_info_sum_to_the_reward(env_id):
    # The reward is the sum of the reward_* terms, added in the order of task.reward_terms: the
    # same float64 additions in the same order, so the sums agree to rounding of 5 terms at most.
    env = gym.make(env_id, **FAST[env_id])
    _, info = env.reset(seed=2)
    terms = env.unwrapped.task.reward_terms
    assert {k for k in info if k.startswith("reward_")} == set(terms)
    assert all(info[k] == 0.0 for k in terms), "a reset starts with no reward"
    rng = np.random.default_rng(2)
    nonzero = set()
    for _ in range(40):
        _, reward, _, _, info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        assert reward == pytest.approx(sum(info[k] for k in terms), rel=1e-14, abs=1e-15)
        nonzero |= {k for k in terms if info[k] != 0.0}
    assert {"reward_angle", "reward_spin", "reward_ctrl"} <= nonzero
    # Batched: the same for every sub-env, including the autoreset step (all terms 0).
    vec = make_vec(env_id, 3, max_episode_steps=5, **FAST[env_id])
    vec.reset(seed=2)
    for _ in range(8):
        _, reward, _, _, info = vec.step(rng.uniform(-1, 1, (3, 3)).astype(np.float32))
        total = np.sum([info[k] for k in terms], axis=0)
        np.testing.assert_allclose(reward, total, rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("env_id", ENVS)
def test_a_config_object_or_keywords_but_not_both(env_id):
    config = CONFIGS[env_id](dt=0.01, frame_skip=3)
    task = gym.make(env_id, config=config).unwrapped.task
    assert task.config is config and (task.dt, task.frame_skip) == (0.01, 3)
    assert make_vec(env_id, 2, config=config).unwrapped.task.config is config
    with pytest.raises(ValueError, match="config"):
        gym.make(env_id, config=config, dt=0.02)
    with pytest.raises(ValueError, match="config"):
        gym.make(env_id, config={"dt": 0.01})
    with pytest.raises(ValueError, match="frame_skip"):
        CONFIGS[env_id](frame_skip=0)
    # A config is a value: replace() builds a new one, validated again, the body rebuilt.
    heavier = dataclasses.replace(config, mass=3.0)
    assert heavier.rigid_body.mass == 3.0 and config.rigid_body.mass != 3.0
    with pytest.raises(ValueError, match="dt"):
        dataclasses.replace(config, dt=-1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.dt = 0.5


@pytest.mark.parametrize("env_id", ENVS)
def test_the_backend_argument_picks_the_simulator_step(env_id):
    """``backend`` reaches the task's scene; over threads a vector env's elements are stepped by
    the same per-element arithmetic, so its rollout equals the serial one bit for bit."""
    with pytest.raises(ValueError, match="backend"):
        CONFIGS[env_id](backend="gpu")
    with pytest.raises(ValueError, match="backend"):
        gym.make(env_id, backend="numpy")  # the numpy step was removed
    runs = []
    for backend in ("compiled", "compiled-threads"):
        env = make_vec(env_id, 6, backend=backend, **FAST[env_id])
        assert env.unwrapped.task.scene.backend == "compiled"
        env.action_space.seed(3)
        obs, _ = env.reset(seed=11)
        seen = [obs]
        for _ in range(20):
            seen.append(env.step(env.action_space.sample())[0])
        runs.append(np.array(seen))
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("env_id", ENVS)
def test_default_spin_scale_is_the_top_of_the_spin_range_but_at_least_one(env_id):
    cls = CONFIGS[env_id]
    assert cls(spin_range=(0.0, 2.5)).observed_spin_scale == 2.5
    assert cls(spin_range=(0.0, 0.5)).observed_spin_scale == 1.0
    assert cls(spin_range=(0.0, 0.5), spin_scale=0.25).observed_spin_scale == 0.25


# --- the Gymnasium ecosystem -----------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_record_video_writes_an_episode_headless(env_id, tmp_path):
    from gymnasium.wrappers import RecordVideo  # writes with moviepy (extra 'render')

    env = RecordVideo(
        gym.make(env_id, render_mode="rgb_array", max_episode_steps=6, **FAST[env_id]),
        str(tmp_path / "videos"),
        episode_trigger=lambda episode: True,
        disable_logger=True,
    )
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = sorted((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
