"""Stage name → compiled kernel factories (see the package docstring for the conventions)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .layout import GROUND_WIDTH


@dataclass(frozen=True)
class Kernel:
    """An element kernel ``module.name(e, st, d)`` and its data ``d``.

    ``template``: the function is undecorated source calling ``wrench`` (an integrator), copied
    into the generated driver. ``slots``: contact slots it writes (detection), per element;
    ``width``: the columns of ``layout.CONTACT_COLUMNS`` it uses (a ground scene's are fewer
    than a scene's with body–body contacts: the step zeroes every column of every slot).
    ``report``: for a kernel that writes ``report`` columns, ``report(columns, counts) -> dict``
    turns the step's (N, REPORT_WIDTH) array into entries of ``scene.report`` ; ``counts`` is None, or for a call of several steps the
    per-step counts of engaged, capped and warm-started elements ((steps, 3),
    ``Driver.__call__``).
    """

    module: str
    name: str
    data: tuple = ()
    template: bool = False
    slots: int = 0
    width: int = GROUND_WIDTH
    report: Callable[[np.ndarray, np.ndarray | None], dict] | None = None


@dataclass(frozen=True)
class ForceKernel:
    """A body-level force term ``module.name(b, x, q, v, w, fd) -> (f, t)`` and its data.

    ``damping``: for a velocity-dependent term, the name of ``module.damping(b, x, q, fd, out)``
    adding its 6×6 damping matrix C (``(F, T) = (F, T)|ᵤ₌₀ − C u``, u = (v, ω)) into ``out``.
    """

    module: str
    name: str
    data: tuple = field(default=())
    damping: str | None = None


Factory = Callable[[object], "Kernel | tuple[Kernel, ...] | None"]
ForceFactory = Callable[[object], "ForceKernel | None"]

STAGES: dict[str, Factory] = {}
FORCES: dict[str, ForceFactory] = {}


def register(name: str):
    """Decorator: ``factory(scene)`` gives the kernel(s) of stage ``name``, or None (numpy)."""

    def deco(factory):
        STAGES[name] = factory
        return factory

    return deco


def register_force(name: str):
    """Decorator: ``factory(scene)`` gives the force kernel of term ``name``, or None."""

    def deco(factory):
        FORCES[name] = factory
        return factory

    return deco


INTEGRATORS: dict[str, str] = {}


def register_integrator(name: str, module: str) -> None:
    """Integrator ``name``'s templates live in ``module``: ``name`` (stage ``integrate``), or
    ``name_velocity`` and ``name_position`` (stages ``integrate_velocity`` / ``_position``)."""
    INTEGRATORS[name] = module
