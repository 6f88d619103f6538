"""Restitution: impacts resolved one after another in time order within the step.

A semi-implicit step stores v₁ ≈ v(t₀ + Δt/2): velocities are step means, positions follow
x₁ = x₀ + Δt v₁. Impacts are resolved on those velocities before the inelastic solve
(``solve.py``), each at the time its contact closes:

1. Per contact, its gap d (at the step's start, linearised: d + τ v_n later) closes after
   τ = d / (−v_n). The earliest closing among the *impact* contacts (ε > 0, impact speed above
   the material's threshold, not yet struck this step) is the next event; all impact contacts
   closing at that instant, and those of the same manifold (body on the ground, body pair)
   closing within one step of it (a box landing flat or nearly so: four corners), are struck
   together, each with its own closing time (at most the step's end).
   Supports: before the first event, the element's other contacts (no impact: ε = 0, or
   closing below the threshold) hold from the step's start, by one inelastic normal solve
   (``v_n ≥ −d/Δt``, ``v_n ≥ 0`` touching; the impact contacts out of play); its impulses
   count as the contacts' impulse (the friction budget of the inelastic solve). A box at rest
   on an edge whose far corners strike within the step pivots on the edge until they do,
   instead of sinking through it. The supports act over the whole step, as a force would, so
   the closing contacts' normal acceleration (``s`` below) is taken after them.
2. The struck contacts get Newton's law, v_n⁺ ≥ target, λ ≥ 0, complementarity (normal rows
   only), solved by ``gauss_seidel``, together with the *loaded* supports (those that carried
   an impulse in step 1), which hold as they did: v_n⁺ ≥ 0 touching, ≥ −d/Δt at a gap d. A box
   dropped on a box resting on the ground meets a fixed support: it leaves with ε times its
   impact speed and the lower box stays, instead of being driven into the ground. The other
   contacts are free in the event: unloaded contacts pass an impulse on only by an impact of
   their own, in its order (the touching balls of a Newton's cradle in space). The bodies'
   velocities change, so later contacts close at other times (a Newton's cradle: the striker stops, the next ball
   moves, reaches the third, …) and the loop goes on until no impact falls within the step
   (or ``max_impacts``, reported).

Path. The bodies travel with the velocity of each interval: x = x₀ + Σ τₖ uₖ and
q = Π exp(τₖ ωₖ) q₀ up to the last event, then the rest of the step with the final velocity
(``Path``; the position update adds the difference to x₀ + Δt v as its displacement, and
``limit_energy`` starts its rotation at exp(−elapsed ω) q so that it ends at
exp((Δt − elapsed) ω) q). A ball a Newton's cradle sets moving mid-step travels only the rest
of the step, and the inelastic solve keeps the gaps where the impacts left them, over the
remaining time. Impulses act where the bodies are at the event (``Rows.moved``): a pair's
impulses at the features' midpoint there, so angular momentum is exact.

The edge freeze (fixed by the supports and the path's orientation): a box at rest tilted on an
edge a fraction of a millimetre from flat, at Δt = 0.01 s. Its far corners close within the
step above the threshold and are struck; without the supports the path before the event was
the free fall through the edge, and without the orientation the end pose lost the pivot's
turn toward flat, so the separation lifted the body back to its start height, the energy
guard (``limit_energy``) found no energy for any motion and zeroed the velocities: tilted and
at rest, the same every step.

Targets. Semi-implicit Euler under a constant non-contact acceleration a (gravity) stores
step-mean velocities: the instantaneous normal velocity at a time t into the step is
w = v_n + a (t − Δt/2). Newton's law acts on it at the closing, w⁺ = −ε w, and the stored
velocity after the event is the step-mean of the outgoing motion, v_n⁺ = −ε w + a (Δt/2 − t).
With the path above, the steps after a bounce sample the outgoing parabola to O(a Δt²):
apexes fall as ε²ᵏ h whatever the impact's phase within the step.

Energy. Each event's velocity change Δu is scaled by the largest α ∈ [0, 1] that keeps the
kinetic energy from growing (Newton's law at several simultaneous contacts can add energy: a
tumbling box with ε = 1); α = min(1, −2 z·dz / |dz|²) in z = M^(1/2) u coordinates. The step's
total energy is guarded after the solve (``energy``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rotation import quat_exp, quat_multiply
from .assembly import scaled_velocity
from .solve import gauss_seidel

_OUT = -np.inf  # normal target of a contact out of play in an event


def impact_targets(vn, s, t, eps, dt):
    """Impact speeds (≥ 0) and post-impact normal velocities of contacts approaching with
    stored normal velocity ``vn`` and closing at time ``t`` into the step; ``s`` is the
    normal part of half the step's non-contact velocity change (a Δt / 2)."""
    rate = 2.0 * s / dt  # the normal acceleration a
    w = vn + rate * (t - 0.5 * dt)  # instantaneous velocity at the closing
    speed = np.maximum(-w, 0.0)
    return speed, eps * speed + rate * (0.5 * dt - t)


