"""Rotation algebra: conversions are mutual inverses, repair restores orthonormality."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigid_env.sim import rotation as rot

# Double precision: conversions of unit quaternions lose a few ulps (~1e-16 each), so 1e-13
# leaves room for a handful of operations while catching any wrong sign or index (errors ~1).
TOL = 1e-13

quaternions = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1
)


@settings(max_examples=200, deadline=None)
@given(quaternions)
def test_matrix_quaternion_round_trip(values):
    q = rot.quat_normalize(np.array(values))
    m = rot.quat_to_matrix(q)
    assert np.allclose(m.T @ m, np.eye(3), atol=TOL)
    assert np.isclose(np.linalg.det(m), 1.0, atol=TOL)
    back = rot.matrix_to_quat(m)
    assert back[3] >= 0
    # q and −q are the same rotation; at w = 0 either sign is valid.
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12


def test_matrix_to_quat_half_turns():
    # Half turns have w = 0: the trace-based formula alone divides by zero there.
    for axis in np.eye(3):
        q = rot.quat_from_axis_angle(axis, np.pi)
        back = rot.matrix_to_quat(rot.quat_to_matrix(q))
        assert rot.quat_angle(back, q) < 1e-7


def test_conventions_match_the_notes():
    # q = (sin(θ/2) u, cos(θ/2)); a quarter turn about z takes x to y (right-handed).
    q = rot.quat_from_axis_angle(np.array([0.0, 0, 1]), np.pi / 2)
    assert np.allclose(q, [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    assert np.allclose(rot.quat_to_matrix(q) @ [1.0, 0, 0], [0, 1, 0], atol=TOL)
    # Hamilton product: a ∘ b applies b first.
    a = rot.quat_from_axis_angle(np.array([1.0, 0, 0]), 0.3)
    b = rot.quat_from_axis_angle(np.array([0.0, 1, 0]), 0.7)
    ab = rot.quat_to_matrix(rot.quat_multiply(a, b))
    assert np.allclose(ab, rot.quat_to_matrix(a) @ rot.quat_to_matrix(b), atol=TOL)
    # skew(w) v = w × v  (the notes' ω*).
    w, v = np.array([0.3, -1.2, 2.0]), np.array([1.5, 0.2, -0.7])
    assert np.allclose(rot.skew(w) @ v, np.cross(w, v), atol=TOL)


def test_rotate_without_matrix_matches_matrix():
    rng = np.random.default_rng(1)
    q = rot.random_quaternions(rng, (50,))
    v = rng.standard_normal((50, 3))
    expected = np.einsum("nij,nj->ni", rot.quat_to_matrix(q), v)
    assert np.allclose(rot.quat_rotate(q, v), expected, atol=TOL)


def test_exp_log_inverse_including_small_and_large_angles():
    rng = np.random.default_rng(2)
    axes = rng.standard_normal((6, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.array([1e-9, 1e-5, 0.1, 1.0, 3.0, np.pi - 1e-6])[:, None]
    v = axes * angles
    assert np.allclose(rot.quat_log(rot.quat_exp(v)), v, atol=1e-12)
    assert np.allclose(np.linalg.norm(rot.quat_exp(v), axis=-1), 1.0, atol=TOL)


def test_gram_schmidt_repairs_a_drifted_rotation():
    rng = np.random.default_rng(3)
    q = rot.random_quaternions(rng, (20,))
    drifted = rot.quat_to_matrix(q) + 1e-3 * rng.standard_normal((20, 3, 3))
    fixed = rot.gram_schmidt(drifted)
    eye = np.broadcast_to(np.eye(3), fixed.shape)
    assert np.allclose(np.swapaxes(fixed, -1, -2) @ fixed, eye, atol=TOL)
    assert np.allclose(np.linalg.det(fixed), 1.0, atol=TOL)
    # The notes' order: the first column keeps its direction.
    a = drifted[..., :, 0] / np.linalg.norm(drifted[..., :, 0], axis=-1, keepdims=True)
    assert np.allclose(fixed[..., :, 0], a, atol=TOL)
    # And a rotation already orthonormal is left alone.
    exact = rot.quat_to_matrix(q)
    assert np.allclose(rot.gram_schmidt(exact), exact, atol=TOL)


@pytest.mark.parametrize("shape", [(), (7,), (2, 3)])
def test_batch_shapes(shape):
    rng = np.random.default_rng(4)
    q = rot.random_quaternions(rng, shape)
    assert rot.quat_to_matrix(q).shape == (*shape, 3, 3)
    assert rot.matrix_to_quat(rot.quat_to_matrix(q)).shape == (*shape, 4)
