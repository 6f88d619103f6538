"""A scene: a static model plus the step pipeline composed from only the terms it uses.

``Scene.pipeline`` is the ordered tuple of stage objects a step runs (``sim.pipeline``) and
``Scene.stages`` their names: the force stages it was given (gravity, damping, springs), then
the integrator's parts, with the contact stages between a semi-implicit integrator's velocity
and position updates. A body tumbling in space has ``stages == ("integrate",)``; a box landing
on the ground ``("gravity", "integrate_velocity", "collide_ground", "assemble_contacts",
"restitute", "solve_contacts", "limit_energy", "integrate_position", "separate_contacts")``.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import contacts as contact_stages
from . import forces
from .body import Body
from .compiled.backend import BACKENDS, driver_for
from .contacts import SolverSettings
from .integrators import CONTACT_CAPABLE, RECORDS
from .model import Ground, Material, Model, Spring
from .parameters import Parameters
from .parameters import build as build_parameters
from .pipeline import StageTimer
from .rotation import cross, quat_rotate, quat_to_matrix
from .state import FIELDS as STATE_FIELDS
from .state import ORIENTATION_TOLERANCE, ZERO_TIME, State
from .validation import positive_scalar

INTEGRATORS: tuple[str, ...] = tuple(RECORDS)
DEFAULT_INTEGRATOR = "splitting"
# Scenes with contacts default to semi-implicit Euler with the implicit gyroscopic term: contact
# impulses act between its velocity and position updates, and it stays stable for tumbling boxes.
CONTACT_INTEGRATOR = "implicit_gyro"
# How the compiled step runs (``compiled.backend``); ``backend=None`` reads RIGID_ENV_BACKEND,
# else "compiled".
BACKEND_VARIABLE = "RIGID_ENV_BACKEND"
_F64 = np.dtype(np.float64)
_State_new = object.__new__


def _carry(new: State, shape, warm: np.ndarray) -> None:
    """Give the state a step returns the warm start of its next step, (N, C, 4) as the compiled
    step writes it (``Driver.__call__``), batch-shaped (``State.contact_impulses``)."""
    new.__dict__["_warm"] = warm if len(shape) == 3 else warm.reshape(*shape[:-2], *warm.shape[1:])


def _later(state: State, dt: float, steps: int) -> tuple:
    """The time of the state ``steps`` steps of ``dt`` after ``state`` (``State.time``)."""
    origin, step, count, offset = state.__dict__.get("_time", ZERO_TIME)
    if step == dt:
        return (origin, dt, count + steps, offset)
    return (state.time if count else origin, dt, steps, 0)  # (a new Δt: a new origin)


def shape_size(shape) -> int:
    """The flattened batch of a state shape (*batch, n, 3): ``math.prod`` of the ints, not
    ``np.prod``, which first makes an array of the tuple (a visible part of a batch-1 step)."""
    return math.prod(shape[:-2])


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
        integrator (``integrators.CONTACT_CAPABLE``); others raise ``ValueError``.
    gravity : world acceleration vector (m/s²), e.g. ``(0, 0, -9.81)``; ``None`` for space.
    ground : a :class:`Ground` (plane z = 0) or ``None``.
    springs : a sequence of :class:`Spring`.
    linear_damping, angular_damping : decay rates of linear and angular momentum, 1/s.
    contacts : a :class:`Material` for body–body contacts, or ``None`` (bodies pass through
        each other).
    backend : one of :data:`BACKENDS`: ``"compiled"`` (the element kernels, one call per
        step over the batch) or ``"compiled-threads"`` (the same over threads, for large
        batches); ``None`` reads the environment variable ``RIGID_ENV_BACKEND`` (default
        ``"compiled"``). ``scene.backend`` is ``"compiled"`` either way. The kernels are the
        only implementation; ``NUMBA_DISABLE_JIT=1`` runs the same source as plain Python (a
        debugging mode, slow).
    timer : a :class:`~rigid_env.sim.pipeline.StageTimer` that accumulates the wall time of
        a step's parts (also settable later as ``scene.timer``); ``None`` times nothing.
    contact_solver : a :class:`~rigid_env.sim.contacts.SolverSettings` (iteration cap,
        tolerance, impact cap of the contact solve); ``None`` takes its defaults.

    A step returns its report with the state: ``state.report`` (a mapping), also
    ``scene.report`` until the scene's next step. With contacts,
    ``report["contacts"]`` is a :class:`~rigid_env.sim.contacts.ContactReport`: its
    ``capped`` counts the batch elements whose solve stopped at a cap instead of converging
    (also raised as a ``ContactSolverWarning``).
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
        timer: StageTimer | None = None,
        contact_solver: SolverSettings | None = None,
        _kernels: bool = True,
    ):
        if isinstance(bodies, Body):
            bodies = (bodies,)
        try:
            bodies = tuple(bodies)
        except TypeError:
            raise ValueError("bodies must be a Body or a non-empty sequence of Body") from None
        if not bodies or not all(isinstance(b, Body) for b in bodies):
            raise ValueError("bodies must be a Body or a non-empty sequence of Body")
        self.dt = positive_scalar(dt, "dt")
        if ground is not None and not isinstance(ground, Ground):
            raise ValueError(f"ground must be a Ground or None, got {ground!r}")
        if contacts is not None and not isinstance(contacts, Material):
            raise ValueError(f"contacts must be a Material or None, got {contacts!r}")
        if timer is not None and not isinstance(timer, StageTimer):
            raise ValueError(f"timer must be a StageTimer or None, got {timer!r}")
        try:
            springs = tuple(springs)
        except TypeError:
            raise ValueError(f"springs must be a sequence of Spring, got {springs!r}") from None
        for sp in springs:
            if not isinstance(sp, Spring):
                raise ValueError(f"springs must contain Spring objects, got {sp!r}")
            if not 0 <= sp.body < len(bodies):
                raise ValueError(f"springs: body index {sp.body} out of range for {len(bodies)}")
        self.backend = _backend(backend)
        # What ``rebuilt`` passes on (a parameter row's scene: other bodies, another ground).
        self._spec = dict(
            dt=dt,
            integrator=integrator,
            gravity=gravity,
            springs=springs,
            linear_damping=linear_damping,
            angular_damping=angular_damping,
            contacts=contacts,
            contact_solver=contact_solver,
        )
        self.model = Model(
            bodies, gravity, ground, springs, linear_damping, angular_damping, contacts
        )
        between, after = contact_stages.build(self.model, self.dt, contact_solver)
        # The contact solve starts from the previous step's impulses, which the state carries.
        self.warm_start = bool(between) and contact_solver is not None and contact_solver.warm_start
        self._c = next((s.layout.c for s in between if hasattr(s, "layout")), 0)  # contact slots
        if integrator is None:
            integrator = CONTACT_INTEGRATOR if between else DEFAULT_INTEGRATOR
        if not isinstance(integrator, str) or integrator not in RECORDS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
        record = RECORDS[integrator]
        if between and not record.contact_capable:
            raise ValueError(
                f"integrator {integrator!r} cannot be combined with contacts: contact impulses "
                f"act between the velocity and position updates of a semi-implicit step; use "
                f"one of {CONTACT_CAPABLE}"
            )
        self.integrator = integrator
        self.forces = forces.build(self.model)
        parts = record.stages()
        if record.semi_implicit:
            velocity, position = parts
            steps = (velocity, *between, position, *after)
        else:
            steps = parts
        self.pipeline: tuple = (*self.forces, *steps)
        self.timer = timer
        self._last: State | None = None  # the last state a step returned (``report``)
        self._known_shapes: tuple = ((), ())
        # A parameter row's scene (``rebuilt``) only lends its kernels' data: no driver.
        self._driver = driver_for(self, self.backend) if _kernels else None
        self.backend = "compiled"

    @property
    def report(self) -> Mapping[str, Any]:
        """The report of the last step this scene ran (``State.report`` of the state it
        returned; see the class docstring). Steps of one scene on several threads: read each
        returned state's ``report`` instead, which is its own step's. A compiled step keeps
        its report columns and builds the dict on the first read (a share of a batch-1 step
        that a caller who never reads it need not pay); a step whose contact
        solve stopped at its cap builds it at once, so its ``ContactSolverWarning`` comes with
        the step."""
        last = self._last
        return {} if last is None else last.report

    def parameters(self, mass=None, inertia=None, friction=None, restitution=None) -> Parameters:
        """Per-element model parameters for :meth:`step` (:mod:`~rigid_env.sim.parameters`):
        ``mass`` (R, n), ``inertia`` (R, n, 3, 3) in body axes (a one-body scene also takes
        (R,) and (R, 3, 3)), the ground's ``friction`` and ``restitution`` (R,); each given
        array has the same R rows, the others take the
        scene's values. Row e serves batch element e (or one row every element). Checked as
        :class:`Body` and :class:`Ground` check theirs: a ``ValueError`` names the array and
        the row. Only a compiled scene takes them (``step`` says why not otherwise)."""
        return build_parameters(
            self,
            {"mass": mass, "inertia": inertia, "friction": friction, "restitution": restitution},
        )

    def rebuilt(self, bodies, ground) -> Scene:
        """This scene with other bodies and ground (same shapes, same composition), without a
        driver of its own: its kernels' data are a parameter row's (``parameters.row_data``);
        it does not step."""
        return Scene(bodies, ground=ground, _kernels=False, **self._spec)

    @property
    def stages(self) -> tuple[str, ...]:
        """The names of :attr:`pipeline`'s stages, in order."""
        return tuple(stage.name for stage in self.pipeline)

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
        try:  # integers only: a float such as 2.5 is refused, not truncated
            sizes = np.atleast_1d(np.asarray(batch_shape))
            if sizes.ndim != 1 or (sizes.size and sizes.dtype.kind not in "iu"):
                raise TypeError
            batch_shape = tuple(int(b) for b in sizes)
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
        # Scale by the largest component first: |q|² of a huge (finite) q would overflow to
        # infinity and normalise to zeros; scaled, every component is in [−1, 1].
        q = out["orientation"]
        peak = np.max(np.abs(q), axis=-1, keepdims=True)
        if not np.all(peak > 0):
            raise ValueError("orientation must be non-zero quaternions (x, y, z, w)")
        q /= peak
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        return State(**out)

    # --- stepping -------------------------------------------------------------------------------

    def step(
        self,
        state: State,
        torque=None,
        force=None,
        *,
        body_torque=None,
        steps: int = 1,
        parameters: Parameters | None = None,
    ) -> State:
        """Advance every batch element by ``steps`` physics steps of ``dt`` under the same loads.

        ``torque``/``force`` are world-frame and held constant over each step. ``body_torque``
        is fixed in the body frame (the axes the :class:`Body` is defined in, which
        ``state.orientation`` maps to the world): it turns with the body, so the integrator
        evaluates ``R(q) body_torque`` wherever it evaluates loads, at that evaluation's
        orientation q (each RK4 stage, each kick of a splitting or exact method, an implicit
        method's start-of-step velocity update). All three broadcast to
        ``(*batch_shape, n_bodies, 3)`` and act at the centres of mass; they add up.

        ``steps`` (a positive int) runs that many steps in one call, each exactly as a call of
        its own would (``step(s, steps=k)`` equals k calls bit for bit) but paying the call's
        overhead once: one kernel call runs all k. With
        ``SolverSettings(warm_start=True)`` each step starts its contact solve from the
        previous step's impulses, which the returned state carries into the next call
        (``State.contact_impulses``; a state that carries none starts cold). A step
        that diverges raises as a single call would, and the k steps' states are not returned.
        The returned state's ``report`` is then the k steps' reports merged entry by entry
        into their maximum (per-element flags OR'ed, the energy removed summed): an iteration
        count is the most any step used, a count of capped solves is non-zero iff some step
        stopped at its cap. A :class:`StageTimer` counts k steps.

        The state passed in is never modified, and the state returned shares no memory with it
        (float64 whatever the input's dtype).
        """
        timer = self.timer
        clock = time.perf_counter
        start = clock() if timer is not None else 0.0
        if not (steps == 1 and type(steps) is int):
            steps = _steps(steps)
        if self._driver is None:
            raise ValueError("this scene lends a parameter row its data and does not step")
        return self._compiled_step(state, torque, force, body_torque, steps, start, parameters)

    def _compiled_step(
        self, state, torque, force, body_torque, steps, start, parameters=None
    ) -> State:
        """The ``steps`` steps in one kernel call over the flattened batch (``compiled.driver``).

        The common case (float64 ndarrays of the right shapes) is checked here in a few
        attribute reads; the unit-quaternion check runs in the kernel (same arithmetic as
        ``_arrays``), whose verdict ``_arrays`` then turns into the same ``ValueError``.
        """
        timer, drv = self.timer, self._driver
        assert drv is not None  # (``step`` refuses a scene without a driver)
        arrays = self._plain_arrays(state)
        if arrays is None:
            arrays = self._arrays(state)
        shape = arrays[0].shape
        # Loads are checked for finiteness only if the step comes out non-finite (below).
        if torque is not None:
            torque = _load(torque, "torque", shape, check_finite=False)
        if force is not None:
            force = _load(force, "force", shape, check_finite=False)
        if body_torque is not None:
            body_torque = _load(body_torque, "body_torque", shape, check_finite=False)
        data = None if parameters is None else self._parameter_data(parameters, shape)
        if timer is not None:
            mid = time.perf_counter()
            timer.add("validate", mid - start)
        warm = None
        if self.warm_start:  # in: what the state carries; out: the returned state's
            carried = self._carried(state, shape)
            warm = (carried, np.empty(carried.shape))
        x, q, v, w, report, (bad_orientation, diverged, capped), counts = drv(
            *arrays, force, torque, body_torque, steps, data, warm
        )
        counts = None if steps == 1 else counts
        if timer is not None:
            end = time.perf_counter()
            timer.add("compiled", end - mid)
            mid = end
        if bad_orientation:
            self._arrays(state)  # raises the ValueError that names state.orientation
            raise ValueError(  # (a quaternion within rounding of the tolerance: same verdict)
                f"state.orientation must hold finite unit quaternions (x, y, z, w) with |q| "
                f"within {ORIENTATION_TOLERANCE:g} of 1"
            )
        if diverged:
            loads = (("torque", torque), ("force", force), ("body_torque", body_torque))
            for name, load in loads:
                if load is not None and not np.isfinite(load).all():
                    raise ValueError(f"{name} contains NaN or infinity")
            self._diagnose(arrays)
        if capped:  # the report now: it warns (ContactSolverWarning) from this step
            built: Any = drv.report(report, counts)
        elif drv.slots:  # the report's columns: ``State.report`` builds it when read
            built = (drv.report, report, counts)
        else:  # (no stage reports: an empty report, as ``State.report`` reads None)
            built = None
        if len(shape) != 3:
            qshape = shape[:-1] + (4,)
            x, q, v, w = x.reshape(shape), q.reshape(qshape), v.reshape(shape), w.reshape(shape)
        # State(x, q, v, w) without the frozen dataclass's four object.__setattr__ calls
        # (item by item, cheaper than update(**)): the same instance, fields set once.
        new = _State_new(State)
        fields = new.__dict__
        fields["position"] = x
        fields["orientation"] = q
        fields["linear_velocity"] = v
        fields["angular_velocity"] = w
        fields["_report"] = built
        clock = state.__dict__.get("_time")  # (``_later``, written out: a free body's step)
        if clock is not None and clock[1] == self.dt:
            fields["_time"] = (clock[0], clock[1], clock[2] + steps, clock[3])
        else:
            fields["_time"] = _later(state, self.dt, steps)
        if warm is not None:  # what the last step's solve ended with (``_warm_slots``)
            _carry(new, shape, warm[1])
        self._last = new
        if timer is not None:
            timer.add("check", time.perf_counter() - mid)
            # The total by its own later read: the parts are back to back here, and a shared
            # read could make their rounded sum exceed it.
            timer.step_seconds += time.perf_counter() - start
            timer.steps += steps
        return new

    def _carried(self, state, shape) -> np.ndarray:
        """The warm start the state carries, (N, C, 4) as the compiled step takes it: per slot
        the impulse (n, t₁, t₂), in slot 0 the flag of a converged solve; zeros (cold) for a
        state that carries none (built, or from another scene)."""
        carried = state.__dict__.get("_warm")
        if carried is not None and carried.shape[:-2] == shape[:-2]:  # (the same scene's)
            if not carried.flags.carray:  # (a view of an indexed state: the one compiled type)
                carried = np.array(carried, order="C")
            if len(shape) == 3 and carried.shape[1] == self._c:
                return carried
            if carried.shape[-2:] == (self._c, 4):
                return carried.reshape(shape_size(shape), self._c, 4)
        return np.zeros((shape_size(shape), self._c, 4))

    def _parameter_data(self, parameters, shape) -> tuple:
        """The driver's data of ``parameters`` for a state of this shape."""
        if not isinstance(parameters, Parameters) or parameters.scene is not self:
            raise ValueError("parameters must come from this scene's parameters()")
        size = shape_size(shape)
        if parameters.rows not in (1, size):
            raise ValueError(
                f"parameters has {parameters.rows} rows; a batch of {size} elements takes "
                f"{size} rows (one per element) or 1"
            )
        return parameters.data

    def _plain_arrays(self, state):
        """The state's arrays if they are float64 ndarrays of consistent shapes, else None."""
        if type(state) is not State:
            return None
        x, q, v, w = (
            state.position,
            state.orientation,
            state.linear_velocity,
            state.angular_velocity,
        )
        if not (type(x) is type(q) is type(v) is type(w) is np.ndarray):
            return None
        if not (x.dtype is _F64 and q.dtype is _F64 and v.dtype is _F64 and w.dtype is _F64):
            return None
        shape = x.shape
        known = self._known_shapes  # (position, orientation) shapes of the last state passed
        if shape != known[0]:
            if len(shape) < 2 or shape[-2:] != (self.model.n_bodies, 3):
                return None
            known = self._known_shapes = (shape, shape[:-1] + (4,))
        if v.shape != shape or w.shape != shape or q.shape != known[1]:
            return None
        return x, q, v, w

    def _arrays(self, state) -> tuple[np.ndarray, ...]:
        """The state's arrays as float64 (no copy when they already are), checked for type,
        shape and unit quaternions; every failure is a ``ValueError`` naming the field."""
        if not isinstance(state, State):
            raise ValueError(f"state must be a State, got {type(state).__name__}")
        arrays = []
        for name, value in zip(STATE_FIELDS, state.arrays(), strict=True):
            try:
                arrays.append(np.asarray(value, dtype=np.float64))
            except (TypeError, ValueError):
                raise ValueError(f"state.{name} must be a numeric array") from None
        x, q, v, w = arrays
        shape = x.shape
        if len(shape) < 2 or shape[-2:] != (self.n_bodies, 3):
            raise ValueError(
                f"state.position must have shape (*batch, {self.n_bodies}, 3) for this scene's "
                f"{self.n_bodies} bodies, got {shape}"
            )
        if v.shape != shape or w.shape != shape or q.shape != shape[:-1] + (4,):
            raise ValueError(
                "state arrays disagree in shape: "
                + ", ".join(f"{k} {a.shape}" for k, a in zip(STATE_FIELDS, arrays, strict=True))
            )
        # |q|² − 1 ≈ 2 (|q| − 1); a zero, non-finite or overflowing |q|² fails the comparison.
        # (One einsum: its summation order does not matter for a tolerance check.)
        with np.errstate(over="ignore", invalid="ignore"):
            deviation = np.abs(np.einsum("...i,...i->...", q, q) - 1.0)
        if not np.all(deviation <= 2 * ORIENTATION_TOLERANCE):
            raise ValueError(
                f"state.orientation must hold finite unit quaternions (x, y, z, w) with |q| "
                f"within {ORIENTATION_TOLERANCE:g} of 1; Scene.initial_state normalises any "
                f"non-zero quaternion"
            )
        return tuple(arrays)

    def _diagnose(self, arrays):
        _require_finite(arrays)
        raise DivergenceError(
            f"the step diverged (non-finite result) with integrator {self.integrator!r} at "
            f"dt={self.dt}; use a smaller dt or a more stable integrator"
        )

    # --- what users read off a state ------------------------------------------------------------
    # Each checks the state as ``step`` does (a state of another scene, or one with NaN or
    # infinity, is the ValueError ``step`` raises for it).

    def _read_arrays(self, state) -> tuple[np.ndarray, ...]:
        arrays = self._arrays(state)
        _require_finite(arrays)
        return arrays

    def linear_momentum(self, state: State) -> np.ndarray:
        """Total m v, ``(*batch, 3)``."""
        _, _, v, _ = self._read_arrays(state)
        return np.sum(self.model.mass[:, None] * v, axis=-2)

    def angular_momentum(self, state: State, about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Total world angular momentum about a world point: Σ (x − o) × m v + M ω."""
        x, q, v, w = self._read_arrays(state)
        about = _finite(about, "about")
        try:
            ok = about.shape[-1] == 3 and np.broadcast_shapes(about.shape, x.shape) == x.shape
        except ValueError:
            ok = False
        if not ok:
            raise ValueError(
                f"about must be a 3-vector or broadcast to {x.shape}, got {about.shape}"
            )
        spin = self.model.apply_inertia(quat_to_matrix(q), w)
        orbit = cross(x - about, v)
        return np.sum(spin + self.model.mass[:, None] * orbit, axis=-2)

    def kinetic_energy(self, state: State) -> np.ndarray:
        """Σ ½ m v² + ½ ωᵀ M ω, ``(*batch,)``."""
        _, q, v, w = self._read_arrays(state)
        m = self.model.mass
        spin = self.model.apply_inertia(quat_to_matrix(q), w)
        lin = 0.5 * m * np.sum(v**2, axis=-1)
        return np.sum(lin + 0.5 * np.sum(w * spin, axis=-1), axis=-1)

    def potential_energy(self, state: State) -> np.ndarray:
        """Gravity −m g·x plus spring energy ½ k (|d| − rest)², ``(*batch,)``."""
        x, q, _, _ = self._read_arrays(state)
        energy = np.zeros(x.shape[:-2])
        if self.model.gravity is not None:
            energy = energy - np.sum(self.model.mass * (x @ self.model.gravity), -1)
        for sp in self.model.springs:
            p = x[..., sp.body, :] + quat_rotate(q[..., sp.body, :], sp.attach)
            stretch = np.linalg.norm(p - sp.anchor, axis=-1) - sp.rest_length
            energy = energy + 0.5 * sp.stiffness * stretch**2
        return energy

    def energy(self, state: State) -> np.ndarray:
        return self.kinetic_energy(state) + self.potential_energy(state)


def _require_finite(arrays) -> None:
    """The ``ValueError`` naming the first state field with NaN or infinity, if any."""
    for name, arr in zip(STATE_FIELDS, arrays, strict=True):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"state.{name} contains NaN or infinity")


def _backend(value: str | None) -> str:
    source = "backend"
    if value is None:
        value, source = os.environ.get(BACKEND_VARIABLE) or "compiled", BACKEND_VARIABLE
    if value not in BACKENDS:
        removed = " (the numpy step was removed: the kernels are the one implementation)"
        raise ValueError(
            f"{source} must be one of {BACKENDS}, got {value!r}"
            + (removed if value in ("numpy", "auto") else "")
        )
    return value


def _finite(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array") from None
    if arr.ndim == 0 or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite array (no NaN or infinity), got {value!r}")
    return arr


def _load(value, name: str, shape: tuple[int, ...], check_finite: bool = True):
    """Validate an applied torque or force against the state shape (cheap in the good case)."""
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape {shape}") from None
    # A single 3-vector always broadcasts (the common case, spared broadcast_shapes' cost).
    if arr.shape != shape and arr.shape != shape[-1:]:
        try:
            ok = np.broadcast_shapes(arr.shape, shape) == shape
        except ValueError:
            ok = False
        if not ok or arr.ndim == 0:
            raise ValueError(f"{name} must broadcast to shape {shape}, got {arr.shape}")
    if check_finite and not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or infinity")
    return arr


def _steps(value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"steps must be a positive int, got {value!r}")
    if value < 1:
        raise ValueError(f"steps must be a positive int, got {value!r}")
    return int(value)
