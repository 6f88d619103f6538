"""Scene factories the benchmarks share (what ``rigid_env.sim`` does not already provide).

Every factory takes ``(integrator, dt)`` first so the benchmarks can sweep both.
"""

from __future__ import annotations

import numpy as np

from rigid_env import sim

LANDING_PREROLL_S = 1.0  # landing batches are timed after this long: boxes on the ground

# The tumbling box: distinct principal moments (0.0867, 0.0667, 0.0333) kg m²; body y is the
# intermediate axis. Spun almost about it, it flips every few seconds (Dzhanibekov effect).
BOX_HALF_EXTENTS = (0.1, 0.2, 0.3)
BOX_MASS = 2.0
DZHANIBEKOV_OMEGA = (0.05, 4.0, 0.05)  # rad/s, world = body axes at t = 0
TUMBLE_OMEGA = (0.3, 3.0, 0.6)  # a generic tumble for speed runs


def box() -> sim.Body:
    return sim.Body.box(BOX_HALF_EXTENTS, BOX_MASS)


def free_body(integrator: str, dt: float, body: sim.Body | None = None) -> sim.Scene:
    """One body in space: no gravity, no ground, ``stages == ("integrate",)``."""
    return sim.Scene([box() if body is None else body], dt, integrator=integrator)


def symmetric_body() -> sim.Body:
    """A square-section box: I_x = I_y ≠ I_z, body z the symmetry axis."""
    return sim.Body.box((0.1, 0.1, 0.3), 1.0)


def needle(ratio: float, mass: float = 1.0, length: float = 1.0) -> sim.Body:
    """A square box whose axial/transverse inertia ratio is ``ratio`` (< 1), long along z.

    For half extents (a, a, c): I_z = 2 m a²/3, I_x = m (a² + c²)/3, so the ratio is
    2a²/(a² + c²); solving gives a = c √(r / (2 − r)).
    """
    c = 0.5 * length
    a = c * np.sqrt(ratio / (2.0 - ratio))
    return sim.Body.box((a, a, c), mass)


def spring(
    integrator: str,
    dt: float,
    stiffness: float = 40.0,
    damping: float = 0.4,
    mass: float = 1.0,
) -> sim.Scene:
    """A sphere on a zero-rest-length spring to the origin: m ẍ = −k x − c ẋ (no torque)."""
    ball = sim.Body.sphere(0.05, mass)
    return sim.Scene(
        [ball],
        dt,
        integrator=integrator,
        springs=[sim.Spring(0, (0.0, 0.0, 0.0), stiffness, damping)],
    )


def stiff_spring(integrator: str, dt: float, k_dt2_over_m: float, mass: float = 1.0) -> sim.Scene:
    """An undamped spring whose stiffness makes ``k Δt² / m`` equal the given number."""
    return spring(integrator, dt, stiffness=k_dt2_over_m * mass / dt**2, damping=0.0, mass=mass)
