"""Both environments: registration, the ``rigid_env:`` prefix, and the env checkers."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest
from env_testing import assert_checkers_pass, make_vec
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
