"""Named observation layouts, as Gymnasium's MuJoCo v5 envs export them.

An env's ``observation_structure`` is an ordered ``dict`` from part name to size: the flat
observation is the parts laid end to end in that order. These helpers turn it into slices, so
code that reads observations (controllers, tests) names the parts instead of hand slicing.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def observation_slices(structure: Mapping[str, int]) -> dict[str, slice]:
    """``name -> slice`` into the flat observation, in the order of ``structure``."""
    out, start = {}, 0
    for name, size in structure.items():
        out[name] = slice(start, start + int(size))
        start += int(size)
    return out


def split_observation(obs: np.ndarray, structure: Mapping[str, int]) -> dict[str, np.ndarray]:
    """``name -> obs[..., part]`` (views along the last axis) for every part of ``structure``.

    Raises ``ValueError`` naming ``obs`` if its last axis is not the structure's total size.
    """
    slices = observation_slices(structure)
    size = sum(int(s) for s in structure.values())
    if np.shape(obs)[-1:] != (size,):
        raise ValueError(
            f"obs must have last axis {size} for {dict(structure)}, got {np.shape(obs)}"
        )
    return {name: obs[..., part] for name, part in slices.items()}
