"""The contact-solve bench's BoxLanding rollout acts with the policy it is given."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rigid_env.envs  # noqa: F401  (registers the envs)
from rigid_env.bench import contact_solve
from rigid_env.cli import UsageError

ACTION = np.array([0.3, -0.2, 0.1], dtype=np.float32)


# The test's own env may meet a solve that stops at its cap: reported by this warning.
@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_rollout_acts_with_the_policy_on_the_envs_observations():
    # The policy must see each observation the env returns, in order, once per env step: a
    # fresh env seeded the same and stepped with the same actions gives that sequence.
    seen: list[np.ndarray] = []

    def policy(obs):
        seen.append(np.array(obs))
        return ACTION

    stats = contact_solve.rollout_boxlanding(1, seed=3, policy=policy)
    env = gym.make("RigidEnv/BoxLanding-v0")
    obs, _ = env.reset(seed=3)
    expected = [obs]
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(ACTION)
        done = terminated or truncated
        expected.append(obs)
    assert len(seen) == len(expected) - 1  # no action after the last observation
    np.testing.assert_array_equal(np.array(seen), np.array(expected[:-1]))
    assert stats["contact_steps"] > 0  # the box reaches the ground within the episode


def test_policy_option_loads_a_saved_model_and_names_it(tmp_path, capsys):
    from stable_baselines3 import PPO  # the rl extra, in dev

    path = tmp_path / "model.zip"
    PPO("MlpPolicy", gym.make("RigidEnv/BoxLanding-v0"), n_steps=64, device="cpu").save(path)
    contact_solve.main(["--rollout", "boxlanding", "--episodes", "1", "--policy", str(path)])
    line = capsys.readouterr().out
    assert f"policy {path}" in line and "contact steps" in line
    with pytest.raises(UsageError, match="--policy: no such file"):
        contact_solve.main(["--rollout", "boxlanding", "--policy", str(tmp_path / "none.zip")])
