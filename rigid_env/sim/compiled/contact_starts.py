"""Starting impulses of one element's solve, mirroring ``contacts.warm_start`` (see there):
the ground particle start and the active-set start (rounds of ``ROUNDS``). Each round solves
its live rows only, for their minimum-norm solution (``min_norm``, numpy: ``pinv`` of the
whole system with identity rows for the dead ones, which gives the dead rows zero)."""

from __future__ import annotations

import numpy as np

from ..contacts.warm_start import PUSH_TOLERANCE, ROUNDS
from .cache import njit
from .min_norm import min_norm


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
def active_set_start(short, a, free, reachable, extra, mu, mass, shaped, k, lam):
    """``warm_start.active_set_start`` for one element: ``lam`` (3C,) ← the start; ``free``
    (3C,) the free contact velocities (its tangent rows are the slip), A (3C, 3C)."""
    c = short.shape[0]
    size = 3 * c
    goal = np.empty(size)
    for i in range(c):
        goal[3 * i] = short[i]
        goal[3 * i + 1] = -free[3 * i + 1]
        goal[3 * i + 2] = -free[3 * i + 2]
    on = reachable.copy()
    push = 0.0  # PUSH_TOLERANCE × the largest |short| (``warm_start``)
    for i in range(c):
        push = max(push, abs(short[i]))
    push *= PUSH_TOLERANCE
    bound = np.zeros(c, np.bool_)
    direction = np.zeros((c, 2))
    budget = extra > 0
    live = np.empty(size, np.bool_)
    cols = np.empty((size, size))
    rhs = np.empty(size)
    known = np.zeros(size)
    nxt = np.empty(c, np.bool_)
    over = np.empty(c, np.bool_)
    index = np.empty(size, np.int64)
    m = np.empty((size, size))
    sub_rhs = np.empty(size)
    sub_x = np.empty(size)
    work = np.empty((3, size, size))
    settled = False
    for _ in range(ROUNDS):
        for i in range(c):
            live[3 * i] = on[i]
            tangent = (on[i] or budget[i]) and mu[i] > 0 and not bound[i]
            live[3 * i + 1] = tangent
            live[3 * i + 2] = tangent
        # Columns: a contact at the cone's boundary acts through n + μ d·t.
        for i in range(size):
            for j in range(size):
                cols[i, j] = a[i, j]
        symmetric = True
        for j in range(c):
            if bound[j] and live[3 * j]:
                symmetric = False
            mix0 = (mu[j] * bound[j]) * direction[j, 0]
            mix1 = (mu[j] * bound[j]) * direction[j, 1]
            for i in range(size):
                cols[i, 3 * j] += cols[i, 3 * j + 1] * mix0
            for i in range(size):
                cols[i, 3 * j] += cols[i, 3 * j + 2] * mix1
        # The budget's part of a boundary contact's friction, μ d extra, is known.
        for i in range(c):
            kn = mu[i] * extra[i]
            known[3 * i + 1] = kn * direction[i, 0] if bound[i] else 0.0
            known[3 * i + 2] = kn * direction[i, 1] if bound[i] else 0.0
        for i in range(size):
            acc = 0.0
            for j in range(size):
                acc += a[i, j] * known[j]
            rhs[i] = goal[i] - acc if live[i] else 0.0
        # The live rows' system, solved for its minimum-norm solution; dead rows get zero.
        count = 0
        for i in range(size):
            if live[i]:
                index[count] = i
                count += 1
        sub = m[:count, :count]
        for i in range(count):
            sub_rhs[i] = rhs[index[i]]
            for j in range(count):
                sub[i, j] = cols[index[i], index[j]]
        min_norm(sub, sub_rhs[:count], sub_x[:count], symmetric, work[:, :count, :count])
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
            acc = 0.0
            for j in range(size):
                acc += a[3 * i, j] * lam[j]
            nxt[i] = (on[i] and lam[3 * i] > 0) or ((not on[i]) and short[i] - acc > push)
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
    if not settled:
        # An unsettled set's equality solution is no LCP solution: the particle start.
        for i in range(size):
            lam[i] = 0.0
        particle_start(short, mass, shaped, k, lam, 3)
