"""Starting impulses of one element's Gauss–Seidel solve (a cold solve; with
``SolverSettings.warm_start`` a step starts from the previous step's impulses instead).

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
  stacks; Gauss–Seidel then only polishes. Each round solves its live rows only, for their
  minimum-norm solution (``min_norm``), which gives the dead rows zero.
"""

from __future__ import annotations

import numpy as np

from .cache import njit
from .min_norm import min_norm

ROUNDS = 6  # active-set rounds (a stack of two needs 2–3)
# A contact left out joins the set when the impulses leave it short by more than this share of
# the element's largest shortfall: a contact the others hold exactly at its target (a face's
# fourth corner) is otherwise added or not by rounding, and the two backends then start from
# different sets (the friction problem of a sliding face need not have a unique solution).
PUSH_TOLERANCE = 1e-12


@njit(cache=True, error_model="numpy")
def particle_start(short, mass, shaped, k, lam, rows):
    """Each ground manifold's violated slots share the impulse that stops its body as a
    particle: λ_n (entry ``rows·c`` of ``lam``) ← m max(short) / count. ``short`` (C,)."""
    for g in range(shaped.shape[0]):
        count = 0
        peak = 0.0
        for s in range(g * k, g * k + k):
            if short[s] > 0:
                count += 1
                peak = max(peak, short[s])
        need = mass[shaped[g]] * peak
        for s in range(g * k, g * k + k):
            lam[rows * s] = need / max(count, 1) if short[s] > 0 else 0.0


