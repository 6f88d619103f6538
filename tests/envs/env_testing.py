"""Checks any rigid_env environment must pass, written once for every env id.

Each helper takes an env id and keyword arguments for ``gymnasium.make``; the per-env test
modules call them (and add their own physics and reward tests).
"""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import rigid_env  # noqa: F401  (registers the ids)
from rigid_env.envs import split_observation


def make_vec(env_id: str, num_envs: int, **kwargs):
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def part(env, obs: np.ndarray, name: str) -> np.ndarray:
    """The observation part ``name`` of ``obs`` (single or batched), by the env's structure."""
    return split_observation(obs, env.unwrapped.observation_structure)[name]


def assert_checkers_pass(env_id: str, ignore: tuple[type[Warning], ...] = (), **kwargs) -> None:
    """Gymnasium's and SB3's checkers, every warning an error (the checkers rebuild per mode)
    but the env's own of the categories ``ignore``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for category in ignore:
            warnings.simplefilter("ignore", category)
        env = gym.make(env_id, **kwargs)
        check_env(env.unwrapped)  # also makes one env per declared render mode from the spec
        sb3_check_env(env)
        sb3_check_env(env.unwrapped)
        env.close()


def single_rollout(env_id: str, seed: int, actions: np.ndarray, **kwargs) -> list[tuple]:
    """A single env driven like one sub-env of a NEXT_STEP vector env.

    ``actions`` is (T, *action_shape). The step after an episode ends is a ``reset()`` recorded
    as (obs, 0.0, False, False, info).
    """
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, False, False, info)]
    done = False
    for action in actions:
        if done:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
            done = False
        else:
            obs, reward, terminated, truncated, info = env.step(action)
            out.append((obs, reward, terminated, truncated, info))
            done = terminated or truncated
    env.close()
    return out


def vector_rollout(env_id: str, num_envs: int, seed: int, actions: np.ndarray, **kwargs):
    env = make_vec(env_id, num_envs, **kwargs)
    obs, info = env.reset(seed=seed)
    out = [(obs, np.zeros(num_envs), np.zeros(num_envs, bool), np.zeros(num_envs, bool), info)]
    for action in actions:
        out.append(env.step(action))
    env.close()
    return out


def assert_vector_equals_singles(
    env_id: str, num_envs: int, seed: int, steps: int, max_episode_steps: int, **kwargs
) -> int:
    """Vector env seeded ``seed`` vs single envs seeded ``seed + i``: equal bit for bit.

    Returns the number of episode ends seen, so callers can insist autoreset was exercised.
    """
    space = gym.make(env_id, **kwargs).action_space
    rng = np.random.default_rng(seed)
    actions = rng.uniform(space.low, space.high, (steps, num_envs, *space.shape)).astype(
        space.dtype
    )
    vec = vector_rollout(
        env_id, num_envs, seed, actions, max_episode_steps=max_episode_steps, **kwargs
    )
    ends = 0
    for i in range(num_envs):
        single = single_rollout(
            env_id, seed + i, actions[:, i], max_episode_steps=max_episode_steps, **kwargs
        )
        for t, ((vo, vr, vte, vtr, vinfo), (so, sr, ste, str_, sinfo)) in enumerate(
            zip(vec, single, strict=True)
        ):
            where = f"env {i}, step {t}"
            assert np.array_equal(vo[i], so), where
            assert vr[i] == sr and vte[i] == ste and vtr[i] == str_, where
            assert set(sinfo) <= set(vinfo), where
            for key, value in sinfo.items():
                assert vinfo["_" + key][i], where
                assert np.array_equal(vinfo[key][i], value), f"{where}, info[{key!r}]"
            ends += bool(ste or str_)
    return ends


def assert_deterministic(env_id: str, seed: int, steps: int, **kwargs) -> None:
    """Same seed, same actions: the same trajectory bit for bit, including across a reset."""
    space = gym.make(env_id, **kwargs).action_space
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, *space.shape)).astype(space.dtype)
    a = single_rollout(env_id, seed, actions, **kwargs)
    b = single_rollout(env_id, seed, actions, **kwargs)
    for (ao, ar, *_, ainfo), (bo, br, *_, binfo) in zip(a, b, strict=True):
        assert np.array_equal(ao, bo) and ar == br
        for key in ainfo:
            assert np.array_equal(ainfo[key], binfo[key])
    c = single_rollout(env_id, seed + 1, actions, **kwargs)
    assert not np.array_equal(a[0][0], c[0][0]), "a different seed must give a different start"


BAD_ACTIONS = ("nan", "inf", "short", "long", "batched", "text")


def bad_action(kind: str, shape: tuple[int, ...]):
    good = np.zeros(shape, np.float32)
    return {
        "nan": np.full(shape, np.nan, np.float32),
        "inf": np.where(np.arange(good.size).reshape(shape) == 0, np.inf, 0.0),
        "short": good.reshape(-1)[:-1],
        "long": np.zeros(good.size + 1),
        "batched": good[None],
        "text": "left",
    }[kind]


def assert_bad_action_rejected(env_id: str, kind: str, **kwargs) -> None:
    """ValueError, and the env is unchanged: its next good step equals an untouched twin's."""
    env, twin = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    env.reset(seed=3)
    twin.reset(seed=3)
    action = env.action_space.sample() * 0 + 0.5
    env.step(action)
    twin.step(action)
    with pytest.raises(ValueError, match="action"):
        env.step(bad_action(kind, env.action_space.shape))
    a, b = env.step(action), twin.step(action)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def assert_picklable(env_id: str, steps: int = 10, **kwargs) -> None:
    """A pickled copy continues the same trajectory (SubprocVecEnv ships envs this way)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=5)
    action = 0.3 * np.ones(env.action_space.shape, env.action_space.dtype)
    env.step(action)
    copy = pickle.loads(pickle.dumps(env))
    for _ in range(steps):
        a, b = env.step(action), copy.step(action)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def assert_frame_ok(frame, shape=None) -> None:
    """An RGB uint8 image with real content (not one flat colour, not a bare gradient)."""
    assert isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.ndim == 3
    assert frame.shape[2] == 3 and (shape is None or frame.shape == shape)
    colours = np.unique(frame.reshape(-1, 3), axis=0)
    assert len(colours) > 50, "a frame with a body, axes and text has many colours"
