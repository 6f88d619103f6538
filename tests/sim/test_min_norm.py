"""The compiled minimum-norm solve of the active-set start (``compiled.min_norm``) against the
pseudo-inverse by SVD (numpy's ``pinv``), on the systems the start meets: Delassus blocks of
ground contacts (rank-deficient: a face's four corners, an edge's two) and their column-mixed
form when a contact sits at its cone's boundary (not symmetric).

Tolerances. x = A⁺ b is computed in floating point to a relative error of order k ε κ, with κ
the condition number of A on its range (symmetric route) or κ² (the route through AᵀA); every
matrix here has κ ≤ 1e3 on its range, so 1e-8 relative (k ≤ 12: k ε κ² ≈ 3e-9) can only fail
on a wrong formula, a wrong rank or a wrong pivot, each of which errs by O(1).
"""

import numpy as np
import pytest

from rigid_env.sim.compiled.min_norm import min_norm

RTOL = 1e-8


def solve(a, b, symmetric):
    k = len(b)
    x = np.full(k, np.nan)
    rank = min_norm(
        np.ascontiguousarray(a), b.copy(), x, symmetric, np.full(3 * k * (k + 1), np.nan)
    )
    return x, rank


def box_face_rows(corners, normal_z=True):
    """J̃ (3C, 6) of ground contacts at ``corners`` (C, 3) of a unit-mass body with unit
    inertia: rows n, t₁, t₂ = z, x, y acting on (v, ω) as the velocity of the point."""
    rows = []
    for r in corners:
        for d in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
            rows.append(np.concatenate([d, np.cross(r, d)]))
    return np.array(rows)


FACE = np.array([[x, y, -0.2] for x in (-0.1, 0.1) for y in (-0.15, 0.15)])


@pytest.mark.parametrize("corners", [FACE, FACE[:2], FACE[:1], FACE[:3]], ids=[4, 2, 1, 3])
def test_delassus_of_ground_contacts_matches_pinv(corners):
    j = box_face_rows(corners)
    a = j @ j.T
    b = np.random.default_rng(1).normal(size=len(a))
    x, rank = solve(a, b, True)
    expected = np.linalg.pinv(a, rcond=1e-12) @ b
    np.testing.assert_allclose(x, expected, rtol=RTOL, atol=RTOL * np.max(np.abs(expected)))
    assert rank == np.linalg.matrix_rank(j)


def test_a_resting_face_shares_its_load_equally():
    # Four corners of a face, each asked to stop the same fall: the minimum-norm normal
    # impulses are equal (the redundant "twist" distribution has no part in it).
    j = box_face_rows(FACE)
    a = j @ j.T
    b = np.zeros(len(a))
    b[0::3] = 1.0
    x, rank = solve(a, b, True)
    assert rank == 6
    np.testing.assert_allclose(x[0::3], np.full(4, x[0]), rtol=1e-12)
    np.testing.assert_allclose(a @ x, b, atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_random_rank_deficient_semidefinite_matches_pinv(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(3, 13))
    r = int(rng.integers(1, k + 1))
    # Singular values in [1, 10]: κ(A) ≤ 100 on its range.
    u, _ = np.linalg.qr(rng.normal(size=(k, r)))
    j = u * rng.uniform(1.0, 10.0, r)
    a = j @ j.T
    a = 0.5 * (a + a.T)
    b = rng.normal(size=k)
    x, rank = solve(a, b, True)
    expected = np.linalg.pinv(a, rcond=1e-12) @ b
    np.testing.assert_allclose(x, expected, rtol=RTOL, atol=RTOL * np.max(np.abs(expected)))
    assert rank == r


@pytest.mark.parametrize("seed", range(6))
def test_column_mixed_boundary_systems_match_pinv(seed):
    # A contact at the cone's boundary acts through n + μ d·t: its normal column gains μ d of its
    # tangent columns, its tangent rows leave; the system is no longer symmetric.
    rng = np.random.default_rng(seed)
    corners = FACE[: int(rng.integers(1, 5))]
    j = box_face_rows(corners)
    a = j @ j.T
    bound = int(rng.integers(len(corners)))
    d = rng.normal(size=2)
    d /= np.linalg.norm(d)
    mu = 0.5
    cols = a.copy()
    cols[:, 3 * bound] += mu * (d[0] * cols[:, 3 * bound + 1] + d[1] * cols[:, 3 * bound + 2])
    live = np.ones(len(a), bool)
    live[3 * bound + 1 : 3 * bound + 3] = False
    m = cols[np.ix_(live, live)]
    assert not np.allclose(m, m.T)
    b = rng.normal(size=len(m))
    x, rank = solve(m, b, False)
    expected = np.linalg.pinv(m, rcond=1e-12) @ b
    np.testing.assert_allclose(x, expected, rtol=RTOL, atol=RTOL * np.max(np.abs(expected)))
    assert rank == np.linalg.matrix_rank(m)


def test_zero_system_gives_zero():
    x, rank = solve(np.zeros((3, 3)), np.ones(3), True)
    assert rank == 0
    np.testing.assert_array_equal(x, np.zeros(3))