def resolve_impacts(layout, rows, u0, u1, dt, settings, q):
    """Impacts of the step in time order. Returns ``(u, impulse, events, capped, path)``: the
    velocities after them (N, n, 6), the normal impulse each contact received (N, C) (the
    supports' and the impacts'), the number of events (N,), whether an element still had
    impacts at ``max_impacts`` or a solve of its events stopped at ``max_iterations``, and the
    :class:`Path` the bodies took from the start orientations ``q`` (N, n, 4)."""
    size, c = rows.gap.shape
    impulse = np.zeros((size, c))
    events = np.zeros(size, int)
    capped = np.zeros(size, bool)
    path = np.zeros(u1.shape[:-1] + (3,))
    elapsed = np.zeros(size)
    gap = np.array(rows.gap)
    orientation = np.array(q)
    if not np.any(layout.eps > 0):
        return u1, impulse, events, capped, Path(path, elapsed, gap, orientation)
    vn0 = rows.velocity(u0, layout)[..., 0]
    vn1 = rows.velocity(u1, layout)[..., 0]
    s = 0.5 * (vn1 - vn0)
    u = np.array(u1)
    struck = np.zeros((size, c), bool)
    loaded = np.zeros((size, c), bool)  # the supports that carried a load before the events
    idx = np.arange(size)
    round_slots = np.zeros(c, bool)  # the sphere–sphere contacts (``round_closing``)
    round_slots[layout.pair_slice] = layout.round_pairs
    supports = True  # the first pass holds the supports (module docstring), then events
    for _ in range(settings.max_impacts + 2):
        sub = rows.take(idx) if len(idx) < size else rows
        vn = sub.velocity(u[idx], layout)[..., 0]
        g = gap[idx]
        close = np.maximum(g, 0.0) / np.where(vn < 0, -vn, 1.0)  # time to close
        if round_slots.any():  # sphere pairs: along the line of centres, exactly
            g[:, round_slots], vn[:, round_slots], close[:, round_slots] = round_closing(
                layout, sub, u[idx], path[idx]
            )
        at = np.minimum(elapsed[idx][:, None] + close, dt)
        speed, target = impact_targets(vn, s[idx], at, layout.eps, dt)
        eligible = (layout.eps > 0) & (vn < 0) & (speed > layout.threshold) & ~struck[idx]
        tau = np.where(eligible, close, np.inf)
        first = np.min(tau, axis=-1)
        going = first < dt - elapsed[idx]
        if not going.any():
            break
        if supports:
            supports = False
            keep = np.flatnonzero(going)
            idx, vn, g, eligible = idx[keep], vn[keep], g[keep], eligible[keep]
            hold = np.where(eligible, _OUT, np.where(g > 0, -g / dt, 0.0))
            du, lam_n, alpha, done = _event(layout, rows.take(idx), u[idx], vn, hold, settings)
            u[idx] += alpha[:, None, None] * du
            impulse[idx] += alpha[:, None] * lam_n
            capped[idx] |= ~done
            loaded[idx] = (alpha[:, None] * lam_n > 0) & ~eligible
            # The supports act over the whole step, as a force would: the closing contacts'
            # normal acceleration is the one they leave (a box struck on a box resting on the
            # ground closes at g, not at the zero relative acceleration of two falling boxes).
            s[idx] = 0.5 * (rows.take(idx).velocity(u[idx], layout)[..., 0] - vn0[idx])
            continue
        if events[idx].max(initial=0) >= settings.max_impacts:
            capped[idx[going]] = True
            break
        keep = np.flatnonzero(going)
        idx, vn, tau, target, g = idx[keep], vn[keep], tau[keep], target[keep], g[keep]
        eligible, first = eligible[keep], first[keep]
        g = g + first[:, None] * vn
        elapsed[idx] += first
        path[idx] += first[:, None, None] * u[idx][..., :3]
        if round_slots.any():  # the sphere pairs' normal velocities and targets at the touch
            g_r, vn_r, close_r = round_closing(layout, rows.take(idx), u[idx], path[idx])
            at_r = np.minimum(elapsed[idx][:, None] + close_r, dt)
            g[:, round_slots], vn[:, round_slots] = g_r, vn_r
            target[:, round_slots] = impact_targets(
                vn_r, s[idx][:, round_slots], at_r, layout.eps[round_slots], dt
            )[1]
        gap[idx] = g
        turn = quat_exp(first[:, None, None] * u[idx][..., 3:])
        orientation[idx] = quat_multiply(turn, orientation[idx])
        # The impulses act where the bodies are now (pairs: the features' midpoint there).
        sub = rows.take(idx).moved(layout, u[idx], path[idx])
        # Contacts closing together (within a relative 1e-9 of the event's time), and the other
        # contacts of their manifolds that close within one step of it: the step cannot order
        # one body's corners on one surface closer than Δt, so they are struck together (a box
        # landing nearly flat bounces like a flat one instead of rocking from edge to edge).
        hit = eligible & (tau <= first[:, None] * (1 + 1e-9) + 1e-15)
        same = layout.manifold[:, None] == layout.manifold[None, :]  # (C, C)
        struck_manifold = (hit.astype(float) @ same) > 0
        hit |= eligible & struck_manifold & (tau < (first + dt)[:, None])
        struck[idx] |= hit
        # The loaded supports hold through the event as they held before it (v_n ≥ their
        # target from the step's start, at the gap the event left them): a box resting on the
        # ground is struck from above as a fixed support, not as a free body.
        held = loaded[idx] & ~hit
        goal = np.where(hit, target, np.where(held, np.where(g > 0, -g / dt, 0.0), _OUT))
        du, lam_n, alpha, done = _event(layout, sub, u[idx], vn, goal, settings)
        u[idx] += alpha[:, None, None] * du
        impulse[idx] += alpha[:, None] * lam_n
        capped[idx] |= ~done
        events[idx] += 1
    return u, impulse, events, capped, Path(path, elapsed, gap, orientation)


