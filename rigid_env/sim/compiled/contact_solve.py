"""The inelastic solve with friction of one element, and the step's ``ContactReport`` from the
report columns.

The contact solve: projected block Gauss–Seidel to a stated tolerance, per batch element.

Problem (one batch element, contacts i with rows n, t₁, t₂, Delassus A, free velocities b):
find impulses λ with v = b + A λ such that, per contact,

* normal: λ_n ≥ 0, v_n ≥ target, λ_n (v_n − target) = 0 (Signorini; the target is −gap/Δt for a
  speculative contact ahead, 0 for a touching one, or a bounce velocity);
* friction: |λ_t| ≤ μ (λ_n + extra) with λ_t = −μ (λ_n + extra) v_t / |v_t| when sliding, v_t = 0
  when sticking (Coulomb's law with the isotropic cone; ``extra`` is the impact impulse the
  contact already carried this step, see ``contact_impacts``).

Gauss–Seidel visits the contacts in turn (Erleben, "Velocity-based shock propagation for
multibody dynamics animation", ACM TOG 2007; Catto's sequential impulses, GDC 2005): the normal
row by its exact 1-D solve, then the tangent pair by its exact 2-D solve over the friction disk
(``contact_gauss_seidel``: the minimiser in the A_tt metric, not a radial projection, which would skew
the friction away from the sliding direction and turn a box sliding diagonally). Each sweep is a descent step of a convex quadratic over a
product of convex sets, so the iteration converges (Jourdan, Alart & Jean, 1998 for the
frictional case with fixed cone radii).

Newton polish (``converge``): an element still unconverged after a round of ``newton_after``
sweeps is handed to a semi-smooth Newton method on the Alart–Curnier function (``contact_newton``),
and the next round of sweeps goes on from its answer (one sweep, when Newton found the root).
That first sweep judges the polish: if it changes the contact velocities more than the last
sweep before it, λ goes back to where the sweeps had it and the element is not polished again.
With the polish fewer solves stop at their cap, in less time (``docs/performance.md``).

Stopping: a batch element has converged when a whole sweep changes no contact velocity (A Δλ
over the sweep) by more than ``tolerance`` times its velocity scale (the largest free contact
velocity or target of that element; a box–box slot with no contact point has a sentinel target
and counts in no scale, see ``solve``). Converged elements drop out; an element that
reaches ``max_iterations`` is reported (``ContactReport``) and its impulse, if it would add kinetic
energy, is cut back along its own direction (``dissipative``).

Order: free contact velocities and targets (the gaps where the impacts left them, over the
time left), the particle start (or the previous step's impulses, kept in the contact slots'
``WARM`` columns, with ``SolverSettings.warm_start``) probed by one sweep, then rounds of
Gauss–Seidel with Newton polishes (``contact_newton.converge``) from the particle start or
from the active-set start (``SolverSettings.start``), and an unconverged impulse cut back so
it adds no kinetic energy (``dissipative``). A cached ``solve`` is recompiled when any
simulator source changes (``cache.py``), so an edit of ``contact_starts`` reaches it.
"""

from __future__ import annotations

import numpy as np

from ..contacts.assembly import FAR_GAP
from ..contacts.stages import REPORT_KEY, ContactReport, warn_capped
from .cache import njit
from .contact_assembly import (
    F_DT,
    F_TOLERANCE,
    I_GROUND,
    I_K,
    I_MAX_ITERATIONS,
    I_N,
    I_NEWTON_AFTER,
    I_NEWTON_STEPS,
    I_PARTICLE,
    I_WARM,
    O_ROUND,
    O_SPIN,
    add_impulses,
    assemble_pair,
    block,
    contact_data,
    contact_velocity,
    delassus,
    load_velocities,
    offsets,
    scaled_velocity,
    solver_views,
    store_velocities,
)
from .contact_gauss_seidel import WORK_PER_CONTACT, gauss_seidel
from .contact_newton import converge
from .contact_starts import active_set_start, particle_start
from .layout import (
    ARM,
    ARM_B,
    CAPPED,
    CONTACT,
    ELAPSED,
    ENERGY_REMOVED,
    ENGAGED,
    IMPACTS,
    IMPULSE,
    ITERATIONS,
    JT,
    JT_B,
    NEWTON,
    PATH_GAP,
    REPORT,
    TOUCHED,
    UNPAID_ENERGY,
    WARM,
    WARM_OK,
    WARMED,
)
from .registry import Kernel, register


