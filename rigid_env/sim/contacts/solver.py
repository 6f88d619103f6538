"""Contact impulses: projected Jacobi with mass splitting on the Delassus matrix, Coulomb
friction and Newton restitution.

The notes' impulse ("Impacto"): at a contact with normal n and arms r_a, r_b, an impulse j n
changes the normal relative velocity by j (1/m_a + 1/m_b + nᵀ(M_a⁻¹(r_a×n))×r_a + …); the
ground is body b with infinite mass (its terms vanish). Every contact point of the scene has
three rows (normal, two tangents) in one Jacobian J (…, 3C, 6n); the Delassus matrix
A = J M⁻¹ Jᵀ (…, 3C, 3C) is built once per step, so an iteration is one small mat-vec
c = b + A λ and a few element-wise clamps over all contacts and the whole batch at once.

The iteration is projected Jacobi with mass splitting (Tonge, English, Catto & Pasquale,
"Mass splitting for jitter-free parallel rigid body simulation", SIGGRAPH 2012): a contact on
bodies touched by K candidate contacts takes 1/K of its own correction (ground-only scenes). With
the rows scaled one by one, Cauchy–Schwarz bounds the scaled A's eigenvalues by the number of
rows on a body, up to 3K with friction; scenes with body–body contacts therefore relax each row
by the inverse of its Gershgorin row sum over the rows that can carry load, which keeps the
iteration from overshooting (``_row_steps``). Unlike Gauss–Seidel it favours no contact, so a
symmetric landing stays symmetric (no spin). It stops as soon as no impulse changes by more
than a relative 1e-13 anywhere in the batch.

A step (semi-implicit Euler: forces → velocities → contacts → positions):

1. *Main pass* on the post-force velocities u₁: normal target ``v_n ≥ −d/Δt`` for a gap d > 0
   (speculative contact: the body may close the gap this step, no more — no tunnelling), and
   ``v_n ≥ 0`` for d ≤ 0. Friction ("Fricción"): per contact, the tangential impulse that
   cancels the sliding velocity, in two rows each clamped to ``|j_t| ≤ μ j_n``; the first row
   is along the sliding direction, so there the law is Coulomb's exactly, the impulse opposes
   sliding and never reverses it (across it, the pyramid admits up to √2 μ j_n in total).
   Ground manifolds start from the impulse that stops the body as a particle, shared equally
   by the violated corners: exact for a box resting or landing flat, so resting is a fixed
   point of the step (no jitter, creep or sinking). An exact solution removes kinetic energy
   (``_dissipative``); an impulse that would add some is cut back along its own direction.
2. Positions drift with the solved velocities: the integrator's position update runs after the
   solve (x ← x₀ + Δt v_s), plus the projection of step 4 as its displacement.
3. *Restitution pass* (velocities only, Box2D v3's ``applyRestitution``): a contact that carried
   impulse and was approached faster than the material's threshold gets ``v_n = −ε v_impact``.
   The impact speed is the normal approach speed interpolated to the instant the gap closes
   under constant normal acceleration, ``v_impact² = v_n0² − 2 a d`` with a = (v_n1 − v_n0)/Δt,
   so that a ball dropped with ε = 1 leaves the ground with the speed it hit it.
4. Energy guard: if the restitution impulse would leave more kinetic energy than the step had
   before contact (Newton's law can do so at simultaneous contacts), it is scaled down until it
   does not. Positions are never pushed apart by velocity: any remaining penetration is removed
   by moving the body (projection), which changes no velocity and so adds no kinetic energy.
"""

from __future__ import annotations

import numpy as np

from ..rotation import cross, quat_to_matrix

MAX_ITERATIONS = 20
RELATIVE_TOLERANCE = 1e-13
WARM_ROUNDS = 6  # active-set rounds of the coupled warm start (a stack of two needs 2–3)
_UP = np.array([0.0, 0.0, 1.0])
_NO_BOUNCE = -1e30  # restitution target of contacts that do not bounce: never binding