def round_closing(layout, rows, u, shift):
    """Gap, normal velocity and time to close (N, R) of the sphere–sphere contacts after the
    bodies translated by ``shift`` (N, n, 3), at velocities u (N, n, 6).

    The centres' offset d = (ra + rb + gap₀) n₀ + Δshift (``Rows.moved``) moves at the
    centres' relative velocity w (a sphere's spin moves its contact point only tangentially):
    the spheres touch when |d + τ w| = R = ra + rb, the smaller root of
    |w|² τ² + 2 d·w τ + |d|² − R² = 0, taken as 2c / (−b + √(b² − 4ac)) (no cancellation
    when the gap is small). The linearised d + τ v_n of the other contacts misses that instant
    by (v_t τ)² / 2R, which turns the normal by v_t τ / R: an oblique impact's exit velocities
    then depend on its phase within the step. No real root (a miss) or moving apart: never."""
    sl = layout.pair_slice
    m = layout.round_pairs
    ra = np.linalg.norm(rows.arm_a[:, sl][:, m], axis=-1)
    rb = np.linalg.norm(rows.arm_b[:, m], axis=-1)
    radius = ra + rb
    pa, pb = layout.pa[m], layout.pb[m]
    d = (radius + rows.gap[:, sl][:, m])[..., None] * rows.normal[:, sl][:, m]
    d = d + shift[:, pa] - shift[:, pb]
    w = u[:, pa, :3] - u[:, pb, :3]
    dist = np.linalg.norm(d, axis=-1)
    gap = dist - radius
    vn = np.sum(d * w, axis=-1) / np.where(dist > 1e-12, dist, 1.0)
    a = np.sum(w * w, axis=-1)
    b = 2.0 * np.sum(d * w, axis=-1)
    c = dist * dist - radius * radius
    disc = b * b - 4.0 * a * c
    meets = (b < 0) & (disc >= 0)  # approaching, and the line passes within R
    root = 2.0 * np.maximum(c, 0.0) / np.where(meets, -b + np.sqrt(np.maximum(disc, 0.0)), 1.0)
    close = np.where(meets, np.where(gap > 0, root, 0.0), np.inf)
    return gap, vn, close