@njit(cache=True, error_model="numpy")
def dissipative(st, e, cs, owner, owner_b, mass, linv, u, lam):
    """scale λ to the most dissipative point of its ray if it would
    add kinetic energy (z = M^(1/2) u, dz = J̃ᵀ λ)."""
    n = u.shape[0]
    z = np.empty((n, 6))
    scaled_velocity(st, e, mass, linv, u, z)
    lin = 0.0
    quad = 0.0
    zz = 0.0
    for b in range(n):
        for k in range(6):
            dz = 0.0
            for c in range(owner.shape[0]):
                col = JT if owner[c] == b else (JT_B if owner_b[c] == b else -1)
                if col >= 0:
                    for r in range(3):
                        dz += lam[3 * c + r] * cs[c, col + 6 * r + k]
            lin += z[b, k] * dz
            quad += dz * dz
            zz += z[b, k] * z[b, k]
    if lin + 0.5 * quad > 1e-12 * zz:
        s = min(max(-lin / (quad if quad > 0 else 1.0), 0.0), 1.0)
        for i in range(lam.shape[0]):
            lam[i] *= s


@njit(cache=True, error_model="numpy", inline="always")
def reach_bound(cs, i, a, b, rim, spin, speed):
    """A bound on contact i's normal speed after the solve: the solve adds no kinetic energy,
    so each body's scaled velocity z_b = M_b^(1/2) u_b stays within |z| (``speed``, of the
    velocities it starts from), |v_b| ≤ |z| / √m_b and |ω_b| ≤ ‖L_b‖₂ |z| (L Lᵀ = M0⁻¹), and
    a contact point moves at most |v_b| + |ω_b| |r| (both bodies' for a body–body contact)."""
    arm = (cs[i, ARM], cs[i, ARM + 1], cs[i, ARM + 2])
    bound = rim[a] + spin[a] * np.sqrt(arm[0] * arm[0] + arm[1] * arm[1] + arm[2] * arm[2])
    if b >= 0:
        arm = (cs[i, ARM_B], cs[i, ARM_B + 1], cs[i, ARM_B + 2])
        bound += rim[b] + spin[b] * np.sqrt(arm[0] * arm[0] + arm[1] * arm[1] + arm[2] * arm[2])
    return speed * bound


@njit(cache=True, error_model="numpy")
def reassemble_pairs(pairs, e, st, ints, floats, o, owner, owner_b, u):
    """The pairs' rows where the impacts left the bodies, t₁ from the velocities after them
    (``contact_assembly.assemble_pair``); nothing in a scene without body–body contacts
    (``contact_assembly.PAIRS``)."""
    if pairs is None:
        return
    o_round = o[O_ROUND]
    for i in range(ints[I_GROUND] * ints[I_K], owner.shape[0]):
        round_pair = ints[o_round + i] != 0
        assemble_pair(e, st, floats, o, i, owner[i], owner_b[i], u, True, round_pair)


