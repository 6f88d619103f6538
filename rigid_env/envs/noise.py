"""Gaussian observation noise: per observation part, a standard deviation in the part's units.

A task's ``observation_noise`` (a dict ``part -> std``, parts as in ``observation_structure``)
becomes the flat entries that get noise and their standard deviations (:func:`noise_entries`).
Each observation then adds ``std * z`` to those entries, ``z`` standard normal draws of the
env's own generator (the single env's ``np_random``, a vector sub-env's), and clips the result
to the observation space, so a noisy observation is still in it. The other entries are left
exactly as they were.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def noise_entries(
    stds: Mapping[str, float], slices: Mapping[str, slice]
) -> tuple[np.ndarray, np.ndarray] | None:
    """The flat indices with a positive standard deviation and those deviations, in order;
    ``None`` if no part has noise."""
    index: list[int] = []
    scale: list[float] = []
    for part, std in stds.items():
        if std > 0:
            entries = range(*slices[part].indices(slices[part].stop))
            index.extend(entries)
            scale.extend([std] * len(entries))
    if not index:
        return None
    return np.array(index, dtype=np.intp), np.array(scale)


def noisy_observation(clean: np.ndarray, z: np.ndarray, task: Any) -> np.ndarray:
    """A new float32 array: ``clean`` (k, size) with ``task.noise_std * z`` (z: (k, m)) added
    to the entries ``task.noise_index`` (in float64), clipped to the observation space."""
    index, std = task.noise_index, task.noise_std
    space = task.single_observation_space
    out = np.array(clean, dtype=np.float32)
    noisy = clean[:, index].astype(np.float64) + std * z
    out[:, index] = np.clip(noisy, space.low[index], space.high[index])
    return out
