"""The contact stages of the step pipeline (``rigid_env.sim.pipeline``).

Between a semi-implicit integrator's ``integrate_velocity`` and ``integrate_position``:

* ``collide_ground`` / ``collide_pairs`` detect at the start-of-step positions and put their
  hits in ``ctx.contacts`` (batch flattened to one axis, ``(N, n, ·)``);
* ``assemble_contacts`` picks the batch elements with a contact within reach this step and
  builds their rows (``assembly``); the other elements skip every later contact stage;
* ``restitute`` resolves the step's impacts in time order (``restitution``);
* ``solve_contacts`` solves the inelastic problem with friction to the stated tolerance
  (``solve``) and writes ``ctx.report["contacts"]`` (a :class:`ContactReport`);

and after ``integrate_position``:

* ``separate_contacts`` removes the penetration the linearised step left (rotation over the
  step) by moving bodies, which changes no velocity.

A solve that stops at ``max_iterations`` or ``max_impacts`` instead of converging is counted in
the report's ``capped`` and raises a :class:`ContactSolverWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .assembly import Layout, assemble
from .restitution import resolve_impacts
from .solve import SolverSettings, solve_inelastic

REPORT_KEY = "contacts"


class ContactSolverWarning(RuntimeWarning):
    """A contact solve stopped at its iteration or impact cap instead of converging."""


@dataclass(frozen=True)
class ContactReport:
    """What the contact stages did in one step (``scene.report["contacts"]``).

    ``engaged``: batch elements with a contact within reach (the others skip the solve);
    ``iterations``: the most Gauss–Seidel sweeps any element needed; ``impacts``: the most
    impact events of any element; ``capped``: elements whose solve stopped at
    ``max_iterations`` or ``max_impacts`` instead of converging (0 in a converged step);
    ``tolerance``: the relative tolerance the converged elements met.
    """

    engaged: int = 0
    iterations: int = 0
    impacts: int = 0
    capped: int = 0
    tolerance: float = 0.0

    @property
    def converged(self) -> bool:
        return self.capped == 0


def _flat(ctx):
    n = ctx.model.n_bodies
    return ctx.x.reshape(-1, n, 3), ctx.q.reshape(-1, n, 4)


def _hits(ctx) -> dict:
    if ctx.contacts is None:
        ctx.contacts = {}
    return ctx.contacts


def _velocities(ctx, state=None):
    """Generalised velocities (N, n, 6) of the context (or of a State)."""
    n = ctx.model.n_bodies
    v, w = (ctx.v, ctx.w) if state is None else (state.linear_velocity, state.angular_velocity)
    return np.concatenate((v.reshape(-1, n, 3), w.reshape(-1, n, 3)), axis=-1)


def _write(ctx, idx, u):
    """Store velocities u (M, n, 6) of the engaged elements ``idx`` back into the context."""
    n = ctx.model.n_bodies
    v = np.array(ctx.v).reshape(-1, n, 3)
    w = np.array(ctx.w).reshape(-1, n, 3)
    v[idx], w[idx] = u[..., :3], u[..., 3:]
    ctx.v, ctx.w = v.reshape(ctx.v.shape), w.reshape(ctx.w.shape)


class CollideGround:
    name = "collide_ground"

    def __init__(self, ground):
        self.ground = ground

    def __call__(self, ctx) -> None:
        _hits(ctx)["ground"] = self.ground.detect(*_flat(ctx))


class CollidePairs:
    name = "collide_pairs"

    def __init__(self, pairs):
        self.pairs = pairs

    def __call__(self, ctx) -> None:
        _hits(ctx)["pairs"] = self.pairs.detect(*_flat(ctx))


class AssembleContacts:
    """Engaged elements (a gap the step's velocities could close) and their rows."""

    name = "assemble_contacts"

    def __init__(self, layout: Layout):
        self.layout = layout

    def __call__(self, ctx) -> None:
        hits, lay = _hits(ctx), self.layout
        arm_a, arm_b, normal, gap = lay.gather(hits.get("ground"), hits.get("pairs"))
        u1 = _velocities(ctx)
        vn1 = np.sum(lay.relative_velocity(u1, arm_a, arm_b) * normal, axis=-1)
        engaged = np.flatnonzero(np.any(gap + ctx.dt * np.minimum(vn1, 0.0) < 0, axis=-1))
        hits["engaged"] = engaged
        if len(engaged) == 0:
            return
        x, q = _flat(ctx)
        sub = (arm_a[engaged], None if arm_b is None else arm_b[engaged])
        hits["rows"] = assemble(lay, q[engaged], u1[engaged], *sub, normal[engaged], gap[engaged])


class Restitute:
    """Impacts of the step in time order (``restitution``)."""

    name = "restitute"

    def __init__(self, layout: Layout, settings: SolverSettings):
        self.layout, self.settings = layout, settings

    def __call__(self, ctx) -> None:
        hits = _hits(ctx)
        idx = hits["engaged"]
        if len(idx) == 0:
            return
        u0 = _velocities(ctx, ctx.start)[idx]
        u1 = _velocities(ctx)[idx]
        u, impulse, events, capped = resolve_impacts(
            self.layout, hits["rows"], u0, u1, ctx.dt, self.settings
        )
        hits["impulse"], hits["events"], hits["impact_capped"] = impulse, events, capped
        if np.any(events):
            _write(ctx, idx, u)


class SolveContacts:
    """The inelastic solve with friction (``solve``) and the step's contact report."""

    name = "solve_contacts"

    def __init__(self, layout: Layout, settings: SolverSettings):
        self.layout, self.settings = layout, settings

    def __call__(self, ctx) -> None:
        hits = _hits(ctx)
        idx = hits["engaged"]
        settings = self.settings
        if len(idx) == 0:
            ctx.report[REPORT_KEY] = ContactReport(tolerance=settings.tolerance)
            return
        rows = hits["rows"]
        impulse = hits.get("impulse")
        if impulse is None:
            impulse = np.zeros(rows.gap.shape)
        u, sweeps, converged = solve_inelastic(
            self.layout, rows, _velocities(ctx)[idx], impulse, ctx.dt, settings
        )
        _write(ctx, idx, u)
        impact_capped = hits.get("impact_capped")
        capped = ~converged if impact_capped is None else ~converged | impact_capped
        events = hits.get("events")
        report = ContactReport(
            engaged=len(idx),
            iterations=int(sweeps.max()),
            impacts=0 if events is None else int(events.max()),
            capped=int(np.sum(capped)),
            tolerance=settings.tolerance,
        )
        ctx.report[REPORT_KEY] = report
        if report.capped:
            warnings.warn(
                "a contact solve stopped at its cap (SolverSettings.max_iterations or "
                "max_impacts) instead of converging; scene.report['contacts'] counts the "
                "elements per step",
                ContactSolverWarning,
                stacklevel=4,
            )


class SeparateContacts:
    """After the position update: remove what penetration is left by moving bodies. Each body
    on the ground is lifted by its deepest overlap; each body pair is pushed apart along its
    normal by its deepest overlap, split by mass (momentum unchanged)."""

    name = "separate_contacts"

    def __init__(self, layout: Layout):
        self.layout = layout

    def __call__(self, ctx) -> None:
        if len(_hits(ctx).get("engaged", ())) == 0:
            return
        lay = self.layout
        x, q = _flat(ctx)
        idx = _hits(ctx)["engaged"]
        x_sub, q_sub = x[idx], q[idx]
        ground = None if lay.ground is None else lay.ground.detect(x_sub, q_sub)
        pairs = None if lay.pairs is None else lay.pairs.detect(x_sub, q_sub)
        _, _, normal, gap = lay.gather(ground, pairs)
        depth = -gap
        if not np.any(depth > 0):
            return
        x_sub = np.array(x_sub)
        if lay.n_ground:
            g = len(lay.ground_bodies)
            dg = depth[..., : lay.n_ground].reshape(len(x_sub), g, lay.k)
            x_sub[..., lay.ground_bodies, 2] += np.maximum(np.max(dg, axis=-1), 0.0)
        if lay.c > lay.n_ground:
            pushes, offset = [], lay.n_ground
            for pa, _, _, slots in lay.pairs.groups:
                sl = slice(offset, offset + len(pa) * slots)
                offset = sl.stop
                d = depth[..., sl].reshape(len(x_sub), len(pa), slots)
                n = normal[..., sl, :][..., ::slots, :]
                pushes.append(np.maximum(np.max(d, axis=-1), 0.0)[..., None] * n)
            push = pushes[0] if len(pushes) == 1 else np.concatenate(pushes, axis=-2)
            x_sub += np.einsum("pn,...pk->...nk", lay.pair_share, push)
        x = np.array(x)
        x[idx] = x_sub
        ctx.x = x.reshape(ctx.x.shape)


__all__ = [
    "AssembleContacts",
    "CollideGround",
    "CollidePairs",
    "ContactReport",
    "ContactSolverWarning",
    "REPORT_KEY",
    "Restitute",
    "SeparateContacts",
    "SolveContacts",
]
