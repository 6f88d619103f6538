"""Per-body constants of a model as one float64 array, and the inertia maps over it.

``body_data(model)`` is (n, BODY_WIDTH): mass, 1/mass, principal moments and their inverses,
the principal frame (quaternion, its conjugate, matrix), the body-axes inertia and its inverse,
and flags for the shortcuts (diagonal inertia; body axes already principal).
"""

from __future__ import annotations

import numpy as np

from .cache import njit
from .rotation import rotate, rotate_inverse

# The helpers below take the body table: inlined (numba IR), since a call that passes an array
# costs tens of ns in reference counting, more than the arithmetic it wraps.

MASS, INV_MASS = 0, 1
MOMENTS, INV_MOMENTS = 2, 5  # 3 each
PRINCIPAL_QUAT, PRINCIPAL_CONJ = 8, 12  # 4 each
AXES = 16  # 9: principal axes → body, row-major
INERTIA, INV_INERTIA = 25, 34  # 9 each, body axes, row-major
DIAGONAL = 43  # 1.0: the body inertia is diagonal (applied elementwise)
PRINCIPAL = 44  # 1.0: body axes are not principal (rotated by the principal frame)
BODY_WIDTH = 45


def body_data(model) -> np.ndarray:
    n = model.n_bodies
    out = np.zeros((n, BODY_WIDTH))
    out[:, MASS] = model.mass
    out[:, INV_MASS] = model.inv_mass
    out[:, MOMENTS : MOMENTS + 3] = model.principal_moments
    out[:, INV_MOMENTS : INV_MOMENTS + 3] = model.inverse_principal_moments_array
    if model.principal_quat is None:
        out[:, PRINCIPAL_QUAT + 3] = 1.0
        out[:, PRINCIPAL_CONJ + 3] = 1.0
    else:
        out[:, PRINCIPAL_QUAT : PRINCIPAL_QUAT + 4] = model.principal_quat
        out[:, PRINCIPAL_CONJ : PRINCIPAL_CONJ + 4] = model.principal_conj
        out[:, PRINCIPAL] = 1.0
    out[:, AXES : AXES + 9] = np.asarray(model.principal_axes).reshape(n, 9)
    out[:, INERTIA : INERTIA + 9] = model.inertia.reshape(n, 9)
    out[:, INV_INERTIA : INV_INERTIA + 9] = model.inv_inertia.reshape(n, 9)
    out[:, DIAGONAL] = 1.0 if model.inertia_diagonal is not None else 0.0
    return out


@njit(cache=True, error_model="numpy", inline="always")
def _mat9(bd, b, col):
    return (
        bd[b, col],
        bd[b, col + 1],
        bd[b, col + 2],
        bd[b, col + 3],
        bd[b, col + 4],
        bd[b, col + 5],
        bd[b, col + 6],
        bd[b, col + 7],
        bd[b, col + 8],
    )


@njit(cache=True, error_model="numpy", inline="always")
def vec3(bd, b, col):
    return (bd[b, col], bd[b, col + 1], bd[b, col + 2])


@njit(cache=True, error_model="numpy", inline="always")
def vec4(bd, b, col):
    return (bd[b, col], bd[b, col + 1], bd[b, col + 2], bd[b, col + 3])


@njit(cache=True, error_model="numpy", inline="always")
def apply_inertia(bd, b, rot, vec):
    """``R M0 Rᵀ vec`` (``Model.apply_inertia``)."""
    return inertia_times(bd[b, DIAGONAL] != 0.0, _mat9(bd, b, INERTIA), rot, vec)


@njit(cache=True, error_model="numpy", inline="always")
def inertia_times(diagonal, m, rot, vec):
    """``R M0 Rᵀ vec`` for M0 the 9-tuple ``m`` (row-major), elementwise when ``diagonal``."""
    local = rotate_inverse(rot, vec)
    if diagonal:
        return rotate(rot, (local[0] * m[0], local[1] * m[4], local[2] * m[8]))
    return rotate(rot, rotate(m, local))


@njit(cache=True, error_model="numpy", inline="always")
def apply_inverse_inertia(bd, b, rot, vec):
    """``R M0⁻¹ Rᵀ vec`` (``Model.apply_inverse_inertia``)."""
    local = rotate_inverse(rot, vec)
    if bd[b, DIAGONAL] != 0.0:
        d = (bd[b, INERTIA], bd[b, INERTIA + 4], bd[b, INERTIA + 8])
        return rotate(rot, (local[0] / d[0], local[1] / d[1], local[2] / d[2]))
    return rotate(rot, rotate(_mat9(bd, b, INV_INERTIA), local))


@njit(cache=True, error_model="numpy", inline="always")
def matrix(bd, b, col):
    """A 9-tuple stored from column ``col`` (e.g. ``AXES``, ``INERTIA``)."""
    return _mat9(bd, b, col)
