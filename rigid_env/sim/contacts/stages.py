"""The contact stages of the step pipeline (``rigid_env.sim.pipeline``).

Between a semi-implicit integrator's ``integrate_velocity`` and ``integrate_position``:

* ``collide_ground`` / ``collide_pairs`` detect at the start-of-step positions and put their
  hits in ``ctx.contacts`` (batch flattened to one axis, ``(N, n, ·)``);
* ``assemble_contacts`` picks the batch elements with a contact within reach this step and
  builds their rows (``assembly``); the other elements skip every later contact stage;
* ``restitute`` resolves the step's impacts in time order (``restitution``);
* ``solve_contacts`` solves the inelastic problem with friction to the stated tolerance
  (``solve``) and writes ``ctx.report["contacts"]`` (a :class:`ContactReport`);
* ``limit_energy`` scales the velocities down if the step would end with more energy than it
  started with plus the work of the applied loads along its motion (``energy``'s invariant),
  and hands the impacts' path to the position update (its translation as
  ``ctx.displacement``, its orientation as the ``ctx.q`` the rotation starts from);

and after ``integrate_position``:

* ``separate_contacts`` removes the penetration the linearised step left (rotation over the
  step) by moving bodies, pays the potential energy of the lift out of the kinetic energy, and
  reports the energy the contacts removed (``ContactReport.energy_removed``).

A solve that stops at ``max_iterations`` or ``max_impacts`` instead of converging is counted in
the report's ``capped`` and raises a :class:`ContactSolverWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..rotation import quat_exp, quat_multiply, quat_normalize, quat_to_matrix
from . import energy
from .assembly import Layout, assemble
from .restitution import resolve_impacts
from .solve import SolverSettings, solve_inelastic

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
        hits["u1"] = u1[engaged]
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
        q = _flat(ctx)[1][idx]
        u, impulse, events, capped, path = resolve_impacts(
            self.layout, hits["rows"], u0, u1, ctx.dt, self.settings, q
        )
        hits["impulse"], hits["events"], hits["impact_capped"] = impulse, events, capped
        hits["path"] = path
        if np.any(impulse):  # supports held or impacts struck
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
        size = ctx.x.reshape(-1, ctx.model.n_bodies, 3).shape[0]
        touched = np.zeros(size, bool)
        if len(idx) == 0:
            ctx.report[REPORT_KEY] = ContactReport(
                tolerance=settings.tolerance,
                touched=touched,
                energy_removed=np.zeros(size),
                capped_mask=np.zeros(size, bool),
            )
            ctx.warm = None
            return
        rows = hits["rows"]
        impulse = hits.get("impulse")
        if impulse is None:
            impulse = np.zeros(rows.gap.shape)
        path = hits.get("path")
        u = _velocities(ctx)[idx]
        if path is None:
            gap = remaining = None
        else:
            gap, remaining = path.gap, ctx.dt - path.elapsed
            if np.any(path.elapsed > 0):
                rows = rows.moved(self.layout, u, path.translation)
        u_in = u
        warm = None
        if ctx.warm is not None:  # the previous step's (λ, converged) over the whole batch
            warm = (ctx.warm[0][idx], ctx.warm[1][idx])
        u, sweeps, converged, newton_steps, lam = solve_inelastic(
            self.layout, rows, u, impulse, ctx.dt, settings, gap, remaining, warm
        )
        if settings.warm_start:  # the next step of this call starts where this one ended
            full = np.zeros((size, *lam.shape[1:]))
            ok = np.zeros(size, bool)
            full[idx], ok[idx] = lam, converged
            ctx.warm = (full, ok)
        _write(ctx, idx, u)
        touched[idx] = np.any(impulse > 0, axis=-1) | np.any(u != u_in, axis=(-1, -2))
        impact_capped = hits.get("impact_capped")
        capped = ~converged if impact_capped is None else ~converged | impact_capped
        capped_mask = np.zeros(size, bool)
        capped_mask[idx] = capped
        events = hits.get("events")
        report = ContactReport(
            engaged=len(idx),
            iterations=int(sweeps.max()),
            newton=int(newton_steps.max()),
            impacts=0 if events is None else int(events.max()),
            capped=int(np.sum(capped)),
            warm_started=0 if warm is None else int(np.sum(warm[1])),
            tolerance=settings.tolerance,
            touched=touched,
            energy_removed=np.zeros(size),
            capped_mask=capped_mask,
        )
        ctx.report[REPORT_KEY] = report
        if report.capped:
            warn_capped(stacklevel=5)  # warn_capped ← __call__ ← run ← Scene.step ← the caller


def warn_capped(stacklevel: int) -> None:
    """The :class:`ContactSolverWarning` of a step with a capped solve (both backends)."""
    warnings.warn(
        "a contact solve stopped at its cap (SolverSettings.max_iterations or "
        "max_impacts) instead of converging; scene.report['contacts'] counts the "
        "elements per step",
        ContactSolverWarning,
        stacklevel=stacklevel,
    )


class LimitEnergy:
    """Before the position update: the contacts add no energy, the loads do their full work
    (``energy``'s invariant (1))."""

    name = "limit_energy"

    def __init__(self, layout: Layout):
        self.layout = layout

    def __call__(self, ctx) -> None:
        hits = _hits(ctx)
        idx = hits.get("engaged", ())
        if len(idx) == 0:
            return
        model, n, dt = ctx.model, ctx.model.n_bodies, ctx.dt
        start = ctx.start
        x0 = start.position.reshape(-1, n, 3)[idx]
        rot0 = quat_to_matrix(start.orientation.reshape(-1, n, 4)[idx])
        u0, u1, u = _velocities(ctx, start)[idx], hits["u1"], _velocities(ctx)[idx]
        pe0 = energy.potential(model, x0)
        e_start = energy.kinetic(model, rot0, u0) + pe0
        e_free = energy.energy(model, x0 + dt * u1[..., :3], rot0, u1)
        rates = energy.load_rates(ctx, idx)
        work = energy.work(rates, u, dt)  # W(u); W(f u) = f W(u)
        if rates is not None:
            e_free = e_free - energy.work(rates, u1, dt)
        path = hits.get("path")
        # The orientation follows the path: turned by each interval's ω up to the last event
        # (q_path), then by the final ω over the rest of the step, so the end orientation is
        # exp((Δt − elapsed) ω) q_path; without events q_path = q₀.
        q0 = start.orientation.reshape(-1, n, 4)[idx]
        moved = np.zeros(len(idx), bool) if path is None else path.elapsed > 0
        rot_path = rot0
        if path is not None and moved.any():
            q0 = np.where(moved[:, None, None], path.orientation, q0)
            rot_path = np.where(moved[:, None, None, None], quat_to_matrix(q0), rot0)
        # KE at the end orientation exp(h ω) q_path equals KE at q_path (ω is its axis).
        ke = energy.kinetic(model, rot_path, u)
        shift = np.zeros(x0.shape) if path is None else path.displacement(u)
        # With a path, x_end = x₀ + translation + (Δt − elapsed) f v: PE is still linear in f.
        base = x0 + shift + (0.0 if path is None else path.elapsed[:, None, None]) * u[..., :3]
        tail = dt - (0.0 if path is None else path.elapsed)
        pe_base = energy.potential(model, base) - pe0
        lin = energy.potential(model, base + tail[:, None, None] * u[..., :3]) - pe0 - pe_base
        if rates is not None:
            lin = lin - work
        reference = np.maximum(e_start, e_free)
        room = reference - pe0 - pe_base
        slack = 1e-12 * np.abs(e_start) + 1e-300  # rounding of the energies
        f = energy.scale_to(ke, lin, room)
        # The end configuration's overlap (rotation over the step) lifts the body too: halve
        # f until the separated end positions fit as well (f = 0 stays at the start).
        for _ in range(MAX_HALVINGS):
            x_end = base + (f * tail)[:, None, None] * u[..., :3]
            q_end = quat_normalize(
                quat_multiply(quat_exp((f * tail)[:, None, None] * u[..., 3:]), q0)
            )
            pe_end = energy.potential(model, separated(self.layout, x_end, q_end))
            excess = f * f * ke + pe_end - pe0 - pe_base
            if rates is not None:
                excess = excess - f * work
            over = excess > room + slack
            if not over.any():
                break
            f = np.where(over, 0.5 * f, f)
        else:
            f = np.where(over, 0.0, f)
        hits["rot0"] = rot_path  # the end orientation's KE, for ``SeparateContacts``
        hits["guard"] = (rates, rot0, u0)
        if np.any(f < 1):
            u = u * f[:, None, None]
            _write(ctx, idx, u)
        if path is not None and moved.any():
            # The position update turns q by Δt ω: start it at exp(−elapsed ω) q_path.
            q = np.array(ctx.q).reshape(-1, n, 4)
            back = quat_exp(-path.elapsed[:, None, None] * u[..., 3:])
            q[idx[moved]] = quat_multiply(back, path.orientation)[moved]
            ctx.q = q.reshape(ctx.q.shape)
        if path is not None and np.any(path.elapsed > 0):
            # x_end = x₀ + Δt v + displacement, the path's translation − elapsed v.
            shift = path.displacement(u)
            full = np.zeros(ctx.x.reshape(-1, n, 3).shape)
            full[idx] = shift
            full = full.reshape(ctx.x.shape)
            ctx.displacement = full if ctx.displacement is None else ctx.displacement + full


def separated(lay: Layout, x, q):
    """Positions (N, n, 3) with the overlap at (x, q) removed: each body on the ground is
    lifted by its deepest overlap; each body pair is pushed apart along its normal by its
    deepest overlap, split by mass (momentum unchanged)."""
    ground = None if lay.ground is None else lay.ground.detect(x, q)
    pairs = None if lay.pairs is None else lay.pairs.detect(x, q)
    _, _, normal, gap = lay.gather(ground, pairs)
    depth = -gap
    if not np.any(depth > 0):
        return x
    x = np.array(x)
    if lay.n_ground:
        g = len(lay.ground_bodies)
        dg = depth[..., : lay.n_ground].reshape(len(x), g, lay.k)
        x[..., lay.ground_bodies, 2] += np.maximum(np.max(dg, axis=-1), 0.0)
    if lay.c > lay.n_ground:
        pushes, offset = [], lay.n_ground
        for pa, _, _, slots in lay.pairs.groups:
            sl = slice(offset, offset + len(pa) * slots)
            offset = sl.stop
            d = depth[..., sl].reshape(len(x), len(pa), slots)
            n = normal[..., sl, :][..., ::slots, :]
            pushes.append(np.maximum(np.max(d, axis=-1), 0.0)[..., None] * n)
        push = pushes[0] if len(pushes) == 1 else np.concatenate(pushes, axis=-2)
        x += np.einsum("pn,...pk->...nk", lay.pair_share, push)
    return x


class SeparateContacts:
    """After the position update: remove what overlap is left (``separated``) and pay the
    potential energy of the lift out of the kinetic energy, keeping E − W unchanged
    (``energy``); then the step's ``energy_removed``."""

    name = "separate_contacts"

    def __init__(self, layout: Layout):
        self.layout = layout

    def __call__(self, ctx) -> None:
        hits = _hits(ctx)
        idx = hits.get("engaged", ())
        report = ctx.report.get(REPORT_KEY)
        if len(idx) == 0:
            return
        model, dt = ctx.model, ctx.dt
        rates, rot0, u0 = hits["guard"]
        x, q = _flat(ctx)
        x_sub = separated(self.layout, x[idx], q[idx])
        u = _velocities(ctx)[idx]
        lift = np.zeros(len(idx))
        if x_sub is not x[idx] and not np.array_equal(x_sub, x[idx]):
            lift = energy.potential(model, x_sub) - energy.potential(model, x[idx])
            if np.any(lift > 0):
                ke = energy.kinetic(model, hits["rot0"], u)
                factor, unpaid = energy.pay(ke, lift, energy.work(rates, u, dt), rates)
                u = u * factor[:, None, None]
                _write(ctx, idx, u)
                if report is not None and np.any(unpaid > 0):
                    report = replace(report, unpaid_energy=float(np.max(unpaid)))
            x = np.array(x)
            x[idx] = x_sub
            ctx.x = x.reshape(ctx.x.shape)
        if report is not None:
            removed = np.zeros(len(report.touched))
            removed[idx] = energy.contact_work(model, rot0, u0, hits["u1"], u) - lift
            ctx.report[REPORT_KEY] = replace(report, energy_removed=removed)


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
