"""The static model of a scene: bodies, ground, springs, as arrays with a body axis.

Following Brax and MuJoCo, everything that does not change while stepping lives here; the
dynamic arrays live in :class:`~rigid_env.sim.state.State`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .body import Body
from .rotation import matrix_to_quat, matvec, rotate, rotate_inverse
from .validation import finite_array, nonnegative_scalar, unit_interval


@dataclass(frozen=True)
class Material:
    """Contact coefficients: Newton's restitution ε in [0, 1], Coulomb's friction μ >= 0.

    Approach speeds below ``restitution_threshold`` (m/s) do not bounce: such micro-bounces are
    treated as resting contact (Box2D's restitution threshold).
    """

    restitution: float = 0.0
    friction: float = 0.5
    restitution_threshold: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "restitution", unit_interval(self.restitution, "restitution"))
        object.__setattr__(self, "friction", nonnegative_scalar(self.friction, "friction"))
        object.__setattr__(
            self,
            "restitution_threshold",
            nonnegative_scalar(self.restitution_threshold, "restitution_threshold"),
        )


@dataclass(frozen=True)
class Ground(Material):
    """The plane z = 0 with normal +z, with the contact coefficients of a :class:`Material`."""


@dataclass(frozen=True, eq=False, init=False)
class Spring:
    """A spring from the world point ``anchor`` to the body-fixed point ``attach`` of body ``body``.

    Force on the body at the attachment point p, with d = p − anchor (SI units):
    ``−stiffness (|d| − rest_length) d̂ − damping (ṗ · d̂) d̂``; with ``rest_length == 0`` the
    direction-free limit ``−stiffness d − damping ṗ``. ``stiffness`` in N/m, ``damping`` in N s/m.
    """

    body: int
    anchor: np.ndarray  # (3,), float64
    stiffness: float
    damping: float
    rest_length: float
    attach: np.ndarray  # (3,), float64

    # An explicit constructor: it takes any 3-sequence for the points and stores float arrays.
    def __init__(
        self,
        body: int,
        anchor: ArrayLike,
        stiffness: float,
        damping: float = 0.0,
        rest_length: float = 0.0,
        attach: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        if not isinstance(body, (int, np.integer)) or isinstance(body, bool):
            raise ValueError(f"body must be a body index (int), got {body!r}")
        anchor_array = finite_array(anchor, "anchor", (3,))
        attach_array = finite_array(attach, "attach", (3,))
        if anchor_array.shape != (3,) or attach_array.shape != (3,):
            raise ValueError("anchor and attach must be 3-vectors")
        object.__setattr__(self, "body", body)
        object.__setattr__(self, "anchor", anchor_array)
        object.__setattr__(self, "attach", attach_array)
        object.__setattr__(self, "stiffness", nonnegative_scalar(stiffness, "stiffness"))
        object.__setattr__(self, "damping", nonnegative_scalar(damping, "damping"))
        object.__setattr__(self, "rest_length", nonnegative_scalar(rest_length, "rest_length"))


class Model:
    """Per-body arrays (leading axis = body) and the scene's force terms, built once."""

    def __init__(
        self,
        bodies: Sequence[Body],
        gravity: ArrayLike | None,
        ground: Ground | None,
        springs: Sequence[Spring],
        linear_damping: float,
        angular_damping: float,
        contacts: Material | None = None,
    ) -> None:
        n = len(bodies)
        self.bodies = tuple(bodies)
        self.n_bodies = n
        self.mass = np.array([b.mass for b in bodies])  # (n,)
        self.inv_mass = 1.0 / self.mass
        self.inertia = np.stack([b.inertia for b in bodies])  # (n, 3, 3), body axes
        self.inv_inertia = np.linalg.inv(self.inertia)
        diag = np.einsum("nii->ni", self.inertia)
        # Primitives have diagonal body inertia: then M0⁻¹ applies elementwise (cheaper).
        self.inertia_diagonal = (
            diag if np.array_equal(self.inertia, diag[..., None] * np.eye(3)) else None
        )
        # Principal frame: inertia = P diag(moments) Pᵀ with det P = +1 (the splitting integrators
        # rotate about principal axes).
        moments, axes = np.linalg.eigh(self.inertia)
        axes[..., :, 2] *= np.sign(np.linalg.det(axes))[..., None]
        if self.inertia_diagonal is not None:
            moments, axes = self.inertia_diagonal, np.broadcast_to(np.eye(3), axes.shape)
        self.principal_moments = moments  # (n, 3)
        self.principal_axes = axes  # (n, 3, 3)
        self.inverse_principal_moments_array = 1.0 / moments  # (n, 3)
        self.inverse_principal_moments = tuple(1.0 / moments[:, a] for a in range(3))
        if np.array_equal(axes, np.broadcast_to(np.eye(3), axes.shape)):
            self.principal_quat = self.principal_conj = None  # body axes are principal
        else:
            self.principal_quat = matrix_to_quat(axes)
            self.principal_conj = self.principal_quat * np.array([-1.0, -1.0, -1.0, 1.0])
        self.gravity = None if gravity is None else finite_array(gravity, "gravity", (3,))
        if self.gravity is not None and self.gravity.shape != (3,):
            raise ValueError(f"gravity must be a 3-vector, got shape {self.gravity.shape}")
        self.ground = ground
        self.contacts = contacts  # Material of body–body contacts, or None (bodies pass through)
        self.springs = tuple(springs)
        self.linear_damping = nonnegative_scalar(linear_damping, "linear_damping")
        self.angular_damping = nonnegative_scalar(angular_damping, "angular_damping")

    def apply_inverse_inertia(self, rot: np.ndarray, vec: np.ndarray) -> np.ndarray:
        """``M⁻¹ vec = R M0⁻¹ Rᵀ vec`` (notes: inertia in world axes), vec in world axes."""
        local = rotate_inverse(rot, vec)
        if self.inertia_diagonal is not None:
            return rotate(rot, local / self.inertia_diagonal)
        return rotate(rot, matvec(self.inv_inertia, local))

    def apply_inertia(self, rot: np.ndarray, vec: np.ndarray) -> np.ndarray:
        """``M vec = R M0 Rᵀ vec``: e.g. the world angular momentum ``L = M ω``."""
        local = rotate_inverse(rot, vec)
        if self.inertia_diagonal is not None:
            return rotate(rot, local * self.inertia_diagonal)
        return rotate(rot, matvec(self.inertia, local))