@njit(cache=True, error_model="numpy")
def active_set_start(short, a, free, reachable, extra, mu, lam, shortfall):
    """``lam`` (3C,) ← the start; ``free``
    (3C,) the free contact velocities (its tangent rows are the slip), A (3C, 3C);
    ``shortfall`` the largest |short| of the slots that hold a contact point, of which the
    push test's tolerance is a share (``contact_solve``'s scales). Returns whether the set
    settled: an unsettled set's equality solution is no LCP solution, and the caller starts
    from the ground particle start instead (``particle_start``)."""
    c = short.shape[0]
    size = 3 * c
    # Scratch in three allocations (this runs on most contact steps).
    floats = np.empty(5 * size + 2 * c + size * size + 3 * size * (size + 1))
    goal = floats[:size]
    rhs = floats[size : 2 * size]
    known = floats[2 * size : 3 * size]
    sub_rhs = floats[3 * size : 4 * size]
    sub_x = floats[4 * size : 5 * size]
    direction = floats[5 * size : 5 * size + 2 * c].reshape((c, 2))
    o = 5 * size + 2 * c
    m = floats[o : o + size * size]
    work = floats[o + size * size :]
    flags = np.empty(5 * c + size, np.bool_)
    on = flags[:c]
    bound = flags[c : 2 * c]
    budget = flags[2 * c : 3 * c]
    nxt = flags[3 * c : 4 * c]
    over = flags[4 * c : 5 * c]
    live = flags[5 * c :]
    index = np.empty(size, np.int64)
    for i in range(c):
        goal[3 * i] = short[i]
        goal[3 * i + 1] = -free[3 * i + 1]
        goal[3 * i + 2] = -free[3 * i + 2]
        on[i] = reachable[i]
        bound[i] = False
        budget[i] = extra[i] > 0
        direction[i, 0] = 0.0
        direction[i, 1] = 0.0
    for i in range(size):
        known[i] = 0.0
    push = PUSH_TOLERANCE * shortfall
    settled = False
    for _ in range(ROUNDS):
        any_bound = False
        symmetric = np.bool_(True)
        for i in range(c):
            live[3 * i] = on[i]
            tangent = (on[i] or budget[i]) and mu[i] > 0 and not bound[i]
            live[3 * i + 1] = tangent
            live[3 * i + 2] = tangent
            any_bound = any_bound or bound[i]
            if bound[i] and on[i]:
                symmetric = np.bool_(False)  # a boundary contact's normal column is mixed (below)
        # The budget's part of a boundary contact's friction, μ d extra, is known.
        for i in range(c):
            kn = mu[i] * extra[i]
            known[3 * i + 1] = kn * direction[i, 0] if bound[i] else 0.0
            known[3 * i + 2] = kn * direction[i, 1] if bound[i] else 0.0
        if any_bound:
            for i in range(0, size, 3):  # a contact's three rows: independent sums, each in order
                acc0 = 0.0
                acc1 = 0.0
                acc2 = 0.0
                for j in range(size):
                    kj = known[j]
                    acc0 += a[i, j] * kj
                    acc1 += a[i + 1, j] * kj
                    acc2 += a[i + 2, j] * kj
                rhs[i] = goal[i] - acc0 if live[i] else 0.0
                rhs[i + 1] = goal[i + 1] - acc1 if live[i + 1] else 0.0
                rhs[i + 2] = goal[i + 2] - acc2 if live[i + 2] else 0.0
        else:
            for i in range(size):
                rhs[i] = goal[i] if live[i] else 0.0
        # The live rows' system, solved for its minimum-norm solution; dead rows get zero.
        # Columns: a contact at the cone's boundary acts through n + μ d·t.
        count = 0
        for i in range(size):
            if live[i]:
                index[count] = i
                count += 1
        sub = m[: count * count].reshape((count, count))
        for i in range(count):
            row = index[i]
            sub_rhs[i] = rhs[row]
            for j in range(count):
                col = index[j]
                jc = col // 3
                if bound[jc] and col == 3 * jc:
                    mix = mu[jc] * direction[jc, 0]
                    value = a[row, col] + a[row, col + 1] * mix
                    mix = mu[jc] * direction[jc, 1]
                    sub[i, j] = value + a[row, col + 2] * mix
                else:
                    sub[i, j] = a[row, col]
        min_norm(sub, sub_rhs[:count], sub_x[:count], symmetric, work)
        for i in range(size):
            lam[i] = 0.0
        for i in range(count):
            lam[index[i]] = sub_x[i]
        for i in range(c):
            ln = max(lam[3 * i], 0.0) if on[i] else 0.0
            cap = mu[i] * (ln + extra[i])
            if bound[i]:
                t1, t2 = cap * direction[i, 0], cap * direction[i, 1]
            else:
                t1, t2 = lam[3 * i + 1], lam[3 * i + 2]
            if not (on[i] or budget[i]):
                t1 = t2 = 0.0
            nt = np.sqrt(t1 * t1 + t2 * t2)
            over[i] = (not bound[i]) and (on[i] or budget[i]) and nt > cap * (1 + 1e-12)
            shrink = cap / (nt if nt > 0 else 1.0) if nt > cap else 1.0
            lam[3 * i] = ln
            lam[3 * i + 1] = t1 * shrink
            lam[3 * i + 2] = t2 * shrink
            # direction of the unshrunk impulse, kept for a contact moved to the boundary
            direction_0 = t1 / (nt if nt > 0 else 1.0)
            direction_1 = t2 / (nt if nt > 0 else 1.0)
            known[3 * i + 1] = direction_0  # scratch until the next round rewrites it
            known[3 * i + 2] = direction_1
        settled = True
        for i in range(c):
            if on[i]:
                nxt[i] = lam[3 * i] > 0
            else:  # an off contact's normal velocity: does the start push through it?
                acc = 0.0
                for j in range(size):
                    acc += a[3 * i, j] * lam[j]
                nxt[i] = short[i] - acc > push
            if nxt[i] != on[i] or over[i]:
                settled = False
        if settled:
            break
        for i in range(c):
            if over[i]:
                direction[i, 0] = known[3 * i + 1]
                direction[i, 1] = known[3 * i + 2]
                bound[i] = True
            on[i] = nxt[i]
            bound[i] = bound[i] and (on[i] or budget[i])
    return settled
