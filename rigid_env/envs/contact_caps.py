"""Capped contact solves inside an environment: counted per env, warned once, in plain words.

The simulator warns (``sim.ContactSolverWarning``) on every step whose contact solve stopped at
its iteration or impact cap. Inside an env that is rare and harmless, but printed once per
process it reads like a fault. A contact env steps its scene through :func:`step_quietly`,
counts each env's capped action periods in ``info["contact_capped"]`` (per episode), and warns
once per env instance with :data:`MESSAGE`, a :class:`ContactCapWarning`.
"""

from __future__ import annotations

import sys
import warnings
from typing import Any

import numpy as np

from .. import sim


class ContactCapWarning(UserWarning):
    """An env's contact solve stopped at its cap (once per env; see :data:`MESSAGE`)."""


MESSAGE = (
    "{env}: a contact solve stopped at its cap (SolverSettings.max_iterations or max_impacts) "
    "instead of converging to its tolerance. That physics step keeps the solver's last "
    "iterate: its contact impulses meet the friction and no-penetration conditions only "
    "approximately, and the step still adds no energy. With the default settings this is rare "
    "(well under 1 % of the physics steps in contact) and harmless for training; "
    "info['contact_capped'] counts such action periods per episode, and only a large count in "
    "many episodes calls for a larger max_iterations. Warned once per env."
)


def step_quietly(scene: sim.Scene, state: sim.State, **step: Any) -> sim.State:
    """``scene.step(state, **step)`` without its ``ContactSolverWarning`` (the env counts caps
    from the returned state's ``report`` instead)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        return scene.step(state, **step)


def capped_mask(report: Any) -> np.ndarray | None:
    """Per env, whether the last step call's contact solve stopped at a cap, or ``None`` if
    none did (the common case, and scenes without contacts)."""
    if report is None or not report.capped:
        return None
    return report.capped_mask


def warn_capped(env: str) -> None:
    """Warn with :data:`MESSAGE`, attributed to the first caller outside rigid_env and
    Gymnasium (the user's ``step`` call, through any wrappers)."""
    frame, level = sys._getframe(0), 1
    while frame.f_back is not None and frame.f_globals.get("__name__", "").startswith(INTERNAL):
        frame, level = frame.f_back, level + 1
    warnings.warn(MESSAGE.format(env=env), ContactCapWarning, stacklevel=level)


INTERNAL = ("rigid_env.", "gymnasium.")  # the packages between a user's step and the warning
