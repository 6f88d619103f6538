"""Rotation algebra on batched arrays: quaternions (x, y, z, w), matrices, the exponential map.

Conventions follow the course notes: ``p = x + R r``; ``q = (sin(θ/2) u, cos(θ/2))`` with the
scalar last; ``Ṙ = ω* R`` and ``q̇ = ½ (ω, 0) ∘ q`` with ω in the world frame.
Every function takes arrays with any leading batch shape.
"""

from __future__ import annotations

import numpy as np


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis; faster than ``np.cross`` on small trailing axes."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = ay * bz - az * by
    out[..., 1] = az * bx - ax * bz
    out[..., 2] = ax * by - ay * bx
    return out


def skew(w: np.ndarray) -> np.ndarray:
    """The cross-product matrix ``ω*`` of the notes: ``skew(w) @ v == w × v``."""
    z = np.zeros_like(w[..., 0])
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    return np.stack(
        (
            np.stack((z, -wz, wy), axis=-1),
            np.stack((wz, z, -wx), axis=-1),
            np.stack((-wy, wx, z), axis=-1),
        ),
        axis=-2,
    )


def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m @ v`` for stacks of 3×3 matrices and 3-vectors."""
    return np.einsum("...ij,...j->...i", m, v)


def rotate(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R v`` (world from body)."""
    return matvec(rot, v)


def rotate_inverse(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Rᵀ v`` (body from world)."""
    return np.einsum("...ji,...j->...i", rot, v)


# --- quaternions -------------------------------------------------------------------------------


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ∘ b`` of (x, y, z, w) quaternions: rotation ``b`` first, then ``a``."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (yy + zz)
    m[..., 0, 1] = 2 * (xy - wz)
    m[..., 0, 2] = 2 * (xz + wy)
    m[..., 1, 0] = 2 * (xy + wz)
    m[..., 1, 1] = 1 - 2 * (xx + zz)
    m[..., 1, 2] = 2 * (yz - wx)
    m[..., 2, 0] = 2 * (xz - wy)
    m[..., 2, 1] = 2 * (yz + wx)
    m[..., 2, 2] = 1 - 2 * (xx + yy)
    return m


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix, with ``w >= 0``.

    Shepperd's method, branch-free over the batch: of the four algebraically equal forms, each
    element uses the one with the largest pivot, which keeps the square root well conditioned.
    """
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    pivots = np.stack((1 + 2 * m00 - trace, 1 + 2 * m11 - trace, 1 + 2 * m22 - trace, 1 + trace))
    best = np.argmax(pivots, axis=0)
    s = np.sqrt(np.maximum(np.take_along_axis(pivots, best[None], axis=0)[0], 1e-300))
    d21, d02, d10 = (
        m[..., 2, 1] - m[..., 1, 2],
        m[..., 0, 2] - m[..., 2, 0],
        m[..., 1, 0] - m[..., 0, 1],
    )
    s21, s02, s10 = (
        m[..., 2, 1] + m[..., 1, 2],
        m[..., 0, 2] + m[..., 2, 0],
        m[..., 1, 0] + m[..., 0, 1],
    )
    candidates = np.stack(
        (
            np.stack((s, s10 / s, s02 / s, d21 / s), axis=-1),
            np.stack((s10 / s, s, s21 / s, d02 / s), axis=-1),
            np.stack((s02 / s, s21 / s, s, d10 / s), axis=-1),
            np.stack((d21 / s, d02 / s, d10 / s, s), axis=-1),
        )
    )
    q = 0.5 * np.take_along_axis(candidates, best[None, ..., None], axis=0)[0]
    return q * np.where(q[..., 3:] < 0, -1.0, 1.0)


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    return np.concatenate((np.sin(half) * axis, np.cos(half)), axis=-1)


def quat_exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation vector ``θ u`` (exponential map), exact for all angles."""
    theta = np.linalg.norm(rotation_vector, axis=-1, keepdims=True)
    half = 0.5 * theta
    # sin(θ/2)/θ, with its Taylor series near zero so that tiny rotations keep full precision.
    sinc = np.where(
        theta > 1e-4, np.sin(half) / np.where(theta > 1e-4, theta, 1.0), 0.5 - theta**2 / 48
    )
    return np.concatenate((sinc * rotation_vector, np.cos(half)), axis=-1)


def quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vector ``θ u`` of a unit quaternion, θ in [0, π] (the shorter way round)."""
    q = q * np.where(q[..., 3:] < 0, -1.0, 1.0)
    v = q[..., :3]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    theta = 2 * np.arctan2(s, q[..., 3:])
    scale = np.where(s > 1e-12, theta / np.where(s > 1e-12, s, 1.0), 2.0)
    return scale * v


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle in [0, π] between the rotations of two unit quaternions.

    ``2 atan2(|vec(a⁻¹ ∘ b)|, |w(a⁻¹ ∘ b)|)``: unlike ``2 arccos|a·b|`` it resolves angles down to
    rounding (arccos loses half the digits near 1).
    """
    d = quat_multiply(quat_conjugate(a), b)
    return 2 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q) v`` without forming the matrix: ``v + 2 w (u × v) + 2 u × (u × v)``."""
    u, w = q[..., :3], q[..., 3:]
    t = 2 * cross(u, v)
    return v + w * t + cross(u, t)


# --- matrices ----------------------------------------------------------------------------------


def gram_schmidt(m: np.ndarray) -> np.ndarray:
    """The notes' rotation repair: normalise column α, orthogonalise β against it, γ = α × β."""
    a = m[..., :, 0]
    b = m[..., :, 1]
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b - np.sum(b * a, axis=-1, keepdims=True) * a
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.stack((a, b, cross(a, b)), axis=-1)


def random_quaternions(rng: np.random.Generator, shape: tuple[int, ...] = ()) -> np.ndarray:
    """Uniformly distributed rotations (normalised 4-D Gaussians), ``w >= 0``."""
    q = quat_normalize(rng.standard_normal((*shape, 4)))
    return q * np.where(q[..., 3:] < 0, -1.0, 1.0)
