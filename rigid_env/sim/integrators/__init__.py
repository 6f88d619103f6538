"""Integrators by name. Each is ``step(model, state, dt, forces, force, torque) -> State``.

| name            | order | conserves (torque-free)                  | cost / step        | fails where                       |
|-----------------|-------|------------------------------------------|--------------------|-----------------------------------|
| `euler`         | 1     | world L exactly; energy grows            | 1 matrix repair    | energy drift ∝ Δt; fast spin      |
| `euler_quat`    | 1     | world L exactly; energy grows            | cheapest           | as `euler`                        |
| `rk4`           | 4     | nothing exactly; drift O(Δt⁴)            | 4 force evaluations| drifts on long runs; stiff springs|
| `splitting`     | 2     | world L and |L| exactly; energy bounded  | 5 axis rotations   | phase error O(Δt²)                |
| `splitting4`    | 4     | as `splitting`                           | 3 × `splitting`    | unstable at very large ω Δt       |
| `implicit_gyro` | 1     | |L| decays slightly; never blows up      | one 3×3 solve      | damps fast spin (energy loss)     |
"""

from __future__ import annotations

from .euler import euler, euler_quat
from .implicit_gyro import implicit_gyro
from .rk4 import rk4
from .splitting import splitting, splitting4

REGISTRY = {
    "euler": euler,
    "euler_quat": euler_quat,
    "rk4": rk4,
    "splitting": splitting,
    "splitting4": splitting4,
    "implicit_gyro": implicit_gyro,
}