def _tangents(n, vrel, vn):
    """Sliding direction t1 (any perpendicular when not sliding) and t2 = n × t1."""
    vt = vrel - vn[..., None] * n
    speed = np.linalg.norm(vt, axis=-1, keepdims=True)
    helper = np.where(np.abs(n[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    perp = helper - np.sum(helper * n, axis=-1, keepdims=True) * n
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    t1 = np.where(speed > 1e-9, vt / np.where(speed > 1e-9, speed, 1.0), perp)
    return t1, cross(n, t1)


class _Layout:
    """Static bookkeeping of the scene's contact points, computed once.

    Ground slots come first (G bodies × K slots, contiguous per body), then each pair group's
    slots (P pairs × S slots). ``a``/``b`` are the body indices per contact (b = −1: ground).
    """

    def __init__(self, model, ground, pairs):
        n = model.n_bodies
        a, b, mu, eps, thr = [], [], [], [], []
        self.n_ground = 0
        if ground is not None:
            self.ground_bodies = ground.bodies
            self.k = ground.k
            self.n_ground = len(ground.bodies) * ground.k
            a.append(np.repeat(ground.bodies, ground.k))
            b.append(np.full(self.n_ground, -1))
            g = model.ground
            for lst, val in (
                (mu, g.friction),
                (eps, g.restitution),
                (thr, g.restitution_threshold),
            ):
                lst.append(np.full(self.n_ground, val))
        if pairs is not None:
            m = model.contacts
            for pa, pb, _, slots in pairs.groups:
                a.append(np.repeat(pa, slots))
                b.append(np.repeat(pb, slots))
                size = len(pa) * slots
                for lst, val in (
                    (mu, m.friction),
                    (eps, m.restitution),
                    (thr, m.restitution_threshold),
                ):
                    lst.append(np.full(size, val))
        self.a, self.b = np.concatenate(a), np.concatenate(b)
        self.mu, self.eps = np.concatenate(mu), np.concatenate(eps)
        self.threshold = np.concatenate(thr)
        self.c = len(self.a)
        self.pair_slice = slice(self.n_ground, self.c)
        self.pb = self.b[self.n_ground :]
        self.pa = self.a[self.n_ground :]
        # Incidence (C, n): which bodies each contact touches (for the mass-splitting counts).
        self.incidence = np.zeros((self.c, n))
        self.incidence[np.arange(self.c), self.a] = 1.0
        has_b = self.b >= 0
        self.incidence[np.arange(self.c)[has_b], self.b[has_b]] = 1.0
        self.single_body = n == 1
        # Projection shares (P, n): pair p moves a by +m_b/(m_a+m_b) of its push, b by −m_a/….
        rows = []
        if pairs is not None:
            for pa, pb, _, _ in pairs.groups:
                for i, j in zip(pa, pb, strict=True):
                    row = np.zeros(n)
                    ma, mb = model.mass[i], model.mass[j]
                    row[i], row[j] = mb / (ma + mb), -ma / (ma + mb)
                    rows.append(row)
        self.pair_share = np.array(rows).reshape(len(rows), n)


class ContactStage:
    """The contact response between a semi-implicit step's velocity and position updates
    (``respond``); ``contacts.stages`` wires it into the pipeline."""

    def __init__(self, model, dt, ground=None, pairs=None, iterations=MAX_ITERATIONS):
        self.model, self.dt, self.ground, self.pairs = model, dt, ground, pairs
        self.iterations = iterations
        self.layout = _Layout(model, ground, pairs)
        # Square roots of the inverse mass matrix: 1/√m and L with L Lᵀ = M0⁻¹ (body axes).
        self.root_inv_mass = 1.0 / np.sqrt(model.mass)
        self.root_inv_inertia = np.linalg.cholesky(model.inv_inertia)
        self.root_inertia = np.linalg.inv(self.root_inv_inertia)  # L⁻¹

    # --- assembly -------------------------------------------------------------------------------

    def _assemble(self, ground_hits, pair_hits):
        """Arms, normals and gaps of all contacts, (…, C, ·); arm_b for the pair slots only.

        ``ground_hits`` is ``GroundContacts.detect``'s (arm, gap) or None, ``pair_hits``
        ``PairContacts.detect``'s list or None (the collide stages' results)."""
        arms, normals, gaps, arm_b = [], [], [], None
        if ground_hits is not None:
            arm, gap = ground_hits
            batch = gap.shape[:-2]
            arms.append(arm.reshape(*batch, -1, 3))
            gaps.append(gap.reshape(*batch, -1))
            normals.append(np.broadcast_to(_UP, arms[-1].shape))
        if pair_hits is not None:
            arm_bs = []
            for _, _, arm_a, arm_bb, n, gap in pair_hits:
                batch = gap.shape[:-2]
                arms.append(arm_a.reshape(*batch, -1, 3))
                arm_bs.append(arm_bb.reshape(*batch, -1, 3))
                normals.append(n.reshape(*batch, -1, 3))
                gaps.append(gap.reshape(*batch, -1))
            arm_b = arm_bs[0] if len(arm_bs) == 1 else np.concatenate(arm_bs, axis=-2)
        if len(arms) == 1:
            return arms[0], arm_b, normals[0], gaps[0]
        cat = np.concatenate
        return cat(arms, -2), arm_b, cat(normals, -2), cat(gaps, -1)

    def _scaled_jacobian(self, basis, arm_a, arm_b, scale):
        """J M^(-1/2) (N, 3C, 6n): with it, A = J M⁻¹ Jᵀ = J̃ J̃ᵀ and Δu = M^(-1/2) J̃ᵀ λ.

        ``scale`` (N, n, 3, 3) is R L with L Lᵀ = M0⁻¹ (body axes), so that the angular rows
        (r × b)ᵀ R L give (r × b)ᵀ M⁻¹ (r × b) = |row|²; the linear rows are b / √m.
        """
        lay, n_rows = self.layout, 3 * self.layout.c
        rxb = cross(arm_a[..., None, :], basis)  # (N, C, 3, 3)
        if lay.single_body:
            ang = rxb.reshape(-1, n_rows, 3) @ scale[:, 0]
            lin = basis.reshape(-1, n_rows, 3) * self.root_inv_mass[0]
            return np.concatenate((lin, ang), axis=-1)
        ja = np.concatenate(
            (basis * self.root_inv_mass[lay.a, None, None], rxb @ scale[:, lay.a]), axis=-1
        )
        jz = np.zeros((len(basis), lay.c, self.model.n_bodies, 3, 6))
        jz[:, np.arange(lay.c), lay.a] = ja
        if arm_b is not None:
            bp = basis[:, lay.pair_slice]
            rxb_b = cross(arm_b[..., None, :], bp)
            jb = np.concatenate(
                (bp * self.root_inv_mass[lay.pb, None, None], rxb_b @ scale[:, lay.pb]), axis=-1
            )
            jz[:, np.arange(lay.n_ground, lay.c), lay.pb] = -jb
        return np.swapaxes(jz, -3, -2).reshape(len(basis), n_rows, -1)

    # --- the stage ------------------------------------------------------------------------------

    def respond(self, start, v1, w1, ground_hits=None, pair_hits=None):
        """The contact response of one step, or ``None`` when no contact is within reach.

        ``start`` is the step's input :class:`State` (restitution reads its velocities), (v1, w1)
        the post-force velocities, the hits detected at the start positions flattened to one
        batch axis ``(N, n, ·)`` (see ``contacts.stages``). Returns
        ``(v, w, shift, v_out, w_out)`` in the batch shape: the main pass's velocities, which
        the positions drift with, the translation that removes the remaining penetration, and
        the velocities after the restitution pass (the step's final ones).
        """
        dt, lay = self.dt, self.layout
        n = self.model.n_bodies
        batch = start.position.shape[:-2]
        flat = [a.reshape(-1, n, a.shape[-1]) for a in (*start.arrays(), v1, w1)]
        arm_a, arm_b, normal, gap = self._assemble(ground_hits, pair_hits)
        u1 = np.concatenate(flat[4:], axis=-1)  # (N, n, 6)
        ua = u1 if lay.single_body else u1[:, lay.a]
        vrel = ua[..., :3] + cross(ua[..., 3:], arm_a)
        if arm_b is not None:
            ub = u1[:, lay.pb]
            vrel[:, lay.pair_slice] -= ub[..., :3] + cross(ub[..., 3:], arm_b)
        vn1 = np.sum(vrel * normal, axis=-1)
        # Only batch elements with a contact within reach this step pay for the solve.
        engaged = np.any(gap + dt * np.minimum(vn1, 0.0) < 0, axis=-1)
        if not engaged.any():
            return None
        if engaged.all():
            result = self._solve(flat, u1, arm_a, arm_b, normal, gap, vrel, vn1)
        else:
            sub = np.flatnonzero(engaged)
            part = self._solve(
                [a[sub] for a in flat],
                u1[sub],
                arm_a[sub],
                None if arm_b is None else arm_b[sub],
                normal[sub],
                gap[sub],
                vrel[sub],
                vn1[sub],
            )
            v, w = flat[4:]
            result = [np.array(v), np.array(w), np.zeros_like(v), np.array(v), np.array(w)]
            for full, got in zip(result, part, strict=True):
                full[sub] = got
        return tuple(a.reshape(*batch, n, a.shape[-1]) for a in result)

    def _solve(self, flat, u1, arm_a, arm_b, normal, gap, vrel, vn1):
        dt, lay, model = self.dt, self.layout, self.model
        x0, q0, v0, w0, v1, w1 = flat
        size, n6 = len(gap), 6 * model.n_bodies
        t1, t2 = _tangents(normal, vrel, vn1)
        basis = np.stack((normal, t1, t2), axis=-2)  # (N, C, 3, 3)
        scale = quat_to_matrix(q0) @ self.root_inv_inertia  # R L, (N, n, 3, 3)
        jt = self._scaled_jacobian(basis, arm_a, arm_b, scale)  # (N, 3C, 6n)
        rows = jt.reshape(size, lay.c, 3, n6)
        diag = np.sum(rows * rows, axis=-1)  # (N, C, 3): the Delassus diagonal
        coupling = np.sum(rows[:, :, 1:] * rows[:, :, :1], axis=-1)  # A_tn within a contact
        free = np.concatenate(
            (vn1[..., None], np.sum(vrel[..., None, :] * basis[:, :, 1:], -1)), -1
        )

        target = np.where(gap > 0, -gap / dt, 0.0)
        short = target - vn1
        if self.pairs is None:
            lam = np.zeros((size, lay.c, 3))
            self._warm_start(lam[..., 0], short)
            omega = np.broadcast_to(self._splitting(short > 0)[..., None], (size, lay.c, 3))
        else:
            # Contacts that can carry load this step: the violated ones and those the step's
            # largest velocity correction could close (see ``_coupled_start``).
            reach = dt * np.max(np.maximum(short, 0.0), axis=-1, keepdims=True)
            reachable = (short > 0) | (gap <= reach)
            delassus = jt @ np.swapaxes(jt, -1, -2)
            lam = self._coupled_start(short, delassus, free[..., 1:], reachable=reachable)
            omega = self._row_steps(reachable, delassus, diag)
        lam = self._main_pass(lam, jt, free, target, omega, diag, coupling)
        dz = lam.reshape(size, 1, -1) @ jt  # (N, 1, 6n): J̃ᵀ λ
        lam, dz = self._dissipative(lam, dz, self._scaled_velocity(u1, q0))

        vel = free + (jt @ dz.reshape(size, n6, 1)).reshape(size, lay.c, 3)
        u = u1 + self._velocity_change(dz, scale)
        shift = self._project(np.zeros_like(v1), gap + dt * vel[..., 0], normal)
        u0 = np.concatenate((v0, w0), axis=-1)
        out = self._restitute(u, u1, u0, q0, lam[..., 0], vn1, gap, vel[..., 0], jt, scale, diag)
        return u[..., :3], u[..., 3:], shift, out[..., :3], out[..., 3:]

    @staticmethod
    def _dissipative(lam, dz, z1):
        """Main-pass energy guard. With z = M^(1/2) u, KE = ½|z|² and the impulse moves z by
        dz = J̃ᵀ λ, so ΔKE = λᵀ v⁺ − ½ λᵀ A λ (v⁺ the contact velocities after it). At a solution
        every term of λᵀ v⁺ is ≤ 0 (λ_n > 0 only where v_n⁺ = target ≤ 0; friction at its bound
        opposes v_t⁺, below it v_t⁺ = 0): the pass can only remove energy. An impulse that adds
        some is no solution (an unconverged iteration); it is scaled to the most dissipative
        point of its own ray, s = −z₁·dz / |dz|² ∈ [0, 1] (s = 1 for a plastic stop)."""
        lin = np.sum(z1[..., 0] * dz[:, 0], axis=-1)
        quad = np.sum(dz[:, 0] ** 2, axis=-1)
        gains = lin + 0.5 * quad > 1e-12 * np.sum(z1[..., 0] ** 2, axis=-1)
        if not np.any(gains):
            return lam, dz
        s = np.where(gains, np.clip(-lin / np.where(quad > 0, quad, 1.0), 0.0, 1.0), 1.0)
        return lam * s[:, None, None], dz * s[:, None, None]

    def _velocity_change(self, dz, scale):
        """Δu = M^(-1/2) J̃ᵀ λ from dz = J̃ᵀ λ (N, 1, 6n): Δv = dz_v / √m, Δω = R L dz_ω."""
        dz = dz.reshape(len(dz), -1, 6)
        dv = dz[..., :3] * self.root_inv_mass[:, None]
        dw = (scale @ dz[..., 3:, None])[..., 0]
        return np.concatenate((dv, dw), axis=-1)

    def _row_steps(self, reachable, delassus, diag):
        """Per-row relaxation (N, C, 3) of scenes with body–body contacts: 1 / Σ_j |Â_ij|, the
        row sums of the diagonally scaled Delassus matrix Â = D^(-1/2) A D^(-1/2) over the rows
        that can carry load (normal rows of reachable contacts, their tangent rows if μ > 0).

        Mass splitting's 1/K bounds Â's spectrum only when each contact's 3×3 block is the
        identity; the rows here are scaled one by one, and a pair row couples two bodies, so a
        body with K contacts can give Â an eigenvalue up to 3K and the 1/K-relaxed Jacobi
        overshoots and diverges (a tilted box landing on another gained 4 J in one step). With
        W = diag(1/row sum), every Gershgorin disc of W Â lies in [0, 1]: the spectral radius
        of I − W Â is at most 1 on those rows, so the iteration cannot overshoot."""
        lay = self.layout
        size, c = reachable.shape
        live = np.broadcast_to(reachable[..., None], (size, c, 3)).copy()
        live[..., 1:] &= (lay.mu > 0)[:, None]
        live = live.reshape(size, -1)
        root = np.sqrt(diag.reshape(size, -1))
        scaled = np.abs(delassus) / root[:, :, None] / root[:, None, :]
        rowsum = np.sum(np.where(live[:, None, :], scaled, 0.0), axis=-1)
        rowsum = np.where(live, rowsum, rowsum + 1.0)  # a row not counted still sees itself
        return (1.0 / np.maximum(rowsum, 1.0)).reshape(size, c, 3)

    def _splitting(self, candidate):
        """Per contact 1/K, K the most candidate contacts on either of its bodies (≥ 1)."""
        lay = self.layout
        cand = candidate.astype(float)
        if lay.single_body:
            count = np.sum(cand, axis=-1, keepdims=True)
        else:
            per_body = cand @ lay.incidence  # (…, n)
            count = per_body[..., lay.a]
            if lay.c > lay.n_ground:
                count[..., lay.pair_slice] = np.maximum(
                    count[..., lay.pair_slice], per_body[..., lay.pb]
                )
        return 1.0 / np.maximum(count, 1.0)

    def _warm_start(self, lam_n, short):
        """Ground only: start each manifold from the impulse that stops its body as a particle,
        shared equally by its violated slots: exact for a box resting or landing flat (corners
        symmetric about the centre of mass), so the iteration starts at the answer there and
        only polishes elsewhere. Writes into ``lam_n`` (…, C)."""
        lay = self.layout
        if lay.n_ground == 0:
            return
        g = len(lay.ground_bodies)
        s = short[..., : lay.n_ground].reshape(*short.shape[:-1], g, lay.k)
        violated = s > 0
        count = np.sum(violated, axis=-1, keepdims=True)
        mass = self.model.mass[lay.ground_bodies]
        need = mass[:, None] * np.max(np.where(violated, s, 0.0), axis=-1, keepdims=True)
        share = np.where(violated, need / np.maximum(count, 1), 0.0)
        lam_n[..., : lay.n_ground] = share.reshape(*short.shape[:-1], -1)

    def _coupled_start(self, short, a_full, slip=None, grow=True, reachable=None):
        """Warm start of scenes with body–body contacts, (N, C, 3), or (N, C) normal-only when
        ``slip`` (the free tangential velocities, (N, C, 2)) is None; ``a_full`` is the
        Delassus matrix of the rows solved, (N, 3C, 3C) or (N, C, C).

        Impulses couple through the bodies (a stack's lower box carries the upper one) and a
        heavy box on a light one (mass ratio 10³) needs its torques balanced to rounding, which
        Jacobi does not reach in its budget: the residual grows from step to step. So the
        contacts are solved directly as equalities (normal: the target; tangents: sticking) on
        an active set (the simplest pivoting for the LCP, cf. Baraff 1994): start from the
        violated contacts, solve by pseudo-inverse (redundant supports, e.g. the four corners
        of a face, get the minimum-norm, symmetric share), clamp λ_n ≥ 0 and λ_t into the
        friction cone, drop contacts that pull, add those the impulses push in (``grow``);
        a few rounds. Exact for resting and sticking stacks; the iteration polishes the rest."""
        lay = self.layout
        size, c = short.shape
        rows = 1 if slip is None else 3
        goal = short[..., None] if slip is None else np.concatenate((short[..., None], -slip), -1)
        goal = goal.reshape(size, -1)
        row_used = np.ones((c, rows), bool)
        row_used[:, 1:] = (lay.mu > 0)[:, None]
        eye = np.eye(rows * c)
        # Start from every contact that could carry load this step: the violated ones, and those
        # the step's largest velocity correction could close, gap ≤ Δt max(short⁺). Starting
        # from the violated ones only misses resting contacts whose velocity is rounding noise
        # of the previous solve (±1e-13 m/s at mass ratio 10³, ±1e-5 at 10⁶: the error of a
        # solve at cond(A) ≈ ratio²): a face with 1 or 2 of its 4 corners on, sticking, needs
        # pulls, and the rounds never settle (a 3-box stack at 10³ got 10⁴ N·s instead of 170).
        on = short > 0 if reachable is None else reachable
        settled = np.zeros(size, bool)
        for _ in range(WARM_ROUNDS):
            live = (on[..., None] & row_used).reshape(size, -1)
            a = np.where(live[..., :, None] & live[..., None, :], a_full, 0.0)
            a += np.where(live, 0.0, 1.0)[..., None] * eye
            lam = (np.linalg.pinv(a) @ np.where(live, goal, 0.0)[..., None]).reshape(size, c, rows)
            lam_n = np.where(on, np.maximum(lam[..., 0], 0.0), 0.0)
            if rows == 3:
                norm = np.linalg.norm(lam[..., 1:], axis=-1)
                cap = lay.mu * lam_n
                shrink = np.where(norm > cap, cap / np.where(norm > 0, norm, 1.0), 1.0)
                lam = np.concatenate((lam_n[..., None], lam[..., 1:] * shrink[..., None]), -1)
            else:
                lam = lam_n[..., None]
            nxt = on & (lam_n > 0)
            if grow:
                pushed = (a_full @ lam.reshape(size, -1, 1)).reshape(size, c, rows)[..., 0]
                nxt |= ~on & (short - pushed > 0)
            settled = np.all(nxt == on, axis=-1)
            if settled.all():
                break
            on = np.where(settled[:, None], on, nxt)
        if not settled.all():
            # An unsettled set's equality solution is no LCP solution (it can be 100× the load):
            # those elements start the iteration from the ground particle start instead.
            fallback = np.zeros((size, c, rows))
            self._warm_start(fallback[..., 0], short)
            lam = np.where(settled[:, None, None], lam, fallback)
        return lam if rows == 3 else lam[..., 0]

    def _converge(self, update, lam, *data):
        """Iterate ``lam ← update(lam, *data)`` per batch element until none of its impulses
        changes by more than a relative ``RELATIVE_TOLERANCE``; converged elements drop out, so
        an element's result does not depend on the rest of the batch and a body at rest (whose
        warm start is already the answer) costs one iteration."""
        out, idx, arrays = lam, None, (lam, *data)
        axes = tuple(range(1, lam.ndim))
        for _ in range(self.iterations):
            new = update(*arrays)
            change = np.max(np.abs(new - arrays[0]), axis=axes)
            going = change > RELATIVE_TOLERANCE * np.max(np.abs(new), axis=axes)
            if idx is None:
                out = new
            else:
                out[idx] = new
            if not going.any():
                break
            if going.all():
                arrays = (new, *arrays[1:])
            else:
                keep = np.flatnonzero(going)
                idx = keep if idx is None else idx[keep]
                arrays = (new[keep], *(a[keep] for a in arrays[1:]))
        return out

    def _main_pass(self, lam, jt, free, target, omega, diag, coupling):
        """Projected Jacobi: normal rows, then the two friction rows seeing that normal update."""
        c, mu = self.layout.c, self.layout.mu

        def update(lam, jt, free, target, step_n, step_t, coupling):
            dz = lam.reshape(len(lam), 1, 3 * c) @ jt
            vel = free + (jt @ np.swapaxes(dz, -1, -2)).reshape(len(lam), c, 3)
            lam_n = np.maximum(lam[..., 0] + step_n * (target - vel[..., 0]), 0.0)
            vt = vel[..., 1:] + coupling * (lam_n - lam[..., 0])[..., None]
            limit = (mu * lam_n)[..., None]
            lam_t = np.clip(lam[..., 1:] - step_t * vt, -limit, limit)
            return np.concatenate((lam_n[..., None], lam_t), axis=-1)

        step_n, step_t = omega[..., 0] / diag[..., 0], omega[..., 1:] / diag[..., 1:]
        return self._converge(update, lam, jt, free, target, step_n, step_t, coupling)

    def _project(self, x, end_gap, normal):
        """Remove penetration left after the step by moving bodies along the normal."""
        lay = self.layout
        depth = -end_gap  # linearised end-of-step penetration (…, C)
        if not np.any(depth > 0):
            return x
        x = np.array(x)
        if lay.n_ground:
            g = len(lay.ground_bodies)
            dg = depth[..., : lay.n_ground].reshape(*depth.shape[:-1], g, lay.k)
            lift = np.maximum(np.max(dg, axis=-1), 0.0)  # (…, G)
            if lay.single_body:
                x[..., 2] += lift
            else:
                x[..., lay.ground_bodies, 2] += lift
        if lay.c > lay.n_ground:
            # One push per pair, its deepest slot, split by mass (momentum unchanged).
            pushes, offset = [], lay.n_ground
            for pa, _, _, slots in self.pairs.groups:
                sl = slice(offset, offset + len(pa) * slots)
                offset = sl.stop
                d = depth[..., sl].reshape(*depth.shape[:-1], len(pa), slots)
                n = normal[..., sl, :][..., ::slots, :]
                pushes.append(np.maximum(np.max(d, axis=-1), 0.0)[..., None] * n)
            push = pushes[0] if len(pushes) == 1 else np.concatenate(pushes, axis=-2)
            x += np.einsum("pn,...pk->...nk", lay.pair_share, push)
        return x

    def _restitute(self, u, u1, u0, q0, lam_n, vn1, gap, start, jt, scale, diag):
        lay, dt = self.layout, self.dt
        size = len(gap)
        vn0 = (jt[:, 0::3] @ self._scaled_velocity(u0, q0))[..., 0]
        # Semi-implicit velocities are step means: v₀ ≈ v(t₀ − Δt/2), v₁ ≈ v(t₀ + Δt/2).
        accel = (vn1 - vn0) / dt
        v_mid = 0.5 * (vn0 + vn1)
        v_end = v_mid + accel * dt  # v(t₀ + Δt): the impact lies between
        lo = np.minimum(v_mid**2, v_end**2)
        hi = np.maximum(v_mid**2, v_end**2)
        v_impact = -np.sqrt(np.clip(v_mid**2 - 2 * accel * np.maximum(gap, 0.0), lo, hi))
        # The stored velocity after the step is v(t₁ − Δt/2) on the outgoing trajectory,
        # which leaves the contact at t₁ with −ε v_impact: hence the −a Δt/2.
        out = -lay.eps * v_impact - 0.5 * accel * dt
        bouncing = (lam_n > 0) & (v_impact < -lay.threshold) & (lay.eps > 0) & (vn1 < 0)
        if not np.any(bouncing):
            return u
        goal = np.where(bouncing, out, _NO_BOUNCE)
        jn = jt[:, 0::3]  # normal rows (N, C, 6n)
        if self.pairs is None:
            lam = np.zeros((size, lay.c))
            self._warm_start(lam, np.where(bouncing, out - start, -1.0))
        else:
            delassus = jn @ np.swapaxes(jn, -1, -2)
            lam = self._coupled_start(np.where(bouncing, out - start, -1.0), delassus, grow=False)
        step = self._splitting(bouncing) / diag[..., 0]

        def update(lam, jn, start, goal, step):
            vn = start + (jn @ (lam[:, None, :] @ jn).reshape(len(lam), -1, 1))[..., 0]
            return np.maximum(lam + step * (goal - vn), 0.0)

        sub = np.flatnonzero(np.any(bouncing, axis=-1))  # only bouncing elements iterate
        lam[sub] = self._converge(update, lam[sub], jn[sub], start[sub], goal[sub], step[sub])
        before = u
        delta = self._velocity_change(lam[:, None, :] @ jn, scale)
        # Energy guard: KE(before + s Δ) <= KE(u1) with the largest s in [0, 1].
        rot = quat_to_matrix(q0)
        inertia = rot @ self.model.inertia @ np.swapaxes(rot, -1, -2)
        m = self.model.mass[:, None]

        def dot_m(p, r):
            lin = np.sum(m * p[..., :3] * r[..., :3], axis=(-1, -2))
            ang = np.einsum("...i,...ij,...j->...", p[..., 3:], inertia, r[..., 3:]).sum(-1)
            return lin + ang

        # Allowance: one more step of the non-contact forces (2u₁ − u₀), the size of the
        # half-step offsets above; a genuine multi-contact energy gain is larger and is cut.
        ke_in = np.maximum(dot_m(u1, u1), dot_m(2 * u1 - u0, 2 * u1 - u0))
        limit = 0.5 * ke_in * (1 + 1e-12) - 0.5 * dot_m(before, before)
        lin = dot_m(before, delta)
        quad = 0.5 * dot_m(delta, delta)
        scale_e = np.ones_like(lin)
        over = lin + quad > limit
        if np.any(over):
            disc = np.sqrt(np.maximum(lin**2 + 4 * quad * np.maximum(limit, 0.0), 0.0))
            s = np.where(quad > 0, (-lin + disc) / np.where(quad > 0, 2 * quad, 1.0), 0.0)
            scale_e = np.where(over, np.clip(s, 0.0, 1.0), 1.0)
        return before + scale_e[..., None, None] * delta

    def _scaled_velocity(self, u, q):
        """z = M^(1/2) u in the coordinates of J̃ (N, 6n, 1): J u = J̃ z, z_ω = L⁻¹ Rᵀ ω."""
        rot = quat_to_matrix(q)
        zv = u[..., :3] / self.root_inv_mass[:, None]
        zw = (self.root_inertia @ (np.swapaxes(rot, -1, -2) @ u[..., 3:, None]))[..., 0]
        return np.concatenate((zv, zw), axis=-1).reshape(len(u), -1, 1)
