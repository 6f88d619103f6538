"""Starting impulses for the Gauss–Seidel solve (the state carries no impulses between steps).

* ``particle_start`` (ground slots): each body's manifold starts from the impulse that stops the
  body as a particle, shared equally by its violated slots. Exact for a box resting or landing
  flat (corners symmetric about the centre of mass), so resting costs one sweep there.
* ``active_set_start`` (scenes with body–body contacts): impulses couple through the bodies (a
  stack's lower box carries the upper one) and a heavy box on a light one (mass ratio 10⁶) is
  ill-conditioned for any iteration. The contacts are solved directly as equalities (normal: the
  target; tangents: sticking) on an active set, the simplest pivoting for the LCP (Baraff, "Fast
  contact force computation for nonpenetrating rigid bodies", SIGGRAPH 1994): start from the
  contacts that can carry load, solve by pseudo-inverse (redundant supports get the
  minimum-norm, symmetric share), clamp λ_n ≥ 0 and λ_t into the friction cone, drop contacts
  that pull, add those the impulses push in; a few rounds. Exact for resting and sticking
  stacks; Gauss–Seidel then only polishes.
"""

from __future__ import annotations

import numpy as np

ROUNDS = 6  # active-set rounds (a stack of two needs 2–3)
# A contact left out joins the set when the impulses leave it short by more than this share of
# the element's largest shortfall: a contact the others hold exactly at its target (a face's
# fourth corner) is otherwise added or not by rounding, and the two backends then start from
# different sets (the friction problem of a sliding face need not have a unique solution).
PUSH_TOLERANCE = 1e-12
# Singular values below this share of the largest are rounding, not a direction of the system:
# the active set's equations are rank-deficient by construction (a face's four corners give four
# normal rows of rank three), and pinv's default (1e-15) keeps an exactly dependent row's
# rounding-size singular value and with it an impulse of ~1e15 its size. ``compiled.min_norm``
# stops its pivoted Cholesky at the same share of the largest diagonal.
RANK_TOLERANCE = 1e-12


def particle_start(layout, short, lam_n):
    """Write the ground slots' start into ``lam_n`` (N, C); ``short`` (N, C) = target − v_n."""
    if layout.n_ground == 0:
        return
    g = len(layout.ground_bodies)
    s = short[..., : layout.n_ground].reshape(len(short), g, layout.k)
    violated = s > 0
    count = np.sum(violated, axis=-1, keepdims=True)
    mass = layout.mass[layout.ground_bodies]
    need = mass[:, None] * np.max(np.where(violated, s, 0.0), axis=-1, keepdims=True)
    share = np.where(violated, need / np.maximum(count, 1), 0.0)
    lam_n[..., : layout.n_ground] = share.reshape(len(short), -1)


def active_set_start(layout, short, delassus, slip, reachable, extra, scale=None):
    """Start (N, C, 3); ``short`` (N, C) = target − v_n, ``slip`` (N, C, 2) the free
    tangential velocities, ``reachable`` (N, C) the initial set, ``extra`` (N, C) the normal
    impulse of this step's impacts (friction budget: a contact that has one takes part in the
    tangential equations even when its normal row is off); ``scale`` (N,) the largest |short|
    that ``PUSH_TOLERANCE`` is a share of (default: over all slots; the solve leaves out the
    slots with no contact point, ``solve.contact_scales``).

    A contact whose sticking impulse leaves its friction cone is moved to the cone's boundary
    in that impulse's direction d (λ_t = μ λ_n d: its normal column gains μ d of its tangent
    columns, its tangent rows leave the equations), and the rest is solved again; a box
    resting on an incline needs this once (its uphill corners carry less load)."""
    size, c = short.shape
    mu = layout.mu
    goal = np.concatenate((short[..., None], -slip), -1).reshape(size, -1)
    row_used = np.ones((c, 3), bool)
    row_used[:, 1:] = (mu > 0)[:, None]
    eye = np.eye(3 * c)
    on = reachable
    bound = np.zeros((size, c), bool)
    direction = np.zeros((size, c, 2))
    settled = np.zeros(size, bool)
    lam = np.zeros((size, c, 3))
    budget = extra > 0
    if scale is None:
        scale = np.max(np.abs(short), axis=-1)
    scale = np.asarray(scale)[:, None]
    for _ in range(ROUNDS):
        rows3 = on[..., None] & row_used
        rows3[..., 1:] = (on | budget)[..., None] & row_used[:, 1:] & ~bound[..., None]
        live = rows3.reshape(size, -1)
        # Columns: a contact at the cone's boundary acts through n + μ d·t.
        cols = np.array(delassus)
        mix = (mu * bound)[..., None] * direction  # (N, C, 2)
        cols[:, :, 0::3] += cols[:, :, 1::3] * mix[:, None, :, 0]
        cols[:, :, 0::3] += cols[:, :, 2::3] * mix[:, None, :, 1]
        a = np.where(live[..., :, None] & live[..., None, :], cols, 0.0)
        a += np.where(live, 0.0, 1.0)[..., None] * eye
        # The budget's part of a boundary contact's friction, μ d extra, is known: move it over.
        known = np.zeros((size, c, 3))
        known[..., 1:] = np.where(bound[..., None], (mu * extra)[..., None] * direction, 0.0)
        rhs = goal - (delassus @ known.reshape(size, -1, 1))[..., 0]
        lam = (
            np.linalg.pinv(a, rcond=RANK_TOLERANCE) @ np.where(live, rhs, 0.0)[..., None]
        ).reshape(size, c, 3)
        lam_n = np.where(on, np.maximum(lam[..., 0], 0.0), 0.0)
        cap = mu * (lam_n + extra)
        lam_t = np.where(bound[..., None], cap[..., None] * direction, lam[..., 1:])
        lam_t = np.where((on | budget)[..., None], lam_t, 0.0)
        norm = np.linalg.norm(lam_t, axis=-1)
        over = ~bound & (on | budget) & (norm > cap * (1 + 1e-12))
        shrink = np.where(norm > cap, cap / np.where(norm > 0, norm, 1.0), 1.0)
        lam = np.concatenate((lam_n[..., None], lam_t * shrink[..., None]), -1)
        nxt = on & (lam_n > 0)
        pushed = (delassus @ lam.reshape(size, -1, 1)).reshape(size, c, 3)[..., 0]
        nxt |= ~on & (short - pushed > PUSH_TOLERANCE * scale)
        settled = np.all(nxt == on, axis=-1) & ~np.any(over, axis=-1)
        if settled.all():
            break
        unit = lam_t / np.where(norm > 0, norm, 1.0)[..., None]
        grow = ~settled[:, None] & over
        direction = np.where(grow[..., None], unit, direction)
        bound = bound | grow
        on = np.where(settled[:, None], on, nxt)
        bound &= on | budget
    if not settled.all():
        # An unsettled set's equality solution is no LCP solution (it can be 100× the load):
        # those elements start from the ground particle start instead.
        fallback = np.zeros((size, c, 3))
        particle_start(layout, short, fallback[..., 0])
        lam = np.where(settled[:, None, None], lam, fallback)
    return lam


__all__ = ["PUSH_TOLERANCE", "RANK_TOLERANCE", "ROUNDS", "active_set_start", "particle_start"]
