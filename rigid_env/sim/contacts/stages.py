"""The contact stages of a step (``rigid_env.sim.pipeline``), by name, with what their kernels
read, and the step's contact report.

Between a semi-implicit integrator's ``integrate_velocity`` and ``integrate_position``:

* ``collide_ground`` / ``collide_pairs`` detect at the start-of-step positions
  (``compiled/ground.py``, ``compiled/contact_pairs.py``);
* ``assemble_contacts`` finds whether the element has a contact within reach this step and
  builds its rows (``compiled/contact_assembly.py``); an element without one skips every later
  contact stage;
* ``restitute`` resolves the step's impacts in time order (``compiled/contact_impacts.py``);
* ``solve_contacts`` solves the inelastic problem with friction to the stated tolerance
  (``compiled/contact_solve.py``) and writes the report (a :class:`ContactReport`);
* ``limit_energy`` scales the velocities down if the step would end with more energy than it
  started with plus the work of the applied loads along its motion, and hands the impacts'
  path to the position update (``compiled/contact_energy.py``);

and after ``integrate_position``:

* ``separate_contacts`` removes the penetration the linearised step left (rotation over the
  step) by moving bodies, pays the potential energy of the lift out of the kinetic energy, and
  reports the energy the contacts removed (``ContactReport.energy_removed``).

A solve that stops at ``max_iterations`` or ``max_impacts`` instead of converging is counted in
the report's ``capped`` and raises a :class:`ContactSolverWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .assembly import Layout
from .settings import SolverSettings

REPORT_KEY = "contacts"
MAX_HALVINGS = 30  # of the energy guard's velocity factor; then it is 0


class ContactSolverWarning(RuntimeWarning):
    """A contact solve stopped at its iteration or impact cap instead of converging."""


@dataclass(frozen=True, eq=False)
class ContactReport:
    """What the contact stages did in one step (``scene.report["contacts"]``).

    ``engaged``: batch elements with a contact within reach (the others skip the solve);
    ``iterations``: the most Gauss–Seidel sweeps any element needed; ``newton``: the most
    Newton steps of the solve's polish any element took (``SolverSettings.newton_after``);
    ``impacts``: the most
    impact events of any element; ``capped``: elements whose solve stopped at
    ``max_iterations`` or ``max_impacts`` instead of converging (0 in a converged step);
    ``warm_started``: elements whose solve started from the previous step's impulses
    (``SolverSettings.warm_start``, which the state carries: ``State.contact_impulses``);
    ``tolerance``: the relative tolerance the converged elements met; ``unpaid_energy``: the
    largest energy excess (J) the energy guard could not take out of the kinetic energy (0
    in every step measured so far; see ``energy``); ``touched``: per batch element (flattened,
    (N,) bool) whether a contact carried an impulse this step — a touch sensor that also sees
    a bounce which began and ended within the step (the positions at the step's ends may both
    be clear of the ground); ``energy_removed``: per batch element (flattened, (N,) float), the
    energy (J) the contacts took out of the step, ``energy``'s ``removed`` (0 for an element with
    no contact within reach; over a call of several steps, the sum over them); ``capped_mask``:
    per batch element (flattened, (N,) bool) whether its solve stopped at a cap this step
    (``capped`` counts them).
    """

    engaged: int = 0
    iterations: int = 0
    impacts: int = 0
    newton: int = 0
    capped: int = 0
    warm_started: int = 0
    tolerance: float = 0.0
    unpaid_energy: float = 0.0
    touched: np.ndarray | None = None
    energy_removed: np.ndarray | None = field(default=None, metadata={"merge": "sum"})
    capped_mask: np.ndarray | None = None

    @property
    def converged(self) -> bool:
        return self.capped == 0


class CollideGround:
    name = "collide_ground"

    def __init__(self, ground):
        self.ground = ground


class CollidePairs:
    name = "collide_pairs"

    def __init__(self, pairs):
        self.pairs = pairs


class AssembleContacts:
    """Engaged or not (a gap the step's velocities could close), and the rows."""

    name = "assemble_contacts"

    def __init__(self, layout: Layout):
        self.layout = layout


class Restitute:
    """Impacts of the step in time order."""

    name = "restitute"

    def __init__(self, layout: Layout, settings: SolverSettings):
        self.layout, self.settings = layout, settings


class SolveContacts:
    """The inelastic solve with friction and the step's contact report."""

    name = "solve_contacts"

    def __init__(self, layout: Layout, settings: SolverSettings):
        self.layout, self.settings = layout, settings


def warn_capped(stacklevel: int) -> None:
    """The :class:`ContactSolverWarning` of a step with a capped solve."""
    warnings.warn(
        "a contact solve stopped at its cap (SolverSettings.max_iterations or "
        "max_impacts) instead of converging; scene.report['contacts'] counts the "
        "elements per step",
        ContactSolverWarning,
        stacklevel=stacklevel,
    )


class LimitEnergy:
    """Before the position update: the contacts add no energy, the loads do their full work."""

    name = "limit_energy"

    def __init__(self, layout: Layout):
        self.layout = layout


class SeparateContacts:
    """After the position update: remove what overlap is left and pay the potential energy of
    the lift out of the kinetic energy; then the step's ``energy_removed``."""

    name = "separate_contacts"

    def __init__(self, layout: Layout):
        self.layout = layout


__all__ = [
    "AssembleContacts",
    "CollideGround",
    "CollidePairs",
    "ContactReport",
    "ContactSolverWarning",
    "REPORT_KEY",
    "Restitute",
    "LimitEnergy",
    "SeparateContacts",
    "SolveContacts",
]