@dataclass
class Path:
    """Where the impacts left the bodies: ``translation`` (N, n, 3) travelled and
    ``orientation`` (N, n, 4) reached up to the last event, at time ``elapsed`` (N,) into the
    step, with the contacts' gaps ``gap`` (N, C) there. The step then ends with
    x = x₀ + translation + (Δt − elapsed) v, q = exp((Δt − elapsed) ω) orientation: a ball that a
    Newton's cradle sets moving mid-step travels only the rest of the step, and the inelastic
    solve keeps the gaps from ``gap`` over the remaining time."""

    translation: np.ndarray
    elapsed: np.ndarray
    gap: np.ndarray
    orientation: np.ndarray

    def displacement(self, u):
        """The position update's correction to x₀ + Δt v: translation − elapsed v, (N, n, 3)."""
        return self.translation - self.elapsed[:, None, None] * u[..., :3]


def _event(layout, rows, u, vn, goal, settings):
    """One event's normal impulses: Newton's law ``v_n ≥ goal`` (−∞: out of play) solved by
    ``gauss_seidel`` from zero. Returns ``(du, lam_n, alpha, converged)``: the velocity change
    of the impulses (N, n, 6), the impulses (N, C), the largest α ∈ [0, 1] with which they add
    no kinetic energy (``_energy_step``), and whether the solve converged (N,)."""
    size, c = vn.shape
    lam_n, _, done = gauss_seidel(
        rows.normal_delassus,
        vn[..., None],
        goal,
        layout.mu,
        np.zeros((size, c, 1)),
        settings,
    )
    lam = np.zeros((size, c, 3))
    lam[..., 0] = lam_n[..., 0]
    du = rows.velocity_change(lam, layout)
    z = scaled_velocity(layout, u, rows.scale)[..., 0]
    dz = scaled_velocity(layout, du, rows.scale)[..., 0]
    return du, lam_n[..., 0], _energy_step(z, dz), done


def _energy_step(z, dz):
    """Largest α ∈ [0, 1] with ½|z + α dz|² ≤ ½|z|²: the impulse adds no kinetic energy."""
    quad = np.sum(dz * dz, axis=-1)
    lin = np.sum(z * dz, axis=-1)
    alpha = np.where(quad > 0, -2.0 * lin / np.where(quad > 0, quad, 1.0), 1.0)
    return np.clip(alpha, 0.0, 1.0)


__all__ = ["impact_targets", "resolve_impacts"]
