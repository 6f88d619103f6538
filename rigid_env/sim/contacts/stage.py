"""The contact response of one semi-implicit step: impacts, then the inelastic solve.

Between the velocity update (forces: u₀ → u₁) and the position update (x₁ = x₀ + Δt u) of a
semi-implicit step, for the batch elements with a contact within reach:

1. ``assembly``: detect at the step's start (x₀, q₀), build the rows and the Delassus matrix.
2. ``restitution``: impacts in time order (Newton's law, energy guard).
3. ``solve``: the inelastic problem with Coulomb friction, solved to the stated tolerance.
   Normal target ``v_n ≥ −d/Δt`` for a gap d > 0 (a speculative contact: the body may close
   the gap this step, no more — no tunnelling; Catto, "Contact Manifolds", 2014 / Box2D v3)
   and ``v_n ≥ 0`` for d ≤ 0. At its solution the impulses remove kinetic energy.
4. ``projection``: after the position update, penetration left by the linearisation (rotation
   over the step) is removed by moving bodies, not by velocity.

Each call records a :class:`ContactReport`; a solve that stopped at a cap instead of
converging also raises a :class:`ContactSolverWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .assembly import Layout, assemble, scaled_velocity
from .restitution import resolve_impacts
from .solve import SolverSettings, dissipative, gauss_seidel
from .warm_start import active_set_start


class ContactSolverWarning(RuntimeWarning):
    """A contact solve stopped at its iteration or impact cap instead of converging."""


@dataclass(frozen=True)
class ContactReport:
    """What the contact stages did in one step.

    ``engaged``: batch elements with a contact within reach (the others skip the solve);
    ``iterations``: the most Gauss–Seidel sweeps any element needed; ``impacts``: the most
    impact events of any element; ``capped``: elements whose solve stopped at
    ``max_iterations`` or ``max_impacts`` instead of converging (0 in a converged step);
    ``residual_tolerance``: the relative tolerance the converged elements met.
    """

    engaged: int = 0
    iterations: int = 0
    impacts: int = 0
    capped: int = 0
    residual_tolerance: float = 0.0

    @property
    def converged(self) -> bool:
        return self.capped == 0


class ContactStage:
    """``respond(x0, q0, u0, u1) -> u``: velocities after the contact response, (N, n, 6)."""

    def __init__(self, model, dt, ground=None, pairs=None, settings=None):
        if settings is None:
            settings = SolverSettings()
        if not isinstance(settings, SolverSettings):
            raise ValueError(f"solver must be a SolverSettings, got {settings!r}")
        self.model, self.dt, self.settings = model, dt, settings
        self.ground, self.pairs = ground, pairs
        self.layout = Layout(model, ground, pairs)
        self.last_report = ContactReport(residual_tolerance=settings.tolerance)

    def engaged(self, x0, q0, u1):
        """Elements (N,) with a contact the step's velocities could reach."""
        lay = self.layout
        arm_a, arm_b, normal, gap = lay.detect(x0, q0)
        vn1 = np.sum(lay.relative_velocity(u1, arm_a, arm_b) * normal, axis=-1)
        return np.any(gap + self.dt * np.minimum(vn1, 0.0) < 0, axis=-1)

    def respond(self, x0, q0, u0, u1):
        """Velocities (N, n, 6) after impacts and the inelastic solve; records the report."""
        engaged = self.engaged(x0, q0, u1)
        report = ContactReport(residual_tolerance=self.settings.tolerance)
        if engaged.any():
            sub = None if engaged.all() else np.flatnonzero(engaged)
            pick = (lambda a: a) if sub is None else (lambda a: a[sub])
            u_sub, report = self._respond(pick(x0), pick(q0), pick(u0), pick(u1))
            if sub is None:
                u1 = u_sub
            else:
                u1 = np.array(u1)
                u1[sub] = u_sub
            report = ContactReport(int(engaged.sum()), *report, self.settings.tolerance)
        self.last_report = report
        if report.capped:
            warnings.warn(
                f"contact solve stopped at its cap in {report.capped} batch element(s) "
                f"(max_iterations={self.settings.max_iterations}, "
                f"max_impacts={self.settings.max_impacts}, "
                f"tolerance={self.settings.tolerance:g}); raise the cap or the tolerance",
                ContactSolverWarning,
                stacklevel=3,
            )
        return u1

    def _respond(self, x0, q0, u0, u1):
        lay, dt, settings = self.layout, self.dt, self.settings
        rows = assemble(lay, x0, q0, u1)
        u, impulse, events, impact_cap = resolve_impacts(lay, rows, u0, u1, dt, settings)
        free = rows.velocity(u, lay)
        target = np.where(rows.gap > 0, -rows.gap / dt, 0.0)
        short = target - free[..., 0]
        # Contacts that can carry load: the violated ones and those the step's largest velocity
        # correction could close (resting contacts whose v_n is rounding noise).
        reach = dt * np.max(np.maximum(short, 0.0), axis=-1, keepdims=True)
        reachable = (short > 0) | (rows.gap <= reach)
        start = active_set_start(lay, short, rows.delassus, free[..., 1:], reachable, impulse)
        lam, sweeps, converged = gauss_seidel(
            rows.delassus, free, target, lay.mu, start, settings, extra=impulse
        )
        if not converged.all():
            bad = np.flatnonzero(~converged)
            sub = rows.take(bad)
            z = scaled_velocity(lay, u[bad], sub.scale)[..., 0]
            dz = (lam[bad].reshape(len(bad), 1, -1) @ sub.jt)[:, 0]
            lam[bad], _ = dissipative(lam[bad], dz, z)
        u = u + rows.velocity_change(lam, lay)
        capped = int(np.sum(~converged | impact_cap))
        return u, (int(sweeps.max()), int(events.max()), capped)

    def project(self, x0, q0, x, q, u):
        """Positions (N, n, 3) with the penetration the linearised step left removed: each body
        on the ground is lifted by its deepest end-of-step overlap; each body pair is pushed
        apart along its normal by its deepest overlap, split by mass (momentum unchanged)."""
        lay = self.layout
        arm_a, arm_b, normal, gap = lay.detect(x, q)
        depth = -gap
        if not np.any(depth > 0):
            return x
        x = np.array(x)
        if lay.n_ground:
            g = len(lay.ground_bodies)
            dg = depth[..., : lay.n_ground].reshape(len(x), g, lay.k)
            lift = np.maximum(np.max(dg, axis=-1), 0.0)  # (N, G)
            x[..., lay.ground_bodies, 2] += lift
        if lay.c > lay.n_ground:
            pushes, offset = [], lay.n_ground
            for pa, _, _, slots in self.pairs.groups:
                sl = slice(offset, offset + len(pa) * slots)
                offset = sl.stop
                d = depth[..., sl].reshape(len(x), len(pa), slots)
                n = normal[..., sl, :][..., ::slots, :]
                pushes.append(np.maximum(np.max(d, axis=-1), 0.0)[..., None] * n)
            push = pushes[0] if len(pushes) == 1 else np.concatenate(pushes, axis=-2)
            x += np.einsum("pn,...pk->...nk", lay.pair_share, push)
        return x


__all__ = ["ContactReport", "ContactSolverWarning", "ContactStage"]