@njit(cache=True, error_model="numpy")
def solve(e, st, d):
    """``SolveContacts`` for one engaged element; writes ITERATIONS, CAPPED and TOUCHED.

    The solve runs over the contacts that can carry an impulse, not over every slot: a
    contact whose gap exceeds what its points can close over the time left, at the largest
    speed the element's kinetic energy allows (``reach_bound``), meets its target whatever
    the impulses (v_n ≥ −bound > −gap/Δt), so its impulse is zero in every solution. Its row
    would only make the dense system larger: a tower of 8 boxes has 28 box pairs, of which 7
    touch, and a heap of 64 boxes 2016. The stopping tests' scales are over every slot with
    a contact point (see below). Scenes without body–body
    contacts keep every slot: a body has only its K lowest points on the ground, and their
    recorded results stay bit for bit (leaving a slot out changes the stopping test, which
    also watches its row, and the warm start, which starts it from its last impulse)."""
    report = st[REPORT]
    if report[e, ENGAGED] == 0.0:
        st[CONTACT][e, 0, WARM_OK] = 0.0  # the next step starts cold
        return
    ints, floats, pairs = d
    o = offsets(ints)
    mu_all, owner, shaped, mass, rim, lflat, linv, owner_b = solver_views(ints, floats, o)
    n_bodies = ints[I_N]
    spin = floats[o[O_SPIN] : o[O_SPIN] + n_bodies]
    dt = floats[F_DT]
    tolerance = floats[F_TOLERANCE]
    k = ints[I_K]
    cs = st[CONTACT][e]
    c = owner.shape[0]
    n = st[0].shape[1]
    # Every slot's free velocities, impulses, targets, shortfalls and the impacts' impulses.
    # A scene that solves every slot (the docstring: no body–body contacts) solves these
    # vectors themselves, and its A and work space follow them in the same allocation (each
    # allocation costs about as much as a sweep).
    head = 18 * n + 9 * c
    every = np.empty(head + (9 * c * c + WORK_PER_CONTACT * c if pairs is None else 0))
    u = block(every, 0, n, 6)
    u_in = block(every, 6 * n, n, 6)
    z = block(every, 12 * n, n, 6)
    at = 18 * n
    free_all = every[at : at + 3 * c]
    lam_all = every[at + 3 * c : at + 6 * c]
    target_all = every[at + 6 * c : at + 7 * c]
    short_all = every[at + 7 * c : at + 8 * c]
    extra_all = every[at + 8 * c : at + 9 * c]
    load_velocities(st, e, u)
    load_velocities(st, e, u_in)
    remaining = dt - report[e, ELAPSED]
    if report[e, ELAPSED] > 0:
        reassemble_pairs(pairs, e, st, ints, floats, o, owner, owner_b, u)
    for i in range(c):
        for r in range(3):
            free_all[3 * i + r] = contact_velocity(cs, i, owner[i], owner_b[i], u, r)
        gap = cs[i, PATH_GAP]
        target_all[i] = -gap / remaining if gap > 0 else 0.0
        short_all[i] = target_all[i] - free_all[3 * i]
        extra_all[i] = cs[i, IMPULSE]
    # The stopping tests' velocity scale and the active-set start's shortfall scale
    # (``contact_starts.PUSH_TOLERANCE``), over the slots that hold a contact point. A box–box
    # slot with no contact point (separated boxes whose faces do not overlap) has the sentinel
    # gap ``box_box.FAR`` = 1e9 m, which keeps it out of every step's reach with finite
    # arithmetic; its target −FAR/Δt (−2.4e11 m/s at Δt = 1/240 s) is no velocity of the
    # problem. Counted in the scale, it made the stopping test accept any sweep that changed
    # the contact velocities by less than 0.24 m/s, six times a resting stack's free velocity
    # g Δt: a pyramid's particle start passed its probe sweep, the boxes sank into each other
    # and the separation lifted them back a little askew each step. Such a slot's target stays
    # in the problem (it keeps the slot's impulse at 0); only the scales leave it out.
    scale = 0.0
    for row in range(3 * c):
        scale = max(scale, abs(free_all[row]))
    shortfall = 0.0
    for i in range(c):
        if cs[i, PATH_GAP] < FAR_GAP:
            scale = max(scale, abs(target_all[i]))
            shortfall = max(shortfall, abs(short_all[i]))
    scale = max(scale, 1e-300)
    if pairs is None:
        m = c
        slots = owner[:0]  # empty: every slot (``delassus``)
        a = block(every, head, 3 * c, 3 * c)
        work = every[head + 9 * c * c :]
        free, lam, target = free_all, lam_all, target_all
        short, extra, mu = short_all, extra_all, mu_all
    else:
        # The contacts that take part (the docstring): within reach, or holding an impact's
        # impulse.
        scaled_velocity(st, e, mass, linv, u, z)
        energy = 0.0
        for b in range(n):
            for j in range(6):
                energy += z[b, j] * z[b, j]
        speed = np.sqrt(energy) * (1.0 + 1e-9)
        chosen = np.empty(c, np.int64)
        m = 0
        for i in range(c):
            bound = reach_bound(cs, i, owner[i], owner_b[i], rim, spin, speed)
            if extra_all[i] > 0 or cs[i, PATH_GAP] <= remaining * bound:
                chosen[m] = i
                m += 1
        slots = chosen[:m]
        size = 3 * m
        # One scratch allocation for the solve of those, carved into views.
        buf = np.empty(size * size + 2 * size + 4 * m + WORK_PER_CONTACT * m)
        a = block(buf, 0, size, size)
        at = size * size
        free = buf[at : at + size]
        lam = buf[at + size : at + 2 * size]
        at += 2 * size
        target = buf[at : at + m]
        short = buf[at + m : at + 2 * m]
        extra = buf[at + 2 * m : at + 3 * m]
        mu = buf[at + 3 * m : at + 4 * m]
        work = buf[at + 4 * m :]
        for s in range(m):
            i = slots[s]
            for r in range(3):
                free[3 * s + r] = free_all[3 * i + r]
            target[s] = target_all[i]
            short[s] = short_all[i]
            extra[s] = extra_all[i]
            mu[s] = mu_all[i]
    delassus(cs, owner, owner_b, slots, m, 3, a)
    warm = ints[I_WARM] != 0 and cs[0, WARM_OK] != 0.0
    if warm:  # the previous step's answer (``SolverSettings.warm_start``)
        report[e, WARMED] = 1.0
        for s in range(m):
            for r in range(3):
                lam[3 * s + r] = cs[_slot(slots, s), WARM + r]
    else:
        _particle(short_all, mass, shaped, k, lam_all, slots, lam)
    sweeps, converged = gauss_seidel(
        a, free, target, mu, lam, extra, 3, np.int64(1), tolerance, scale, work, np.bool_(False)
    )
    max_iterations = ints[I_MAX_ITERATIONS]
    steps = 0
    if not converged:
        # A warm start that fails its probe goes on as a cold solve (the active-set start
        # sets every entry of lam): warm-started solves are capped no more often.
        if ints[I_PARTICLE] == 0:
            peak = 0.0
            for s in range(m):
                peak = max(peak, max(short[s], 0.0))
            reach = dt * peak
            reachable = np.empty(m, np.bool_)
            for s in range(m):
                reachable[s] = short[s] > 0 or cs[_slot(slots, s), PATH_GAP] <= reach
            if not active_set_start(short, a, free, reachable, extra, mu, lam, shortfall):
                _particle(short_all, mass, shaped, k, lam_all, slots, lam)
        # (the probe's sweep decomposed A_tt into ``work``: True)
        newton_after, newton_steps = ints[I_NEWTON_AFTER], ints[I_NEWTON_STEPS]
        more, converged, steps = converge(
            a, free, target, mu, lam, extra, max_iterations, tolerance, scale, newton_after,
            newton_steps, work, np.bool_(True),
        )  # fmt: skip
        sweeps += more
    if pairs is not None:  # (else lam is lam_all)
        lam_all[:] = 0.0
        for s in range(m):
            for r in range(3):
                lam_all[3 * slots[s] + r] = lam[3 * s + r]
    if ints[I_WARM] != 0:
        for i in range(c):
            for r in range(3):
                cs[i, WARM + r] = lam_all[3 * i + r]
        cs[0, WARM_OK] = 1.0 if converged else 0.0
    if not converged:
        dissipative(st, e, cs, owner, owner_b, mass, linv, u, lam_all)
    add_impulses(st, e, cs, owner, owner_b, lflat, rim, lam_all, 3, u, 1.0)
    store_velocities(st, e, u)
    touched = False
    for i in range(c):
        if extra_all[i] > 0:
            touched = True
    for b in range(n):
        for j in range(6):
            if u[b, j] != u_in[b, j]:
                touched = True
    report[e, TOUCHED] = 1.0 if touched else 0.0
    report[e, ITERATIONS] = sweeps
    report[e, NEWTON] = steps
    if not converged:
        report[e, CAPPED] = 1.0


