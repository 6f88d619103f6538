"""A capped contact solve inside BoxLanding: counted in info per env, warned once, in words."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from env_testing import assert_vector_equals_singles, make_vec

from rigid_env import sim
from rigid_env.envs.contact_caps import ContactCapWarning

ID = "RigidEnv/BoxLanding-v0"
# One sweep per solve: nearly every solve in contact stops at the cap.
CAPPING = dict(
    contact_solver=sim.SolverSettings(max_iterations=1, warm_start=True),
    height_range=(0.3, 0.5),
    frame_skip=4,
)


def run(env, steps, actions=None):
    """Step ``env`` with zero (or given) actions, recording every warning."""
    shape = env.action_space.shape
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        infos = [env.step(np.zeros(shape, np.float32))[4] for _ in range(steps)]
    return infos, caught


def test_capped_periods_are_counted_and_warned_once_per_env():
    env = gym.make(ID, max_episode_steps=1000, **CAPPING)
    _, info = env.reset(seed=0)
    assert info["contact_capped"] == 0
    infos, caught = run(env, 30)
    counts = [i["contact_capped"] for i in infos]
    assert counts[-1] > 5 and np.all(np.diff(counts) >= 0), counts
    kinds = [w.category for w in caught]
    # The simulator's own warning never reaches the user; the env's comes once, in words.
    assert kinds == [ContactCapWarning], kinds
    message = str(caught[0].message)
    assert "info['contact_capped']" in message and "adds no energy" in message
    # Attributed to the caller of env.step (here run(), in this file), past the wrappers.
    assert caught[0].filename == __file__
    # A new episode starts its count again; the same env does not warn again.
    env.reset(seed=1)
    infos, caught = run(env, 30)
    assert infos[0]["contact_capped"] <= 1 and infos[-1]["contact_capped"] > 5
    assert caught == []
    # Another env instance warns once of its own.
    other = gym.make(ID, **CAPPING)
    other.reset(seed=0)
    assert [w.category for w in run(other, 30)[1]] == [ContactCapWarning]


def test_default_settings_count_no_caps_on_a_quiet_landing():
    env = gym.make(ID, height_range=(0.3, 0.5), frame_skip=4, tilt_range=(0.0, 0.05))
    env.reset(seed=0)
    infos, caught = run(env, 30)
    assert infos[-1]["contact_capped"] == 0 and caught == []
    assert infos[-1]["touchdowns"] >= 1, "the box landed"


def test_vector_env_counts_per_sub_env_and_warns_once():
    env = make_vec(ID, 4, **CAPPING)
    env.reset(seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(30):
            info = env.step(np.zeros((4, 3), np.float32))[4]
    assert [w.category for w in caught] == [ContactCapWarning]
    assert info["contact_capped"].shape == (4,) and np.all(info["contact_capped"] > 0)


@pytest.mark.filterwarnings("ignore::rigid_env.envs.contact_caps.ContactCapWarning")
def test_vector_counts_equal_single_envs_seeded_s_plus_i():
    # assert_vector_equals_singles compares every info entry, contact_capped included.
    ends = assert_vector_equals_singles(
        ID, num_envs=3, seed=20, steps=24, max_episode_steps=10, **CAPPING
    )
    assert ends >= 3
