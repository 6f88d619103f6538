"""Integrators by name: one :class:`~.common.Integrator` record each, in ``RECORDS``.

| name            | order | torque-free body keeps            | cost / step         | fails where            |
|-----------------|-------|-----------------------------------|---------------------|------------------------|
| `euler`         | 1     | world L exactly; energy drifts    | matrix + repair     | energy drift ∝ Δt      |
| `euler_quat`    | 1     | world L exactly; energy grows     | cheapest            | as `euler`             |
| `rk4`           | 4     | nothing exactly; drift O(Δt⁴)     | 4 force evaluations | long runs, stiff terms |
| `splitting`     | 2     | world L exactly; energy bounded   | 5 axis rotations    | phase error O(Δt²)     |
| `splitting4`    | 4     | as `splitting`                    | 3 × `splitting`     | large ω Δt             |
| `implicit_gyro` | 1     | never blows up; loses energy      | one 3×3 solve       | damps fast spin        |
| `implicit`      | 1     | stiff springs bounded (any k Δt²) | one 6×6 solve/body  | damps resolved springs |

Semi-implicit integrators (``integrate_velocity`` then ``integrate_position``) take contacts
between their two parts: `euler`, `euler_quat`, `implicit_gyro`, `implicit`. Explicit
symplectic Euler on a spring of natural frequency ω_n diverges once ω_n Δt > 2; `implicit`
does not.

Adding an integrator: write a module that defines its step parts and ``RECORDS = (record,)``,
and add the module to ``_MODULES`` below; every table derives from ``RECORDS``.
"""

from __future__ import annotations

from . import euler, implicit, implicit_gyro, rk4, splitting
from .common import INTEGRATE, POSITION, VELOCITY, Integrator

_MODULES = (euler, rk4, splitting, implicit_gyro, implicit)

RECORDS: dict[str, Integrator] = {r.name: r for m in _MODULES for r in m.RECORDS}
ORDERS: dict[str, int] = {name: r.order for name, r in RECORDS.items()}
CONTACT_CAPABLE: tuple[str, ...] = tuple(n for n, r in RECORDS.items() if r.contact_capable)

__all__ = [
    "CONTACT_CAPABLE",
    "INTEGRATE",
    "Integrator",
    "ORDERS",
    "POSITION",
    "RECORDS",
    "VELOCITY",
]
