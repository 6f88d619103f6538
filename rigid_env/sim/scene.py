"""A scene: a static model plus the step pipeline composed from only the terms it uses.

``Scene.stages`` names the pipeline: force stages (gravity, damping, springs) evaluated inside
the integrator, then ``integrate``, then the contact stages when a ground is given. A body
tumbling in space has ``stages == ("integrate",)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import contacts as contact_stages
from . import forces
from .body import Body
from .compiled.backend import driver_for
from .integrators import REGISTRY
from .model import Ground, Material, Model, Spring
from .rotation import cross, quat_rotate, quat_to_matrix
from .state import State
from .validation import positive_scalar

INTEGRATORS: tuple[str, ...] = tuple(REGISTRY)
DEFAULT_INTEGRATOR = "splitting"
# Scenes with contacts default to semi-implicit Euler with the implicit gyroscopic term: contact
# impulses act between its velocity and position updates, and it stays stable for tumbling boxes.
CONTACT_INTEGRATOR = "implicit_gyro"


class DivergenceError(FloatingPointError):
    """A step from a valid state produced NaN or infinity (the integrator blew up)."""


class Scene:
    """Bodies, a time step, an integrator and the optional terms: gravity, ground, springs.

    Parameters
    ----------
    bodies : a :class:`Body` or a sequence of them.
    dt : time step in seconds.
    integrator : one of :data:`INTEGRATORS`; ``None`` picks :data:`DEFAULT_INTEGRATOR`, or
        :data:`CONTACT_INTEGRATOR` when the scene has contacts. Contacts need a semi-implicit
        integrator (``contacts.COMPATIBLE_INTEGRATORS``); others raise ``ValueError``.
    gravity : world acceleration vector (m/s²), e.g. ``(0, 0, -9.81)``; ``None`` for space.
    ground : a :class:`Ground` (plane z = 0) or ``None``.
    springs : a sequence of :class:`Spring`.
    linear_damping, angular_damping : decay rates of linear and angular momentum, 1/s.
    contacts : a :class:`Material` for body–body contacts, or ``None`` (bodies pass through
        each other).
    backend : ``"auto"`` (compiled when numba is installed and every stage has a kernel, else
        numpy), ``"numpy"``, ``"compiled"`` or ``"compiled-threads"``; ``None`` reads the
        environment variable ``RIGID_ENV_BACKEND`` (default ``"auto"``). See
        :mod:`rigid_env.sim.compiled.backend`.
    """

    def __init__(
        self,
        bodies,
        dt,
        integrator: str | None = None,
        gravity=None,
        ground: Ground | None = None,
        springs: Sequence[Spring] = (),
        linear_damping: float = 0.0,
        angular_damping: float = 0.0,
        contacts: Material | None = None,
        backend: str | None = None,
    ):
        if isinstance(bodies, Body):
            bodies = (bodies,)
        bodies = tuple(bodies)
        if not bodies or not all(isinstance(b, Body) for b in bodies):
            raise ValueError("bodies must be a Body or a non-empty sequence of Body")
        self.dt = positive_scalar(dt, "dt")
        if ground is not None and not isinstance(ground, Ground):
            raise ValueError(f"ground must be a Ground or None, got {ground!r}")
        if contacts is not None and not isinstance(contacts, Material):
            raise ValueError(f"contacts must be a Material or None, got {contacts!r}")
        springs = tuple(springs)
        for sp in springs:
            if not isinstance(sp, Spring):
                raise ValueError(f"springs must contain Spring objects, got {sp!r}")
            if not 0 <= sp.body < len(bodies):
                raise ValueError(f"springs: body index {sp.body} out of range for {len(bodies)}")
        self.model = Model(
            bodies, gravity, ground, springs, linear_damping, angular_damping, contacts
        )
        contact_names, contact_stage = contact_stages.build(self.model, self.dt)
        if integrator is None:
            integrator = CONTACT_INTEGRATOR if contact_stage else DEFAULT_INTEGRATOR
        if integrator not in REGISTRY:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
        if contact_stage and integrator not in contact_stages.COMPATIBLE_INTEGRATORS:
            raise ValueError(
                f"integrator {integrator!r} cannot be combined with contacts: contact impulses "
                f"act between the velocity and position updates of a semi-implicit step; use "
                f"one of {contact_stages.COMPATIBLE_INTEGRATORS}"
            )
        self.integrator = integrator
        terms = forces.build_terms(self.model)
        self._forces = (
            forces.combine(terms, forces.is_velocity_dependent(self.model)) if terms else None
        )
        self._integrate = REGISTRY[integrator]
        self._post_stages: tuple = ((contact_names, contact_stage),) if contact_stage else ()
        self.stages: tuple[str, ...] = (
            *(name for name, _ in terms),
            "integrate",
            *contact_names,
        )
        self._driver = driver_for(self, backend)
        self.backend = "numpy" if self._driver is None else "compiled"

    @property
    def n_bodies(self) -> int:
        return self.model.n_bodies

    # --- states ---------------------------------------------------------------------------------

    def initial_state(
        self,
        position=None,
        orientation=None,
        linear_velocity=None,
        angular_velocity=None,
        batch_shape=(),
    ) -> State:
        """A state broadcast to ``(*batch_shape, n_bodies, ·)``; unset fields are zero/identity.

        Given arrays may carry batch axes of their own; the result has the broadcast batch shape.
        Orientations are normalised (any non-zero quaternion is accepted).
        """
        n = self.n_bodies
        try:
            batch_shape = tuple(int(b) for b in np.atleast_1d(np.asarray(batch_shape, int)))
        except (TypeError, ValueError):
            raise ValueError(f"batch_shape must be a tuple of ints, got {batch_shape!r}") from None
        if any(b < 0 for b in batch_shape):
            raise ValueError(f"batch_shape must be non-negative, got {batch_shape}")
        fields = {
            "position": (position, 3, np.zeros(3)),
            "orientation": (orientation, 4, np.array([0.0, 0.0, 0.0, 1.0])),
            "linear_velocity": (linear_velocity, 3, np.zeros(3)),
            "angular_velocity": (angular_velocity, 3, np.zeros(3)),
        }
        arrays = {}
        for name, (value, width, default) in fields.items():
            arr = default if value is None else _finite(value, name)
            if arr.shape[-1:] != (width,):
                raise ValueError(f"{name} must end in an axis of length {width}, got {arr.shape}")
            arrays[name] = arr
        try:
            shape = np.broadcast_shapes(
                (*batch_shape, n, 1), *(a.shape[:-1] + (1,) for a in arrays.values())
            )
        except ValueError:
            shape = None
        if shape is None or shape[-2] != n:
            raise ValueError(
                f"state arrays do not broadcast to (*batch_shape, {n}, ·): "
                + ", ".join(f"{k} {a.shape}" for k, a in arrays.items())
            )
        out = {}
        for name, arr in arrays.items():
            out[name] = np.array(np.broadcast_to(arr, shape[:-1] + arr.shape[-1:]), dtype=float)
        norm = np.linalg.norm(out["orientation"], axis=-1, keepdims=True)
        if np.any(norm < 1e-12):
            raise ValueError("orientation must be non-zero quaternions (x, y, z, w)")
        out["orientation"] /= norm
        return State(**out)

    # --- stepping -------------------------------------------------------------------------------

    def step(self, state: State, torque=None, force=None) -> State:
        """Advance every batch element by one ``dt``; torque and force are world-frame.

        ``torque``/``force`` broadcast to ``(*batch_shape, n_bodies, 3)`` and act at the centres
        of mass for the whole step. The state passed in is never modified.
        """
        shape = self._check_state(state)
        torque = _load(torque, "torque", shape)
        force = _load(force, "force", shape)
        if self._driver is not None:
            return self._compiled_step(state, shape, force, torque)
        new = self._integrate(self.model, state, self.dt, self._forces, force, torque)
        for _, stage in self._post_stages:
            new = stage(state, new)
        if not _all_finite(new):
            self._diagnose(state)
        return new

    def _compiled_step(self, state, shape, force, torque) -> State:
        n, drv = self.n_bodies, self._driver
        flat = (-1, n, 3)
        x, q, v, w, _, bad = drv(
            _flat(state.position, flat),
            _flat(state.orientation, (-1, n, 4)),
            _flat(state.linear_velocity, flat),
            _flat(state.angular_velocity, flat),
            drv.zeros(shape).reshape(flat) if force is None else _flat_load(force, shape, flat),
            drv.zeros(shape).reshape(flat) if torque is None else _flat_load(torque, shape, flat),
        )
        if bad:
            self._diagnose(state)
        qshape = shape[:-1] + (4,)
        return State(x.reshape(shape), q.reshape(qshape), v.reshape(shape), w.reshape(shape))

    def _check_state(self, state) -> tuple[int, ...]:
        if not isinstance(state, State):
            raise ValueError(f"state must be a State, got {type(state).__name__}")
        shape = state.position.shape
        if len(shape) < 2 or shape[-2:] != (self.n_bodies, 3):
            raise ValueError(f"state.position must have shape (*batch, {self.n_bodies}, 3)")
        if (
            state.linear_velocity.shape != shape
            or state.angular_velocity.shape != shape
            or state.orientation.shape != shape[:-1] + (4,)
        ):
            raise ValueError("state arrays disagree in shape")
        return shape

    def _diagnose(self, state):
        names = ("position", "orientation", "linear_velocity", "angular_velocity")
        for name, arr in zip(names, state.arrays(), strict=True):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"state.{name} contains NaN or infinity")
        raise DivergenceError(
            f"the step diverged (non-finite result) with integrator {self.integrator!r} at "
            f"dt={self.dt}; use a smaller dt or a more stable integrator"
        )

    # --- what users read off a state ------------------------------------------------------------

    def linear_momentum(self, state: State) -> np.ndarray:
        """Total m v, ``(*batch, 3)``."""
        return np.sum(self.model.mass[:, None] * state.linear_velocity, axis=-2)

    def angular_momentum(self, state: State, about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Total world angular momentum about a world point: Σ (x − o) × m v + M ω."""
        spin = self.model.apply_inertia(state.rotation, state.angular_velocity)
        orbit = cross(state.position - np.asarray(about, float), state.linear_velocity)
        return np.sum(spin + self.model.mass[:, None] * orbit, axis=-2)

    def kinetic_energy(self, state: State) -> np.ndarray:
        """Σ ½ m v² + ½ ωᵀ M ω, ``(*batch,)``."""
        m = self.model.mass
        spin = self.model.apply_inertia(state.rotation, state.angular_velocity)
        lin = 0.5 * m * np.sum(state.linear_velocity**2, axis=-1)
        return np.sum(lin + 0.5 * np.sum(state.angular_velocity * spin, axis=-1), axis=-1)

    def potential_energy(self, state: State) -> np.ndarray:
        """Gravity −m g·x plus spring energy ½ k (|d| − rest)², ``(*batch,)``."""
        energy = np.zeros(state.batch_shape)
        if self.model.gravity is not None:
            energy = energy - np.sum(self.model.mass * (state.position @ self.model.gravity), -1)
        for sp in self.model.springs:
            p = state.position[..., sp.body, :] + quat_rotate(
                state.orientation[..., sp.body, :], sp.attach
            )
            stretch = np.linalg.norm(p - sp.anchor, axis=-1) - sp.rest_length
            energy = energy + 0.5 * sp.stiffness * stretch**2
        return energy

    def energy(self, state: State) -> np.ndarray:
        return self.kinetic_energy(state) + self.potential_energy(state)

    def rotation(self, state: State) -> np.ndarray:
        return quat_to_matrix(state.orientation)


