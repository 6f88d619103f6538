"""Rotation algebra on scalar tuples for the kernels, mirroring ``rigid_env.sim.rotation``.

3-vectors and quaternions (x, y, z, w) are tuples; a matrix is a 9-tuple, row-major. Each
function follows ``rigid_env.sim.rotation``'s batched read-outs operation for operation.
"""

from __future__ import annotations

import math

from .cache import njit


@njit(cache=True, error_model="numpy")
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, error_model="numpy")
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, error_model="numpy")
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, error_model="numpy")
def scale(s, a):
    """``s * a`` (scalar first, as numpy's ``s * a`` with a scalar s)."""
    return (s * a[0], s * a[1], s * a[2])


@njit(cache=True, error_model="numpy")
def div(a, b):
    """Elementwise ``a / b``."""
    return (a[0] / b[0], a[1] / b[1], a[2] / b[2])


@njit(cache=True, error_model="numpy")
def norm3(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(cache=True, error_model="numpy")
def quat_multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


@njit(cache=True, error_model="numpy")
def quat_conjugate(q):
    return (-q[0], -q[1], -q[2], q[3])


@njit(cache=True, error_model="numpy")
def quat_normalize(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@njit(cache=True, error_model="numpy")
def quat_to_matrix(q):
    x, y, z, w = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (
        1 - 2 * (yy + zz),
        2 * (xy - wz),
        2 * (xz + wy),
        2 * (xy + wz),
        1 - 2 * (xx + zz),
        2 * (yz - wx),
        2 * (xz - wy),
        2 * (yz + wx),
        1 - 2 * (xx + yy),
    )


@njit(cache=True, error_model="numpy")
def rotate(m, v):
    """``R v``."""
    return (
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    )


@njit(cache=True, error_model="numpy")
def rotate_inverse(m, v):
    """``Rᵀ v``."""
    return (
        m[0] * v[0] + m[3] * v[1] + m[6] * v[2],
        m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
        m[2] * v[0] + m[5] * v[1] + m[8] * v[2],
    )


@njit(cache=True, error_model="numpy")
def matmul(a, b):
    """``a @ b`` of 9-tuples."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@njit(cache=True, error_model="numpy")
def quat_rotate(q, v):
    """``v + 2 w (u × v) + 2 u × (u × v)``, as ``rotation.quat_rotate``."""
    u = (q[0], q[1], q[2])
    w = q[3]
    c = cross(u, v)
    t = (2 * c[0], 2 * c[1], 2 * c[2])
    ut = cross(u, t)
    return (v[0] + w * t[0] + ut[0], v[1] + w * t[1] + ut[1], v[2] + w * t[2] + ut[2])


@njit(cache=True, error_model="numpy")
def quat_exp(r):
    """Unit quaternion of the rotation vector r, with a small-angle series."""
    theta = norm3(r)
    half = 0.5 * theta
    sinc = math.sin(half) / theta if theta > 1e-4 else 0.5 - theta**2 / 48
    return (sinc * r[0], sinc * r[1], sinc * r[2], math.cos(half))


@njit(cache=True, error_model="numpy")
def align_sign(q_new, q_old):
    """``q_new`` or ``−q_new``, whichever is nearer ``q_old`` (as ``integrators.common``)."""
    d = q_new[0] * q_old[0] + q_new[1] * q_old[1] + q_new[2] * q_old[2] + q_new[3] * q_old[3]
    s = -1.0 if d < 0 else 1.0
    return (q_new[0] * s, q_new[1] * s, q_new[2] * s, q_new[3] * s)


@njit(cache=True, error_model="numpy")
def gram_schmidt(m):
    """Normalise column α, orthogonalise β against it, γ = α × β (``rotation.gram_schmidt``)."""
    a = (m[0], m[3], m[6])
    b = (m[1], m[4], m[7])
    na = norm3(a)
    a = (a[0] / na, a[1] / na, a[2] / na)
    ba = b[0] * a[0] + b[1] * a[1] + b[2] * a[2]
    b = (b[0] - ba * a[0], b[1] - ba * a[1], b[2] - ba * a[2])
    nb = norm3(b)
    b = (b[0] / nb, b[1] / nb, b[2] / nb)
    c = cross(a, b)
    return (a[0], b[0], c[0], a[1], b[1], c[1], a[2], b[2], c[2])


@njit(cache=True, error_model="numpy")
def matrix_to_quat(m):
    """Shepperd's method with the largest pivot and w ≥ 0, as ``rotation.matrix_to_quat``."""
    m00, m11, m22 = m[0], m[4], m[8]
    trace = m00 + m11 + m22
    p0 = 1 + 2 * m00 - trace
    p1 = 1 + 2 * m11 - trace
    p2 = 1 + 2 * m22 - trace
    p3 = 1 + trace
    best, pivot = 0, p0
    if p1 > pivot:
        best, pivot = 1, p1
    if p2 > pivot:
        best, pivot = 2, p2
    if p3 > pivot:
        best, pivot = 3, p3
    s = math.sqrt(max(pivot, 1e-300))
    d21, d02, d10 = m[7] - m[5], m[2] - m[6], m[3] - m[1]
    s21, s02, s10 = m[7] + m[5], m[2] + m[6], m[3] + m[1]
    if best == 0:
        q = (s, s10 / s, s02 / s, d21 / s)
    elif best == 1:
        q = (s10 / s, s, s21 / s, d02 / s)
    elif best == 2:
        q = (s02 / s, s21 / s, s, d10 / s)
    else:
        q = (d21 / s, d02 / s, d10 / s, s)
    q = (0.5 * q[0], 0.5 * q[1], 0.5 * q[2], 0.5 * q[3])
    sign = -1.0 if q[3] < 0 else 1.0
    return (q[0] * sign, q[1] * sign, q[2] * sign, q[3] * sign)


@njit(cache=True, error_model="numpy")
def transpose(m):
    return (m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8])


@njit(cache=True, error_model="numpy")
def skew(w):
    """The cross-product matrix ``ω*`` as a 9-tuple."""
    return (0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)
