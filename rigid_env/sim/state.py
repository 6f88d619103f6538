"""The dynamic state: arrays with leading batch axes, then a body axis."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .rotation import cross, quat_rotate, quat_to_matrix, rotate_inverse

# What ``state[index]`` accepts on the batch axes: numpy's basic and advanced indices.
BatchIndex = int | slice | np.ndarray | tuple[int | slice | np.ndarray, ...]
# A state's quaternions must have |q| within this of 1 (a step renormalises its copy); a
# quaternion farther off (or zero, or overflowing) is rejected rather than silently rescaled.
ORIENTATION_TOLERANCE = 1e-6
FIELDS = ("position", "orientation", "linear_velocity", "angular_velocity")  # ``arrays()``
# ``State.time`` is origin + (count − offset) Δt, held as (origin, Δt, count, offset): a step
# of the same Δt only adds to the count (a tuple, no array work), so the time is the origin
# plus a whole number of steps times Δt, not a sum of rounded increments; origin and offset
# are per element (arrays) once some elements were reset (``edited``).
ZERO_TIME = (0.0, 0.0, 0, 0)


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
    def report(self) -> Mapping[str, Any]:
        """What the step that returned this state reported (``Scene.step``; with contacts,
        ``report["contacts"]`` is a :class:`~rigid_env.sim.contacts.ContactReport` over the
        batch): the step's own, whatever other steps of the same scene ran since or run on
        other threads. Empty for a state no step returned (built, indexed or copied)."""
        report = self.__dict__.get("_report")
        if report is None:
            return {}
        if isinstance(report, tuple):  # a compiled step's columns: built on the first read
            build, *columns = report
            report = self.__dict__["_report"] = build(*columns)
        return report

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

    @property
    def time(self) -> np.ndarray:
        """Seconds since the state's origin, per batch element, ``batch_shape``: each step adds
        its Δt (exactly: the time is the origin plus a whole number of steps times Δt); a
        state built by hand starts at 0, and so do the elements :meth:`edited` resets."""
        origin, step, count, offset = self.__dict__.get("_time", ZERO_TIME)
        return np.broadcast_to(origin + (count - offset) * step, self.batch_shape).astype(float)

    @property
    def contact_impulses(self) -> np.ndarray | None:
        """With ``SolverSettings(warm_start=True)``: the impulses (normal, t₁, t₂) per contact
        slot, ``(*batch_shape, C, 3)``, the last step's contact solve ended with where it
        converged (zeros elsewhere), from which the next step's solve starts; None for a state
        that carries none (cold start). ``state[index]`` keeps its elements' impulses."""
        carried = self.__dict__.get("_warm")  # (*batch, C, 4): λ, then slot 0's flag
        if carried is None:
            return None
        return np.where(carried[..., :1, 3:] != 0.0, carried[..., :3], 0.0)

    def edited(self, reset: BatchIndex, **arrays: np.ndarray) -> State:
        """This state with some of its arrays replaced (``position=`` … ``angular_velocity=``,
        the same shapes), for a reset of the batch elements ``reset``: the contact impulses
        it carries go along (``contact_impulses``), but the elements ``reset``, whose state
        was edited, start their next contact solve cold."""
        fields = dict(zip(FIELDS, self.arrays(), strict=True))
        for name, value in arrays.items():
            if name not in fields:
                raise ValueError(f"unknown state field {name!r}; expected one of {FIELDS}")
            if np.shape(value) != np.shape(fields[name]):
                raise ValueError(
                    f"{name} must keep the shape {np.shape(fields[name])}, got {np.shape(value)}"
                )
            fields[name] = value
        new = State(**fields)
        origin, step, count, offset = self.__dict__.get("_time", ZERO_TIME)
        if count:  # the reset elements start their clock again, at 0
            origin = np.array(np.broadcast_to(origin, self.batch_shape), dtype=float)
            offset = np.array(np.broadcast_to(offset, self.batch_shape), dtype=np.int64)
            origin[reset], offset[reset] = 0.0, count
            new.__dict__["_time"] = (origin, step, count, offset)
        carried = self.__dict__.get("_warm")
        if carried is not None:
            carried = np.array(carried)
            flags = carried[..., 0, 3]  # (*batch,): slot 0's converged flag, a view
            flags[reset] = 0.0
            new.__dict__["_warm"] = carried
        return new

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its report (a compiled step's refers to the scene's driver)."""
        fields = dict(self.__dict__)
        fields.pop("_report", None)
        return fields

    def copy(self) -> State:
        return State(*(np.array(a) for a in self.arrays()))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (self.position, self.orientation, self.linear_velocity, self.angular_velocity)

    def __getitem__(self, index: BatchIndex) -> State:
        """Index the batch axes: ``state[3]`` is batch element 3 (all bodies)."""
        if not isinstance(index, tuple):
            index = (index,)
        full = (*index, Ellipsis, slice(None), slice(None))
        part = State(*(a[full] for a in self.arrays()))
        origin, step, count, offset = self.__dict__.get("_time", ZERO_TIME)
        if count:
            batch = (*index, Ellipsis)
            origin = np.broadcast_to(origin, self.batch_shape)[batch]
            offset = np.broadcast_to(offset, self.batch_shape)[batch]
            part.__dict__["_time"] = (origin, step, count, offset)
        carried = self.__dict__.get("_warm")
        if carried is not None:  # (the arrays' layout: batch, then slots and 4)
            part.__dict__["_warm"] = carried[full]
        return part
