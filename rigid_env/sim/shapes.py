"""Collision shapes, in body coordinates centred on the centre of mass."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Sphere:
    radius: float


@dataclass(frozen=True, eq=False)
class Box:
    half_extents: np.ndarray  # (3,)

    @property
    def vertices(self) -> np.ndarray:
        """The eight corners, (8, 3)."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return signs * self.half_extents


@dataclass(frozen=True, eq=False)
class Polyhedron:
    vertices: np.ndarray  # (V, 3), relative to the centre of mass
    faces: tuple[tuple[int, ...], ...]  # counter-clockwise seen from outside


Shape = Sphere | Box | Polyhedron
