"""Input checks shared by the simulator: each failure is a ``ValueError`` naming the parameter."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def positive_scalar(value: float, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not np.isfinite(x) or x <= 0:
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return x


def nonnegative_scalar(value: float, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a non-negative number, got {value!r}") from None
    if not np.isfinite(x) or x < 0:
        raise ValueError(f"{name} must be non-negative and finite, got {value!r}")
    return x


def unit_interval(value: float, name: str) -> float:
    x = nonnegative_scalar(value, name)
    if x > 1:
        raise ValueError(f"{name} must lie in [0, 1], got {value!r}")
    return x


def finite_array(value: ArrayLike, name: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """A float64 copy of ``value``; ``shape`` fixes the trailing dimensions (``None`` = any)."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {value!r}") from None
    if shape is not None and arr.shape[arr.ndim - len(shape) :] != shape:
        raise ValueError(f"{name} must have trailing shape {shape}, got shape {arr.shape}")
    if shape is not None and arr.ndim < len(shape):
        raise ValueError(f"{name} must have trailing shape {shape}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or infinity)")
    return arr


def inertia_tensor(value: ArrayLike, name: str = "inertia") -> np.ndarray:
    """A symmetric positive-definite 3×3 tensor whose principal moments obey I1 + I2 >= I3."""
    inertia = finite_array(value, name, (3, 3))
    if inertia.shape != (3, 3):
        raise ValueError(f"{name} must have shape (3, 3), got {inertia.shape}")
    scale = np.max(np.abs(inertia))
    if not np.allclose(inertia, inertia.T, rtol=0, atol=1e-12 * scale):
        raise ValueError(f"{name} must be symmetric")
    moments = np.linalg.eigvalsh(inertia)
    if moments[0] <= 0:
        raise ValueError(f"{name} must be positive definite, got principal moments {moments}")
    # A real mass distribution has I1 + I2 >= I3 for its principal moments (triangle inequality),
    # with equality for a flat lamina; allow rounding of the caller's arithmetic.
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        raise ValueError(
            f"{name} is unphysical: principal moments {moments} violate the triangle inequality"
        )
    return 0.5 * (inertia + inertia.T)
