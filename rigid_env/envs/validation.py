"""Argument checks shared by the environments: each failure is a ``ValueError`` naming the argument.

Scalar checks come from the simulator (:mod:`rigid_env.sim.validation`); this module adds what
only environments need: integers, ranges, quaternions, choices, and actions.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import Any, TypeVar

import numpy as np

from ..sim.validation import finite_array, nonnegative_scalar, positive_scalar, unit_interval
from . import kernels

__all__ = [
    "action_batch",
    "at_most",
    "choice",
    "finite_array",
    "nonnegative_scalar",
    "positive_int",
    "positive_scalar",
    "positive_vector",
    "quaternions",
    "scalar_range",
    "unit_interval",
]


T = TypeVar("T")


def positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def at_most(value: float, name: str, maximum: float, unit: str = "") -> float:
    """``value`` if it is at most ``maximum`` (the documented bound of ``name``)."""
    if value > maximum:
        raise ValueError(f"{name} must be at most {maximum:g}{unit}, got {value!r}")
    return value


def scalar_range(
    value: Any, name: str, minimum: float = 0.0, maximum: float = math.inf
) -> tuple[float, float]:
    """A pair ``(low, high)`` with ``minimum <= low <= high <= maximum``, both finite."""
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high) of numbers, got {value!r}") from None
    if not (np.isfinite(low) and np.isfinite(high)) or not minimum <= low <= high <= maximum:
        bound = "" if maximum == math.inf else f" <= {maximum:g}"
        raise ValueError(
            f"{name} must satisfy {minimum:g} <= low <= high{bound} (finite), got {value!r}"
        )
    return low, high


def positive_vector(value: Any, name: str, size: int = 3, maximum: float = math.inf) -> np.ndarray:
    """A scalar (broadcast) or a ``size``-vector of positive finite numbers at most ``maximum``,
    as float64 (size,)."""
    arr = finite_array(value, name)
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    if arr.shape != (size,) or np.any(arr <= 0):
        raise ValueError(
            f"{name} must be a positive number or {size} positive numbers, got {value!r}"
        )
    if np.any(arr > maximum):
        raise ValueError(f"{name} must be at most {maximum:g} in every entry, got {value!r}")
    return arr


def quaternions(value: Any, name: str) -> np.ndarray:
    """Non-zero quaternions (x, y, z, w), shape ``(..., 4)``, normalised."""
    q = finite_array(value, name, (4,))
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError(f"{name} must be non-zero quaternions (x, y, z, w), got {value!r}")
    return q / norm


def choice(value: T, name: str, options: Collection[Any]) -> T:
    if value not in options:
        raise ValueError(f"{name} must be one of {tuple(options)}, got {value!r}")
    return value


def action_batch(action: Any, shape: tuple[int, ...], name: str = "action") -> np.ndarray:
    """A float64 copy of ``action`` with exactly ``shape``, finite, clipped to [-1, 1].

    Raises ``ValueError`` for a wrong shape, a non-numeric value, NaN or infinity; nothing in the
    environment changes before this check passes, so a rejected action leaves it usable.
    """
    try:
        arr = np.array(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be a numeric array of shape {shape}, got {action!r}"
        ) from None
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    # One compiled pass: numpy's isfinite, all and clip are three dispatches on a 3-vector.
    if not kernels.finite_clip(arr.reshape(-1)):
        raise ValueError(f"{name} contains NaN or infinity: {action!r}")
    return arr