def _finite(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array") from None
    if arr.ndim == 0 or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite array (no NaN or infinity), got {value!r}")
    return arr


def _load(value, name: str, shape: tuple[int, ...]):
    """Validate an applied torque or force against the state shape (cheap in the good case)."""
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape {shape}") from None
    if arr.shape != shape:
        try:
            ok = np.broadcast_shapes(arr.shape, shape) == shape
        except ValueError:
            ok = False
        if not ok or arr.ndim == 0:
            raise ValueError(f"{name} must broadcast to shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or infinity")
    return arr


def _flat(arr: np.ndarray, flat: tuple[int, ...]) -> np.ndarray:
    """A float64, C-contiguous, writable (N, n, ·) view or copy, as the kernels take."""
    if arr.dtype != np.float64 or not arr.flags.c_contiguous or not arr.flags.writeable:
        arr = np.array(arr, dtype=np.float64, order="C")
    return arr.reshape(flat)


def _flat_load(arr: np.ndarray, shape, flat) -> np.ndarray:
    if arr.shape != shape:
        arr = np.broadcast_to(arr, shape)
    return _flat(arr, flat)


def _all_finite(state: State) -> bool:
    # One reduction per array: a NaN or infinity anywhere makes the sum non-finite.
    total = 0.0
    for arr in state.arrays():
        total += arr.sum()
    return bool(np.isfinite(total))
