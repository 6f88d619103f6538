"""The integrator record and the pieces integrators share.

Each integrator is one :class:`Integrator` record, defined next to its code in its own module:
its name, the stage parts it contributes to the step pipeline, its order and its geometric
properties. Everything else (``sim.INTEGRATORS``, the contact check, the bench's theoretical
orders, the tests' tables) derives from the records in ``integrators.RECORDS``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..pipeline import FunctionStage, StepContext
from ..rotation import quat_to_matrix

VELOCITY, POSITION, INTEGRATE = "integrate_velocity", "integrate_position", "integrate"

Part = Callable[[StepContext], None]


@dataclass(frozen=True)
class Integrator:
    """One integrator.

    ``parts`` are ``(stage name, fn(ctx))`` pairs in step order: either one ``"integrate"``
    part (the whole step), or ``"integrate_velocity"`` then ``"integrate_position"`` for a
    semi-implicit method (forces → v, ω; then v, ω → x, q), between which contact stages run.
    ``order`` is the global order of accuracy on smooth problems; ``symplectic`` whether the
    map is symplectic (bounded energy error, no drift).
    """

    name: str
    parts: tuple[tuple[str, Part], ...]
    order: int
    symplectic: bool
    summary: str = ""

    def __post_init__(self):
        names = tuple(name for name, _ in self.parts)
        if names not in ((INTEGRATE,), (VELOCITY, POSITION)):
            raise ValueError(
                f"integrator {self.name}: parts must be {INTEGRATE!r} or "
                f"({VELOCITY!r}, {POSITION!r}), got {names}"
            )

    @property
    def semi_implicit(self) -> bool:
        """Velocities are updated first, then positions drift with the new velocities."""
        return self.parts[0][0] == VELOCITY

    @property
    def contact_capable(self) -> bool:
        """Contacts need the velocity/position split: they act between the two parts."""
        return self.semi_implicit

    def stages(self) -> tuple[FunctionStage, ...]:
        """Fresh stage objects for one scene's pipeline."""
        return tuple(FunctionStage(name, fn) for name, fn in self.parts)


def kick(velocity, dt, inverse, load):
    """``velocity + dt · inverse · load``, or ``velocity`` when nothing acts."""
    if load is None:
        return velocity
    return velocity + dt * inverse * load


def translate(ctx: StepContext) -> None:
    """The position update of x: ``x ← x + Δt v`` plus any contact displacement."""
    x = ctx.x + ctx.dt * ctx.v
    if ctx.displacement is not None:
        x = x + ctx.displacement
    ctx.x = x


def start_rotation(ctx: StepContext) -> np.ndarray:
    """R(q) at the start of the step, computed once per step and shared by the parts."""
    rot = ctx.cache.get("rotation")
    if rot is None:
        rot = ctx.cache["rotation"] = quat_to_matrix(ctx.q)
    return rot


def align_sign(q_new: np.ndarray, q_old: np.ndarray) -> np.ndarray:
    """Pick the sign of ``q_new`` nearest ``q_old`` so trajectories are continuous (q ≡ −q)."""
    return q_new * np.where(np.sum(q_new * q_old, axis=-1, keepdims=True) < 0, -1.0, 1.0)
