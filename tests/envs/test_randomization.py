"""Per-episode torque limits and observation noise: off by default, seeded, in the docs' terms."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from env_testing import assert_checkers_pass, make_vec, part

from rigid_env.envs.box_landing import BoxLandingConfig
from rigid_env.envs.reorient import ReorientConfig

REORIENT, LANDING = "RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0"
ENVS = (REORIENT, LANDING)
FAST = {REORIENT: {}, LANDING: dict(height_range=(0.3, 0.5), frame_skip=4)}
NOISE = {
    REORIENT: {"error_quaternion": 0.01, "angular_velocity": 0.05},
    LANDING: {"height": 0.02, "linear_velocity": 0.05, "up": 0.01, "angular_velocity": 0.05},
}


def rollout(env_id, seed, steps, **kwargs):
    """Observations and infos of a single env under fixed actions, with its resets."""
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        out.append((obs, info))
        if terminated or truncated:
            out.append(env.reset())
    return out


# --- off by default ----------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_off_by_default_no_extra_draws_and_no_extra_info(env_id):
    env = gym.make(env_id)
    task = env.unwrapped.task
    assert task.config.torque_scale_range is None and task.config.observation_noise is None
    assert task.noise_index is None
    rng = np.random.default_rng(0)
    assert len(task.draw(rng)) == len(task.draw_start(rng)), "nothing drawn beyond the start"
    _, info = env.reset(seed=0)
    assert "observation_clean" not in info and "torque_limit" not in info


@pytest.mark.parametrize("env_id", ENVS)
def test_zero_noise_and_a_unit_torque_scale_leave_the_first_episode_bit_for_bit(env_id):
    # Noise of std 0 draws nothing; a range (1, 1) draws its uniform after the start, so the
    # first episode (until the next reset's draws) is the default one bit for bit.
    kwargs = dict(FAST[env_id], max_episode_steps=200)
    names = list(NOISE[env_id])
    base = rollout(env_id, 4, 15, **kwargs)
    zero = rollout(env_id, 4, 15, observation_noise=dict.fromkeys(names, 0.0), **kwargs)
    unit = rollout(env_id, 4, 15, torque_scale_range=(1.0, 1.0), **kwargs)
    for (bo, bi), (zo, zi), (uo, ui) in zip(base, zero, unit, strict=True):
        assert np.array_equal(bo, zo) and np.array_equal(bo, uo)
        assert bi.keys() == zi.keys() == ui.keys() - {"torque_limit"}
        np.testing.assert_array_equal(ui["torque_limit"], (1.0, 1.0, 1.0))


# --- torque limits -----------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_torque_limit_is_drawn_per_episode_in_its_range_and_seeded(env_id):
    env = make_vec(env_id, 64, torque_scale_range=(0.5, 2.0), max_torque=(1.0, 2.0, 0.5))
    _, info = env.reset(seed=0)
    limit = info["torque_limit"]
    scale = limit / np.array([1.0, 2.0, 0.5])
    assert np.allclose(scale, scale[:, :1]), "one scale for the three axes"
    assert scale.min() >= 0.5 and scale.max() <= 2.0 and np.ptp(scale[:, 0]) > 1.0
    again = make_vec(env_id, 64, torque_scale_range=(0.5, 2.0), max_torque=(1.0, 2.0, 0.5))
    assert np.array_equal(again.reset(seed=0)[1]["torque_limit"], limit)
    assert not np.array_equal(env.reset(seed=1)[1]["torque_limit"], limit)


def test_the_drawn_torque_limit_is_the_torque_applied():
    # Reorient from rest, action 1 about the principal body x axis for one action: the body
    # gains Ω_x = limit · period / I_x (a body-fixed torque about a principal axis of a body
    # at rest: ω × Iω = 0 throughout).
    env = gym.make(REORIENT, torque_scale_range=(0.25, 4.0), spin_range=(0.0, 0.0))
    task = env.unwrapped.task
    seen = []
    for seed in range(4):
        _, info = env.reset(seed=seed)
        env.unwrapped.set_state(orientation=(0, 0, 0, 1), target=(0, 0, 0, 1))
        obs, *_ = env.step(np.array([1.0, 0.0, 0.0], np.float32))
        omega = part(env, obs, "angular_velocity")[0] * task.spin_scale
        expected = info["torque_limit"][0] * task.config.action_period / task.inertia[0, 0]
        assert omega == pytest.approx(expected, rel=1e-6)  # float32 observation
        seen.append(info["torque_limit"][0])
    assert np.ptp(seen) > 0.5


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ((0.0, 1.0), "start above 0"),
        ((2.0, 1.0), "torque_scale_range"),
        ((1.0, float("nan")), "torque_scale_range"),
        ((1.0, 2e4), "torque_scale_range"),  # max_torque × 2e4 exceeds the 1e4 N m bound
        (1.5, "torque_scale_range"),
    ],
)
def test_bad_torque_scale_range_is_refused(value, match):
    for config in (ReorientConfig, BoxLandingConfig):
        with pytest.raises(ValueError, match=match):
            config(torque_scale_range=value)


# --- observation noise -------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_noise_has_the_stated_std_per_part_and_the_clean_observation_is_in_info(env_id):
    stds = NOISE[env_id]
    env = make_vec(env_id, 256, observation_noise=stds, **FAST[env_id])
    quiet = make_vec(env_id, 256, **FAST[env_id])
    obs, info = env.reset(seed=0)
    ref, _ = quiet.reset(seed=0)
    assert np.array_equal(info["observation_clean"], ref), "the clean observation is the env's"
    space = env.single_observation_space
    seen = {name: [] for name in env.unwrapped.observation_structure}
    for _ in range(4):
        assert env.observation_space.contains(obs)
        clean = info["observation_clean"].astype(float)
        for name in seen:
            noise = part(env, obs.astype(float) - clean, name)
            # Clipping to the space narrows the spread near a bound: keep clean values that
            # are 5 standard deviations inside both.
            std = stds.get(name, 0.0)
            inside = (part(env, clean - space.low, name) > 5 * std) & (
                part(env, space.high - clean, name) > 5 * std
            )
            seen[name].append(noise[inside] if std else noise.ravel())
        obs, _, _, _, info = env.step(np.zeros((256, 3), np.float32))
    for name, chunks in seen.items():
        noise = np.concatenate(chunks)
        if name not in stds:
            assert np.all(noise == 0), f"{name} has no noise"
        else:
            assert len(noise) > 1000, name
            assert np.std(noise) == pytest.approx(stds[name], rel=0.08), name
            assert abs(np.mean(noise)) < 0.1 * stds[name], name


@pytest.mark.parametrize("env_id", ENVS)
def test_noisy_episodes_are_reproducible_from_the_seed(env_id):
    kwargs = dict(FAST[env_id], observation_noise=NOISE[env_id], max_episode_steps=8)
    a, b = rollout(env_id, 6, 20, **kwargs), rollout(env_id, 6, 20, **kwargs)
    for (ao, ai), (bo, bi) in zip(a, b, strict=True):
        assert np.array_equal(ao, bo)
        assert np.array_equal(ai["observation_clean"], bi["observation_clean"])
    c = rollout(env_id, 7, 20, **kwargs)
    assert not np.array_equal(a[0][0], c[0][0])


@pytest.mark.parametrize("env_id", ENVS)
def test_partial_reset_keeps_the_other_sub_envs_noisy_observation(env_id):
    env = make_vec(env_id, 3, observation_noise=NOISE[env_id])
    env.reset(seed=0)
    obs = env.step(np.zeros((3, 3), np.float32))[0]
    again, _ = env.reset(options={"reset_mask": np.array([False, True, False])})
    assert np.array_equal(again[[0, 2]], obs[[0, 2]])


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ({"heading": 0.1}, "unknown observation part 'heading'"),
        ({"angular_velocity": -0.1}, r"observation_noise\['angular_velocity'\]"),
        ({"angular_velocity": 1e9}, r"observation_noise\['angular_velocity'\]"),
        (0.1, "observation_noise must be a dict"),
    ],
)
def test_bad_observation_noise_is_refused(value, match):
    for config in (ReorientConfig, BoxLandingConfig):
        with pytest.raises(ValueError, match=match):
            config(observation_noise=value)


@pytest.mark.parametrize("env_id", ENVS)
def test_checkers_pass_with_noise_and_torque_limits(env_id):
    # Gymnasium's checker resets twice with one seed and compares: noise is seeded too.
    assert_checkers_pass(env_id, observation_noise=NOISE[env_id], torque_scale_range=(0.5, 1.5))
