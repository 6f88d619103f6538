"""Force stages. A scene gets only the terms it was given (a free body in space gets none).

Each term is a stage (``rigid_env.sim.pipeline.Stage``) that names its element kernel
(``compiled/forces.py``: the wrench per body, and for a velocity-dependent term its damping
matrix, which the symmetric splitting kicks solve with); ``velocity_dependent`` says whether
its wrench depends on (v, ω), which picks the integrators' damped kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Model


@dataclass(frozen=True)
class ForceTerm:
    """One force term of a scene: its stage name, and whether it depends on (v, ω)."""

    name: str
    velocity_dependent: bool


def build(model: Model) -> tuple[ForceTerm, ...]:
    """The force stages a model needs, in order: gravity (m g), damping (ṗ = −γ_v p,
    L̇ = −γ_ω L), springs (the force at the attachment point, torque (R r) × F)."""
    stages: list[ForceTerm] = []
    if model.gravity is not None and np.any(model.gravity):
        stages.append(ForceTerm("gravity", False))
    if model.linear_damping or model.angular_damping:
        stages.append(ForceTerm("damping", True))
    if model.springs:
        stages.append(ForceTerm("springs", any(sp.damping for sp in model.springs)))
    return tuple(stages)
