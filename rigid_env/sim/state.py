"""The dynamic state: arrays with leading batch axes, then a body axis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .rotation import cross, quat_rotate, quat_to_matrix, rotate_inverse

# What ``state[index]`` accepts on the batch axes: numpy's basic and advanced indices.
BatchIndex = int | slice | np.ndarray | tuple[int | slice | np.ndarray, ...]
# A state's quaternions must have |q| within this of 1 (a step renormalises its copy); a
# quaternion farther off (or zero, or overflowing) is rejected rather than silently rescaled.
ORIENTATION_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class State:
    """Positions of the centres of mass, orientations (x, y, z, w), velocities; world frame.

    Shapes ``(*batch_shape, n_bodies, 3)`` (orientation ``(…, 4)``). A step never modifies a
    state: it returns a new one, float64, sharing no memory with its input.

    Orientations must be unit quaternions. ``Scene.initial_state`` normalises any non-zero
    quaternion; a state built by hand is checked by ``Scene.step`` and the read-outs: |q|
    within ``ORIENTATION_TOLERANCE`` (1e-6) of 1 is accepted (the step renormalises
    its own copy, so e.g. float32 data works), farther off, zero or non-finite is a
    ``ValueError`` naming ``orientation`` (rejected rather than rescaled: a quaternion that
    far from unit is a bug upstream, not rounding).
    """

    position: np.ndarray
    orientation: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return self.position.shape[:-2]

    @property
    def rotation(self) -> np.ndarray:
        """Rotation matrices R (body → world), ``(*batch, n, 3, 3)``."""
        return quat_to_matrix(self.orientation)

    @property
    def body_angular_velocity(self) -> np.ndarray:
        """Ω = Rᵀ ω, the angular velocity in body axes."""
        return rotate_inverse(self.rotation, self.angular_velocity)

    def point_position(self, local_point: ArrayLike) -> np.ndarray:
        """World position ``x + R r`` of the body-fixed point r (notes: p = x + R r)."""
        return self.position + quat_rotate(self.orientation, np.asarray(local_point, float))

    def point_velocity(self, local_point: ArrayLike) -> np.ndarray:
        """World velocity ``v + ω × (R r)`` of the body-fixed point r (notes)."""
        arm = quat_rotate(self.orientation, np.asarray(local_point, float))
        return self.linear_velocity + cross(self.angular_velocity, arm)

    def copy(self) -> State:
        return State(*(np.array(a) for a in self.arrays()))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (self.position, self.orientation, self.linear_velocity, self.angular_velocity)

    def __getitem__(self, index: BatchIndex) -> State:
        """Index the batch axes: ``state[3]`` is batch element 3 (all bodies)."""
        if not isinstance(index, tuple):
            index = (index,)
        full = (*index, Ellipsis, slice(None), slice(None))
        return State(*(a[full] for a in self.arrays()))
