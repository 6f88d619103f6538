"""Stage name → compiled kernel factories (see the package docstring for the conventions), and
the integrators, each picked at compile time by the type of its tag (``integrate``)."""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba.extending import overload

from .layout import GROUND_WIDTH


@dataclass(frozen=True)
class Kernel:
    """An element kernel ``module.name(e, st, d)`` and its data ``d``.

    ``tag``: for an integrator's part, the integrator's tag class (``register_integrator``).
    ``slots``: contact slots it writes (detection), per element; ``width``: the columns of
    ``layout.CONTACT_COLUMNS`` it uses (a ground scene's are fewer than a scene's with
    body–body contacts: the step zeroes every column of every slot). ``report``: for a kernel
    that writes ``report`` columns, ``report(columns, counts) -> dict`` turns the step's
    (N, REPORT_WIDTH) array into entries of ``scene.report``; ``counts`` is None, or for a
    call of several steps the per-step counts of engaged, capped and warm-started elements
    ((steps, 3), ``Driver.__call__``).
    """

    module: str
    name: str
    data: tuple = ()
    tag: type | None = None
    slots: int = 0
    width: int = GROUND_WIDTH
    report: Callable[[np.ndarray, np.ndarray | None], dict] | None = None


@dataclass(frozen=True)
class ForceKernel:
    """A body-level force term's data (``compiled.forces.wrench`` evaluates the term named
    ``name``, one of ``forces.TERMS``)."""

    name: str
    data: tuple = field(default=())


Factory = Callable[[object], "Kernel | tuple[Kernel, ...] | None"]
ForceFactory = Callable[[object], "ForceKernel | None"]

STAGES: dict[str, Factory] = {}
FORCES: dict[str, ForceFactory] = {}


def register(name: str):
    """Decorator: ``factory(scene)`` gives the kernel(s) of stage ``name``, or None."""

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


@dataclass(frozen=True)
class Integrator:
    """An integrator's element kernels: ``one`` for a one-part integrator (stage
    ``integrate``), or ``velocity`` and ``position`` (stages ``integrate_velocity`` /
    ``integrate_position``, the contact stages between them); ``tag`` the class of its tag."""

    tag: type
    one: Callable | None = None
    velocity: Callable | None = None
    position: Callable | None = None


# Variant name (an integrator, or ``<name>_damped`` for its kernel with velocity-dependent
# forces) → its kernels; and the same by tag class.
INTEGRATORS: dict[str, Integrator] = {}
_BY_TAG: dict[type, Integrator] = {}


def register_integrator(name: str, namespace: dict, one=None, velocity=None, position=None):
    """Integrator variant ``name`` runs ``one``, or ``velocity`` then ``position``. Its tag is
    a one-field namedtuple class of its own, bound in ``namespace`` (the kernels' module
    globals) under its name, so numba's cache can pickle the step's signature by reference and
    find the class again in a new process."""
    tag = namedtuple(f"Integrate_{name}", ["id"])  # noqa: PYI024 (a type per integrator)
    tag.__module__ = namespace["__name__"]
    namespace[tag.__name__] = tag
    record = Integrator(tag, one, velocity, position)
    INTEGRATORS[name] = record
    _BY_TAG[tag] = record


# --- the integrator a step runs, chosen by its tag's type ------------------------------------
# numba specialises the step for the tag's class: each overload below resolves to one
# integrator's kernels when the step compiles (nothing generated). The kernels are plain
# functions ``kernel(tag, e, st, d)``, each the implementation of its overload, compiled as a
# function of its own that the step calls with the step tuple by reference (``calls.as_ref``,
# a pointer: passed by value it would be 14 arrays of 11 words). Called rather than inlined
# (``inline="always"`` overloads): numba types an inlined overload twice, which made a new
# free composition's first compile 1.5-2.3 times as long, for a fraction of a microsecond per
# batch-1 step (``docs/performance.md`` has the measurement). Without numba's JIT the
# functions below look the kernels up and run them as Python.


def integrate(tag, e, st, d):
    """The whole step of the integrator (its one part, or both halves)."""
    parts = _BY_TAG[type(tag)]
    if parts.one is not None:
        parts.one(tag, e, st, d)
    else:
        parts.velocity(tag, e, st, d)
        parts.position(tag, e, st, d)


def integrate_velocity(tag, e, st, d):
    _BY_TAG[type(tag)].velocity(tag, e, st, d)


def integrate_position(tag, e, st, d):
    _BY_TAG[type(tag)].position(tag, e, st, d)


@overload(integrate)
def _integrate(tag, e, st, d):
    parts = _BY_TAG[tag.instance_class]
    if parts.one is not None:
        return parts.one
    # Both halves, inlined into this one function (numba inlines an ``inline="always"``
    # function's code where it is called, typing it once).
    velocity, position = _inlined(parts.velocity), _inlined(parts.position)

    def both(tag, e, st, d):
        velocity(tag, e, st, d)
        position(tag, e, st, d)

    return both


def _inlined(kernel):
    from .cache import njit

    return njit(error_model="numpy", inline="always")(kernel)


@overload(integrate_velocity)
def _integrate_velocity(tag, e, st, d):
    return _BY_TAG[tag.instance_class].velocity


@overload(integrate_position)
def _integrate_position(tag, e, st, d):
    return _BY_TAG[tag.instance_class].position
