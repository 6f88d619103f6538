"""Vector envs: a bad seed or sub-env index is a ValueError naming it; the env stays usable."""

from __future__ import annotations

import numpy as np
import pytest
from env_testing import make_vec

ENVS = ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0")
BAD_SEEDS = [1.5, -1, True, "7", [1, 2], [1, 2.5, 3], [0, -1, 2], {"a": 1}]


@pytest.mark.parametrize("seed", BAD_SEEDS, ids=repr)
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_reset_seed_raises_and_leaves_env_usable(env_id, seed):
    env, twin = make_vec(env_id, 3), make_vec(env_id, 3)
    env.reset(seed=4)
    twin.reset(seed=4)
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=seed)
    # The rejected call changed nothing: the next steps match a twin that never saw it.
    action = 0.3 * np.ones((3, 3), np.float32)
    assert np.array_equal(env.step(action)[0], twin.step(action)[0])
    assert np.array_equal(env.reset(seed=9)[0], make_vec(env_id, 3).reset(seed=9)[0])


BAD_INDICES = [5, 3, -1, [0, 3], 1.0, [0.5], np.array([True, False, True]), [[0, 1]], []]


@pytest.mark.parametrize("index", BAD_INDICES, ids=repr)
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_set_state_index_raises_and_leaves_env_usable(env_id, index):
    env, twin = make_vec(env_id, 3), make_vec(env_id, 3)
    env.reset(seed=4)
    twin.reset(seed=4)
    with pytest.raises(ValueError, match="index"):
        env.set_state(index=index)
    action = 0.3 * np.ones((3, 3), np.float32)
    assert np.array_equal(env.step(action)[0], twin.step(action)[0])
    obs, _ = env.set_state(index=np.int64(2))  # numpy integers are fine
    assert obs.shape[0] == 3
