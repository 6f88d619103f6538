"""The SB3 adapter over a native vector env equals SB3's own DummyVecEnv of single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

import rigid_env  # noqa: F401
from agents.rollout import make_vec
from agents.vec_adapter import GymVectorToSB3

ID = "RigidEnv/Reorient-v0"
N = 4
# Short episodes that end both ways: truncation after 7 steps, or "success" (termination) as soon
# as the angle error is below 2 rad with any spin (hold_time 0: one step within suffices).
KW = dict(angle_threshold=2.0, spin_threshold=100.0, hold_time=0.0)
STEPS = 7


def make_pair(seed):
    adapter = GymVectorToSB3(make_vec(ID, N, max_episode_steps=STEPS, **KW))
    reference = DummyVecEnv([lambda: gym.make(ID, max_episode_steps=STEPS, **KW) for _ in range(N)])
    for venv in (adapter, reference):
        venv.seed(seed)
    return adapter, reference


def test_spaces_shapes_and_dtypes():
    adapter, _ = make_pair(0)
    obs = adapter.reset()
    assert adapter.num_envs == N
    single = gym.make(ID)
    assert adapter.observation_space == single.observation_space
    assert adapter.action_space == single.action_space
    assert obs.shape == (N, 10) and obs.dtype == np.float32
    assert isinstance(adapter.reset_infos, list) and len(adapter.reset_infos) == N
    obs, reward, done, infos = adapter.step(np.zeros((N, 3), np.float32))
    assert obs.shape == (N, 10) and obs.dtype == np.float32
    assert reward.shape == (N,) and reward.dtype == np.float32
    assert done.shape == (N,) and done.dtype == np.bool_
    assert isinstance(infos, list) and len(infos) == N and all(isinstance(i, dict) for i in infos)
    assert all(isinstance(i["is_success"], bool) for i in infos)
    assert adapter.get_attr("render_mode") == [None] * N


def test_steps_match_dummy_vec_env_with_same_step_resets_and_terminal_observations():
    adapter, reference = make_pair(3)
    np.testing.assert_array_equal(adapter.reset(), reference.reset())
    rng = np.random.default_rng(0)
    ended = {"terminated": 0, "truncated": 0}
    for _ in range(40):
        action = rng.uniform(-1, 1, (N, 3)).astype(np.float32)
        obs, reward, done, infos = adapter.step(action)
        ref_obs, ref_reward, ref_done, ref_infos = reference.step(action)
        # The returned obs of a finished env is already its next episode's reset obs, and the
        # next action acts in that episode: no transition across a reset reaches the learner.
        np.testing.assert_array_equal(obs, ref_obs)
        np.testing.assert_array_equal(reward, ref_reward)
        np.testing.assert_array_equal(done, ref_done)
        for i in range(N):
            assert ("terminal_observation" in infos[i]) == bool(done[i])
            if done[i]:
                np.testing.assert_array_equal(
                    infos[i]["terminal_observation"], ref_infos[i]["terminal_observation"]
                )
                assert not np.array_equal(infos[i]["terminal_observation"], obs[i])
                truncated = infos[i]["TimeLimit.truncated"]
                assert truncated == ref_infos[i]["TimeLimit.truncated"]
                ended["truncated" if truncated else "terminated"] += 1
            assert infos[i]["is_success"] == ref_infos[i]["is_success"]
    assert ended["terminated"] > 0 and ended["truncated"] > 0  # both ways were exercised


def test_terminal_observation_is_the_final_observation_of_the_episode():
    # Drive the raw NEXT_STEP vector env alongside: at the step an episode ends, its returned obs
    # is the final one, which the adapter must report as terminal_observation.
    adapter = GymVectorToSB3(make_vec(ID, N, max_episode_steps=STEPS, **KW))
    raw = make_vec(ID, N, max_episode_steps=STEPS, **KW)
    adapter.seed(5)
    adapter.reset()
    raw.reset(seed=5)
    for _ in range(STEPS):
        action = np.zeros((N, 3), np.float32)
        obs, _, done, infos = adapter.step(action)
        raw_obs, _, term, trunc, _ = raw.step(action)
        if done.any():  # first ends: both envs are still in step
            i = int(np.flatnonzero(done)[0])
            np.testing.assert_array_equal(infos[i]["terminal_observation"], raw_obs[i])
            np.testing.assert_array_equal(done, term | trunc)
            # The raw env resets on its next step; its reset obs is what the adapter returned.
            raw_next, reward, *_ = raw.step(action)
            np.testing.assert_array_equal(obs[i], raw_next[i])
            assert reward[i] == 0.0  # the raw env's placeholder step the adapter skips
            return
        np.testing.assert_array_equal(obs, raw_obs)
    pytest.fail("no episode ended")


def test_seeding_is_deterministic():
    def stream(seed):
        adapter = GymVectorToSB3(make_vec(ID, N, max_episode_steps=STEPS, **KW))
        adapter.seed(seed)
        out = [adapter.reset()]
        for _ in range(12):
            out.append(adapter.step(np.full((N, 3), 0.3, np.float32))[0])
        return np.stack(out)

    np.testing.assert_array_equal(stream(1), stream(1))
    assert not np.array_equal(stream(1), stream(2))


def test_rejects_a_vector_env_without_next_step_autoreset():
    venv = gym.make_vec(ID, num_envs=2, vectorization_mode="sync")
    venv.metadata["autoreset_mode"] = gym.vector.AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match="autoreset"):
        GymVectorToSB3(venv)
