"""Integrators by name. Each is ``step(model, state, dt, forces, force, torque) -> State``.

| name            | order | torque-free body keeps            | cost / step         | fails where            |
|-----------------|-------|-----------------------------------|---------------------|------------------------|
| `euler`         | 1     | world L exactly; energy grows     | matrix + repair     | energy drift ∝ Δt      |
| `euler_quat`    | 1     | world L exactly; energy grows     | cheapest            | as `euler`             |
| `rk4`           | 4     | nothing exactly; drift O(Δt⁴)     | 4 force evaluations | long runs, stiff terms |
| `splitting`     | 2     | world L exactly; energy bounded   | 5 axis rotations    | phase error O(Δt²)     |
| `splitting4`    | 4     | as `splitting`                    | 3 × `splitting`     | large ω Δt             |
| `implicit_gyro` | 1     | never blows up; loses energy      | one 3×3 solve       | damps fast spin        |
| `implicit`      | 1     | stiff springs bounded (any k Δt²) | one 6×6 solve/body  | damps resolved springs |

Contacts (``sim.contacts``) need a semi-implicit step (positions drift with the final velocity):
`euler`, `euler_quat`, `implicit_gyro`, `implicit`. Explicit symplectic Euler on a spring of
natural frequency ω_n diverges once ω_n Δt > 2; `implicit` does not.
"""

from __future__ import annotations

from .euler import euler, euler_quat
from .exact import exact, exact4
from .implicit import implicit
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
    "implicit": implicit,
    "exact": exact,
    "exact4": exact4,
}
