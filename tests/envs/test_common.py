"""Both environments: registration, the ``rigid_env:`` prefix, and the env checkers."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from env_testing import BAD_ACTIONS, assert_bad_action_rejected, assert_checkers_pass, make_vec
from gymnasium.vector import AutoresetMode

import rigid_env
from rigid_env.envs import ENV_SPECS
from rigid_env.envs.box_landing import BoxLandingEnv, BoxLandingVectorEnv
from rigid_env.envs.reorient import ReorientEnv, ReorientVectorEnv

ROOT = Path(rigid_env.__file__).resolve().parents[1]
ENVS = {
    "RigidEnv/Reorient-v0": (ReorientEnv, ReorientVectorEnv),
    "RigidEnv/BoxLanding-v0": (BoxLandingEnv, BoxLandingVectorEnv),
}


def test_every_registered_env_is_covered():
    assert set(ENV_SPECS) == set(ENVS)


@pytest.mark.parametrize("env_id", ENVS)
def test_registered_with_time_limit_and_vector_entry_point(env_id):
    single, vector = ENVS[env_id]
    spec = gym.spec(env_id)
    assert spec.max_episode_steps == ENV_SPECS[env_id]["max_episode_steps"]
    assert isinstance(gym.make(env_id).unwrapped, single)
    vec = make_vec(env_id, 3)
    assert isinstance(vec.unwrapped, vector)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert vec.unwrapped.max_episode_steps == spec.max_episode_steps


@pytest.mark.parametrize("env_id", ENVS)
def test_make_with_module_prefix_needs_no_import(env_id):
    code = f"import gymnasium as g; e = g.make('rigid_env:{env_id}'); e.reset(seed=0)"
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
    assert np.all(a[0][:, -3:] == 0), "previous action (last 3 entries) is cleared at reset"
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