@njit(cache=True, error_model="numpy", inline="always")
def _slot(slots, s):
    """The slot of the solve's contact s: s itself when ``slots`` is empty (every slot)."""
    return s if slots.shape[0] == 0 else slots[s]


@njit(cache=True, error_model="numpy", inline="always")
def _particle(short_all, mass, shaped, k, lam_all, slots, lam):
    """The ground particle start over every slot (``particle_start``), taken at ``slots``
    (``lam`` is ``lam_all`` when ``slots`` is empty)."""
    lam_all[:] = 0.0
    particle_start(short_all, mass, shaped, k, lam_all, 3)
    for s in range(slots.shape[0]):
        for r in range(3):
            lam[3 * s + r] = lam_all[3 * slots[s] + r]


def report_of(tolerance: float):
    """The ``Kernel.report`` function: ``state.report["contacts"]``, and
    its ``ContactSolverWarning`` when a solve was capped."""

    def report(columns: np.ndarray, counts: np.ndarray | None = None) -> dict:
        if len(columns) == 1:  # batch 1: Python floats, cheaper than five reductions
            row = columns[0].tolist()
            engaged, iterations, impacts = int(row[ENGAGED] > 0), row[ITERATIONS], row[IMPACTS]
            newton, warmed = row[NEWTON], int(row[WARMED] > 0)
            capped, unpaid = int(row[CAPPED] > 0), row[UNPAID_ENERGY]
            touched = np.array([row[TOUCHED] > 0])
            removed = np.array([row[ENERGY_REMOVED]])
            capped_mask = np.array([capped > 0])
        else:
            engaged = int(np.count_nonzero(columns[:, ENGAGED]))
            peak = columns.max(axis=0)
            iterations, impacts, unpaid = peak[ITERATIONS], peak[IMPACTS], peak[UNPAID_ENERGY]
            newton = peak[NEWTON]
            capped = int(np.count_nonzero(columns[:, CAPPED]))
            warmed = int(np.count_nonzero(columns[:, WARMED]))
            touched = columns[:, TOUCHED] > 0
            removed = columns[:, ENERGY_REMOVED].copy()
            capped_mask = columns[:, CAPPED] > 0
        if counts is not None:  # several steps: the most of any one step
            engaged, capped, warmed = (int(m) for m in counts.max(axis=0))
        # ContactReport(...) without the frozen dataclass's nine object.__setattr__ calls
        # (a share of a batch-1 step): the same instance, fields set once.
        out = object.__new__(ContactReport)
        if engaged == 0:
            iterations = impacts = unpaid = newton = 0.0
        out.__dict__.update(
            engaged=engaged,
            iterations=int(iterations),
            impacts=int(impacts),
            newton=int(newton),
            capped=capped,
            warm_started=warmed,
            tolerance=tolerance,
            unpaid_energy=float(unpaid),
            touched=touched,
            energy_removed=removed,
            capped_mask=capped_mask,
        )
        if capped:
            # warn_capped ← report ← Driver.report ← Scene._compiled_step ← Scene.step ← caller
            warn_capped(stacklevel=6)
        return {REPORT_KEY: out}

    return report


@register("solve_contacts")
def _solve_contacts(scene):
    data = contact_data(scene)
    if data is None:
        return None
    return Kernel(__name__, "solve", data, report=report_of(float(data[1][F_TOLERANCE])))
