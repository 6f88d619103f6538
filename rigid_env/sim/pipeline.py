"""The step pipeline: one mutable context per step, run through an ordered tuple of stages.

``Scene.step(state, torque, force, body_torque=, steps=)`` validates its input, builds a
:class:`StepContext`, runs ``scene.pipeline`` over it (every stage in order), and returns the
context's arrays as a new :class:`~rigid_env.sim.state.State` (with ``steps=k``, k times, each
step's context built from the last one's result). ``scene.stages`` is ``tuple(s.name for s in
scene.pipeline)``: what is listed runs, nothing else does.

The stage protocol (:class:`Stage`)
-----------------------------------
A stage is any object with a ``name: str`` and ``__call__(ctx: StepContext) -> None``. It reads
and writes the context's fields; it returns nothing. Stages may rebind a field to a new array
or write into it in place: the context's state arrays are the step's own fresh copies, never
the caller's (a step's output never shares memory with its input).

The context (:class:`StepContext`), all arrays batch-first, ``(*batch, n_bodies, 3|4)``:

``model``, ``dt``
    the scene's static model and time step.
``start``
    the :class:`State` passed to ``Scene.step`` (read only: the start-of-step values).
``x, q, v, w``
    position, orientation quaternion (x, y, z, w), linear and angular velocity (world frame),
    float64, C-contiguous, owned by the step. They start as copies of ``start`` and end as
    the returned state.
``applied_force, applied_torque``
    the validated actuation (``None`` or arrays broadcastable to ``x``'s shape), world frame.
``body_torque``
    the validated body-frame torque (``None`` or broadcastable to ``x``'s shape): it turns with
    the body, so every evaluation of the wrench at an orientation q adds ``R(q) body_torque``.
``force, torque``
    accumulators of the total wrench on each body at the start of the step: they start as the
    applied loads (``None`` = nothing acts, which lets a free body skip the arithmetic), plus
    the body torque at the start orientation (added by ``Scene.step`` once it has
    renormalised ``q``), and each force stage adds its term with :meth:`StepContext.add_wrench`.
``forces``
    the scene's force stages, so an integrator can re-evaluate the wrench at its own
    intermediate states with :meth:`StepContext.wrench_at` (RK4 stages, splitting half steps).
``contacts``
    the slot for contact data: detection stages write it, the solve stage reads it (its
    content is the contact stages' business; ``None`` when nothing was detected).
``displacement``
    ``None`` or a translation ``(*batch, n, 3)`` that the position update adds to
    ``x + Δt v`` (a contact solve's penetration correction, which changes no velocity).
``report``
    a dict of per-step facts that the scene exposes afterwards as ``scene.report`` (e.g. a
    contact solve that stopped at its iteration cap says so there).
``cache``
    a dict for values one stage computes for a later stage of the same owner (e.g. the
    start-of-step rotation matrix the integrator's two parts share); keys are the owner's.
``warm``
    what a stage hands to the same stage of the next step (the contact solve's impulses when
    ``SolverSettings.warm_start``): in a call's first step what the state passed in carries
    (``State.contact_impulses``, else ``None``), then the previous step's; the state a call
    returns carries its last, so k calls are bit for bit one call of k steps.

Order of a step
---------------
Force stages (``gravity``, ``damping``, ``springs``) accumulate the wrench at the start state.
A semi-implicit integrator contributes two stages, ``integrate_velocity`` (forces → v, ω) and
``integrate_position`` (v, ω → x, q); contact stages (``collide_*``, ``solve_contacts``) sit
between them, so positions move once, with the contact-corrected velocities. Other integrators
(``rk4``, ``splitting``, ``splitting4``) are one ``integrate`` stage and cannot take contacts.

Backends and element kernels
----------------------------
The numpy stages run over the whole batch at once. A compiled backend may attach to a stage
object a per-element kernel of the same name and run the same stages per batch element in one
call: the context's flat, batch-first arrays are laid out for that (``reshape(-1, n, 3)``).

Timing
------
``Scene(..., timer=StageTimer())`` (or ``scene.timer = StageTimer()``) accumulates the wall
time of each stage by name, of the step's own input validation and output check, and of whole
steps; ``scene.timer = None`` (the default) times nothing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .model import Model
from .rotation import quat_rotate
from .state import State


@runtime_checkable
class Stage(Protocol):
    """One part of a step: ``stage(ctx)`` updates the context in place."""

    name: str

    def __call__(self, ctx: StepContext) -> None: ...


class StepContext:
    """One step's mutable working set (see the module docstring for each field)."""

    __slots__ = (
        "model",
        "dt",
        "start",
        "x",
        "q",
        "v",
        "w",
        "applied_force",
        "applied_torque",
        "body_torque",
        "force",
        "torque",
        "forces",
        "contacts",
        "displacement",
        "report",
        "cache",
        "warm",
    )

    def __init__(
        self,
        model: Model,
        dt: float,
        state: State,
        force: np.ndarray | None = None,
        torque: np.ndarray | None = None,
        forces: Sequence = (),
        body_torque: np.ndarray | None = None,
    ):
        self.model, self.dt, self.start = model, dt, state
        # Fresh float64 copies: stages may write in place without touching the caller's state.
        self.x = np.array(state.position, dtype=np.float64, order="C")
        self.q = np.array(state.orientation, dtype=np.float64, order="C")
        self.v = np.array(state.linear_velocity, dtype=np.float64, order="C")
        self.w = np.array(state.angular_velocity, dtype=np.float64, order="C")
        self.applied_force, self.applied_torque = force, torque
        self.body_torque = body_torque
        self.force, self.torque = force, torque
        self.forces = tuple(forces)
        self.contacts: Any = None
        self.displacement: np.ndarray | None = None
        self.report: dict[str, Any] = {}
        # Values one stage computes for a later one of the same integrator (e.g. the rotation
        # matrix at the start of the step); private to the stages that write them.
        self.cache: dict[str, Any] = {}
        # What the previous step left for this one (the contact solve's impulses with
        # ``SolverSettings.warm_start``: from the state passed in, in a call's first step).
        self.warm: Any = None

    def add_wrench(self, force: np.ndarray | None, torque: np.ndarray | None) -> None:
        """Add a term's (F, T) to the accumulators (``None`` = that component is zero)."""
        if force is not None:
            self.force = force if self.force is None else self.force + force
        if torque is not None:
            self.torque = torque if self.torque is None else self.torque + torque

    def wrench_at(self, x, q, v, w) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Applied loads plus every force term evaluated at (x, q, v, w): the world loads,
        then the body torque turned into the world by q, then the force terms."""
        force, torque = self.applied_force, self.applied_torque
        if self.body_torque is not None:
            turned = quat_rotate(q, self.body_torque)
            torque = turned if torque is None else torque + turned
        for term in self.forces:
            f, t = term.wrench(x, q, v, w)
            if f is not None:
                force = f if force is None else force + f
            if t is not None:
                torque = t if torque is None else torque + t
        return force, torque

    def state(self) -> State:
        return State(self.x, self.q, self.v, self.w)


class StageTimer:
    """Cumulative wall time (``time.perf_counter``) per stage name over the steps it watched.

    ``seconds[name]`` sums each stage's own calls; ``seconds["validate"]`` is ``Scene.step``'s
    input checks and context set-up, ``seconds["check"]`` its finiteness check and output.
    ``steps`` counts physics steps (a ``Scene.step(..., steps=k)`` call counts k).
    ``step_seconds`` is the wall time of whole ``Scene.step`` calls, measured by its own clock
    reads around them (so the parts can be checked against it: they are disjoint intervals
    inside it and their sum can only be smaller, by the loop's bookkeeping between them).
    """

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self.seconds: dict[str, float] = {}
        self.step_seconds = 0.0
        self.steps = 0

    def add(self, name: str, seconds: float) -> None:
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds

    def per_step(self) -> dict[str, float]:
        """Mean seconds per step of each part (empty before the first step)."""
        return {k: v / self.steps for k, v in self.seconds.items()} if self.steps else {}


def run(pipeline: Sequence[Stage], ctx: StepContext, timer: StageTimer | None = None) -> None:
    """Run the stages in order over ``ctx``; with a timer, time each call by the stage name."""
    if timer is None:
        for stage in pipeline:
            stage(ctx)
        return
    clock = time.perf_counter
    for stage in pipeline:
        start = clock()
        stage(ctx)
        timer.add(stage.name, clock() - start)


class FunctionStage:
    """A stage from a name and a function ``fn(ctx) -> None`` (e.g. an integrator's part)."""

    __slots__ = ("name", "fn")

    def __init__(self, name: str, fn):
        self.name, self.fn = name, fn

    def __call__(self, ctx: StepContext) -> None:
        self.fn(ctx)

    def __repr__(self) -> str:
        return f"<stage {self.name}>"
