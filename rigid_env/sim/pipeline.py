"""The step's composition: an ordered tuple of named stages, and the timer of whole steps.

``scene.pipeline`` lists what a step of the scene runs, in order, and ``scene.stages`` their
names (``tuple(s.name for s in scene.pipeline)``): what is listed runs, nothing else does. A
stage object names a stage and holds what its kernel factory reads (a contact stage its
layout and solver settings, a force term its velocity dependence); the compiled package maps
each name to its element kernel (``compiled/registry.py``) and the driver runs them per batch
element in one call (``compiled/driver.py``).

Order of a step
---------------
Force stages (``gravity``, ``damping``, ``springs``) accumulate the wrench at the start state.
A semi-implicit integrator contributes two stages, ``integrate_velocity`` (forces → v, ω) and
``integrate_position`` (v, ω → x, q); contact stages (``collide_*``, ``solve_contacts``) sit
between them, so positions move once, with the contact-corrected velocities. Other integrators
(``rk4``, ``splitting``, ``splitting4``, ``exact``, ``exact4``) are one ``integrate`` stage and
cannot take contacts.

Timing
------
``Scene(..., timer=StageTimer())`` (or ``scene.timer = StageTimer()``) accumulates the wall
time of the step's input validation, of the compiled call and of the output check, and of
whole steps; ``scene.timer = None`` (the default) times nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable


@runtime_checkable
class Stage(Protocol):
    """One part of a step, by name (its kernel is ``compiled.registry``'s of that name)."""

    name: str


@dataclass(frozen=True)
class NamedStage:
    """A stage that is its name only (an integrator's part)."""

    name: str


class StageTimer:
    """Cumulative wall time (``time.perf_counter``) per part of a step over the steps it watched.

    ``seconds["validate"]`` is ``Scene.step``'s input checks, ``seconds["compiled"]`` the
    compiled call, ``seconds["check"]`` its finiteness check and output. ``steps`` counts
    physics steps (a ``Scene.step(..., steps=k)`` call counts k). ``step_seconds`` is the wall
    time of whole ``Scene.step`` calls, measured by its own clock reads around them (so the
    parts can be checked against it: they are disjoint intervals inside it and their sum can
    only be smaller, by the bookkeeping between them).
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
