"""The envs' compiled per-step kernels against the simulator's numpy reference."""

from __future__ import annotations

import numpy as np

from rigid_env.envs import kernels
from rigid_env.sim.rotation import quat_rotate, quat_to_matrix

EPS = np.finfo(float).eps


def _unit_quaternions(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_rotation_matrices_match_the_simulator():
    q = _unit_quaternions(500)
    # Each entry is 1 - 2(a² + b²) or 2(ab ± cd) with |components| <= 1: a few roundings of
    # terms <= 2, so both forms agree to within 8 eps (a bound, not a tuned value).
    assert np.max(np.abs(kernels.rotation_matrices(q) - quat_to_matrix(q))) <= 8 * EPS


def test_world_torque_rotates_the_body_torque_into_the_world():
    q = _unit_quaternions(200, seed=1)
    torque = np.random.default_rng(2).uniform(-1, 1, (200, 3))
    out = np.empty((200, 1, 3))
    kernels.world_torque(q[:, None, :], torque, out)
    # Two products of |entries| <= 1 and |τ| <= 1 summed three ways: within 16 eps.
    assert np.max(np.abs(out[:, 0] - quat_rotate(q, torque))) <= 16 * EPS


def test_finite_clip_clips_like_numpy_and_rejects_nan_and_infinity():
    a = np.array([-3.0, -1.0, -0.25, 0.0, 0.5, 1.0, 7.0])
    expected = np.clip(a, -1.0, 1.0)
    assert kernels.finite_clip(a) and np.array_equal(a, expected)
    for bad in (np.nan, np.inf, -np.inf):
        assert not kernels.finite_clip(np.array([0.5, bad, 0.2]))
