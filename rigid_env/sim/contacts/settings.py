"""The contact solve's settings (``SolverSettings``): its caps, tolerance, start and warm start.

The solve itself is ``compiled/contact_solve.py`` (its module docstring states the problem and
the method).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

MAX_ITERATIONS = 500
TOLERANCE = 1e-12
MAX_IMPACTS = 32
STARTS = ("active_set", "particle")
# Sweeps per round between Newton polishes: 10 was faster and capped fewer solves than 30 in
# the BoxLanding rollout (``docs/performance.md``).
NEWTON_AFTER = 10
NEWTON_STEPS = 50  # Newton steps at most per solve


@dataclass(frozen=True)
class SolverSettings:
    """Settings of the contact solve.

    Parameters
    ----------
    max_iterations : Gauss–Seidel sweeps at most per solve (≥ 1). A solve that stops here
        instead of at the tolerance is reported (``Scene``'s contact report and a
        :class:`ContactSolverWarning`).
    tolerance : relative stopping tolerance in (0, 1): a solve has converged when one sweep
        changes no contact velocity by more than ``tolerance`` × the element's largest free
        contact velocity (m/s). The default 1e-12 sits a few hundred roundings above machine
        precision.
    max_impacts : impacts resolved in time order within one step per batch element (≥ 1); a
        step with more (a long Newton's cradle at a large Δt) is reported like an iteration cap.
    start : ``"active_set"`` (default): when the particle start is not already the solution,
        Gauss–Seidel starts from the active-set direct solve (``compiled.contact_starts``), which is exact
        for resting and sticking contacts; ``"particle"``: always from the particle start
        (Gauss–Seidel alone; slower to converge on an incline or a resting polyhedron, see
        ``python -m rigid_env.bench.contact_solve``).
    newton_after : Gauss–Seidel sweeps (≥ 1) per round: a solve not converged after a round
        is polished by semi-smooth Newton steps (``compiled.contact_newton``) and the next round
        goes on from Newton's answer, up to ``max_iterations`` sweeps in all.
    newton_steps : Newton steps at most per solve, over all rounds (≥ 0; 0: Gauss–Seidel
        alone); a jump past a change of contact mode (``compiled.contact_newton``) counts as one.
    warm_start : False (default): every step's solve starts as above. True: a step whose
        previous step converged with contacts engaged starts from that step's impulses
        instead (contact slots are fixed per vertex, so slot i is the same contact) and probes
        them with one sweep instead of the particle start; with the active-set start, a probe
        that fails goes on as a cold solve, so no more solves reach the cap (with
        ``"particle"`` it goes on from the probed impulses). The state a step returns carries
        the impulses (``State.contact_impulses``), so the next call starts warm too and k
        calls are bit for bit one call of k steps; a state that carries none (built by hand)
        starts cold. The answer meets the same tolerance as a cold start, not its bits (where
        the friction problem has several solutions, not even the same solution). On
        BoxLanding's rollout states (8 steps per call) it makes the physics ~1.4× cheaper:
        the previous step's impulses are mostly already the answer.
    """

    max_iterations: int = MAX_ITERATIONS
    tolerance: float = TOLERANCE
    max_impacts: int = MAX_IMPACTS
    start: str = "active_set"
    newton_after: int = NEWTON_AFTER
    newton_steps: int = NEWTON_STEPS
    warm_start: bool = False

    def __post_init__(self):
        if not isinstance(self.warm_start, (bool, np.bool_)):
            raise ValueError(f"warm_start must be True or False, got {self.warm_start!r}")
        object.__setattr__(self, "warm_start", bool(self.warm_start))
        for name, low in (
            ("max_iterations", 1),
            ("max_impacts", 1),
            ("newton_after", 1),
            ("newton_steps", 0),
        ):
            value = getattr(self, name)
            try:
                as_int = operator.index(value)
            except TypeError:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}") from None
            if isinstance(value, bool) or as_int < low:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
            object.__setattr__(self, name, int(as_int))
        try:
            tol = float(self.tolerance)
        except (TypeError, ValueError):
            raise ValueError(
                f"tolerance must be a number in (0, 1), got {self.tolerance!r}"
            ) from None
        if not 0 < tol < 1:
            raise ValueError(f"tolerance must be a number in (0, 1), got {self.tolerance!r}")
        object.__setattr__(self, "tolerance", tol)
        if self.start not in STARTS:
            raise ValueError(f"start must be one of {STARTS}, got {self.start!r}")
