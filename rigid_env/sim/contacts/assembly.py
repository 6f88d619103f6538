"""Contact rows: which bodies each contact point touches, its Jacobian and effective masses.

Every contact point has three rows, normal n and two tangents t₁, t₂ (Catto, "Iterative
Dynamics with Temporal Coherence", GDC 2005). The notes' impulse ("Impacto"): an impulse j n at
a contact with arms r_a, r_b changes the normal relative velocity by
j (1/m_a + 1/m_b + nᵀ(M_a⁻¹(r_a×n))×r_a + …); the ground is a body b of infinite mass.

All rows of one batch element form one Jacobian J (3C, 6n). It is stored scaled, J̃ = J M^(-1/2),
so that the Delassus matrix is A = J M⁻¹ Jᵀ = J̃ J̃ᵀ (its diagonal the inverse effective masses)
and an impulse λ changes the velocities by Δu = M^(-1/2) J̃ᵀ λ. ``M^(-1/2)`` uses 1/√m for the
linear part and R L, L Lᵀ = M0⁻¹ (Cholesky, body axes), for the angular part.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rotation import cross, quat_to_matrix

_UP = np.array([0.0, 0.0, 1.0])
FAR_GAP = 1e3  # a pair slot with no contact point (box_box.FAR): its arms stay unshifted


class Layout:
    """Static bookkeeping of a scene's contact points, computed once per scene.

    Ground slots come first (G bodies × K slots, contiguous per body), then each pair group's
    slots (P pairs × S slots). ``a``/``b`` are the body indices per contact (b = −1: ground);
    ``mu``, ``eps``, ``threshold`` the material per contact.
    """

    def __init__(self, model, ground, pairs):
        n = model.n_bodies
        self.n_bodies = n
        self.ground, self.pairs = ground, pairs
        a, b, mu, eps, thr = [], [], [], [], []
        round_pairs: list[np.ndarray] = []
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
            for (pa, pb, _, slots), kind in zip(pairs.groups, pairs.kinds, strict=True):
                round_pairs.append(np.full(len(pa) * slots, kind == "sphere_sphere"))
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
        # Per pair slot: a sphere–sphere contact, whose normal follows the centres (``moved``).
        self.round_pairs = np.concatenate(round_pairs) if round_pairs else np.zeros(0, bool)
        # Manifold of each contact: one per body on the ground, one per body pair.
        self.manifold = np.where(self.b < 0, self.a, n + n * self.a + np.maximum(self.b, 0))
        self.mu, self.eps = np.concatenate(mu), np.concatenate(eps)
        self.threshold = np.concatenate(thr)
        self.c = len(self.a)
        self.pair_slice = slice(self.n_ground, self.c)
        self.pa, self.pb = self.a[self.n_ground :], self.b[self.n_ground :]
        self.single_body = n == 1
        self.mass = model.mass
        # Square roots of the inverse mass matrix: 1/√m and L with L Lᵀ = M0⁻¹ (body axes).
        self.root_inv_mass = 1.0 / np.sqrt(model.mass)
        self.root_inv_inertia = np.linalg.cholesky(model.inv_inertia)
        self.root_inertia = np.linalg.inv(self.root_inv_inertia)  # L⁻¹
        # ‖L‖₂ = 1/√(least principal moment): |ω| ≤ ‖L‖₂ |z_ω| (the compiled solve's reach)
        self.spin = np.linalg.norm(self.root_inv_inertia, 2, axis=(-2, -1))
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

    def detect(self, x, q):
        """Arms, normals and gaps of all contacts at positions (N, n, ·); see ``gather``."""
        ground = None if self.ground is None else self.ground.detect(x, q)
        pairs = None if self.pairs is None else self.pairs.detect(x, q)
        return self.gather(ground, pairs)

    def gather(self, ground_hits, pair_hits):
        """Arms, normals and gaps of all contacts (N, C, ·) from the detectors' results
        (``GroundContacts.detect``'s (arm, gap), ``PairContacts.detect``'s list, or None);
        ``arm_b`` covers the pair slots only (None without pairs)."""
        arms, normals, gaps, arm_b = [], [], [], None
        if ground_hits is not None:
            arm, gap = ground_hits
            arms.append(arm.reshape(len(arm), -1, 3))
            gaps.append(gap.reshape(len(gap), -1))
            normals.append(np.broadcast_to(_UP, arms[-1].shape))
        if pair_hits is not None:
            arm_bs = []
            for _, _, arm_a, arm_bb, n, gap in pair_hits:
                arms.append(arm_a.reshape(len(gap), -1, 3))
                arm_bs.append(arm_bb.reshape(len(gap), -1, 3))
                normals.append(n.reshape(len(gap), -1, 3))
                gaps.append(gap.reshape(len(gap), -1))
            arm_b = arm_bs[0] if len(arm_bs) == 1 else np.concatenate(arm_bs, axis=-2)
        if len(arms) == 1:
            return arms[0], arm_b, normals[0], gaps[0]
        cat = np.concatenate
        return cat(arms, -2), arm_b, cat(normals, -2), cat(gaps, -1)

    def relative_velocity(self, u, arm_a, arm_b):
        """World velocity of a's contact point relative to b's, (N, C, 3), from u (N, n, 6)."""
        ua = u if self.single_body else u[:, self.a]
        vrel = ua[..., :3] + cross(ua[..., 3:], arm_a)
        if arm_b is not None:
            ub = u[:, self.pb]
            vrel[:, self.pair_slice] -= ub[..., :3] + cross(ub[..., 3:], arm_b)
        return vrel


@dataclass
class Rows:
    """The assembled contact problem of a set of batch elements (leading axis N).

    ``jt`` (N, 3C, 6n) is J̃ = J M^(-1/2); ``delassus`` (N, 3C, 3C) = J̃ J̃ᵀ; ``scale``
    (N, n, 3, 3) = R L maps scaled angular coordinates back to ω; ``gap`` (N, C) the signed
    distances at the step's start; ``normal`` (N, C, 3); ``arm_a``/``arm_b`` the detected
    arms (before the midpoint shift) and ``q`` the orientations they were detected at.
    """

    jt: np.ndarray
    delassus: np.ndarray
    scale: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    arm_a: np.ndarray
    arm_b: np.ndarray | None
    q: np.ndarray

    def take(self, idx) -> Rows:
        return Rows(
            self.jt[idx],
            self.delassus[idx],
            self.scale[idx],
            self.gap[idx],
            self.normal[idx],
            self.arm_a[idx],
            None if self.arm_b is None else self.arm_b[idx],
            self.q[idx],
        )

    def moved(self, layout, u, shift) -> Rows:
        """The rows after the bodies translated by ``shift`` (N, n, 3) (pairs' arms only).

        A sphere–sphere contact's normal is the line of centres at that instant: detected at
        the step's start, xa − xb = (ra + rb + d) n (``pairs.sphere_sphere``), so after the
        shift d' = xa − xb + Δshift and n' = d'/|d'|, with the arms −ra n' and rb n' and the
        points |d'| − ra − rb apart along n'. The start's normal at the moved points would
        give the impulse a moment about both centres (spurious spin) and tilt the exit
        directions, by an angle of the order of the relative travel over the distance of the
        centres. Other pairs keep their detected normal (a face's normal turns only with its
        body, by ω times the event's time)."""
        if self.arm_b is None:
            return self
        normal, arm_a, arm_b, apart = self.normal, self.arm_a, self.arm_b, None
        round_pairs = layout.round_pairs
        if round_pairs.any():
            sl = layout.pair_slice
            ra = np.linalg.norm(arm_a[:, sl][:, round_pairs], axis=-1, keepdims=True)
            rb = np.linalg.norm(arm_b[:, round_pairs], axis=-1, keepdims=True)
            n0 = normal[:, sl][:, round_pairs]
            rel = (shift[:, layout.pa] - shift[:, layout.pb])[:, round_pairs]
            centres = (ra + rb + self.gap[:, sl][:, round_pairs, None]) * n0 + rel
            dist = np.linalg.norm(centres, axis=-1, keepdims=True)
            n1 = np.where(dist > 1e-12, centres / np.where(dist > 1e-12, dist, 1.0), n0)
            normal, arm_a, arm_b = np.array(normal), np.array(arm_a), np.array(arm_b)
            pair_normal, pair_arm_a = normal[:, sl], arm_a[:, sl]
            pair_normal[:, round_pairs] = n1
            pair_arm_a[:, round_pairs] = -ra * n1
            normal[:, sl], arm_a[:, sl] = pair_normal, pair_arm_a
            arm_b[:, round_pairs] = rb * n1
            apart = pair_apart(layout, self.gap, self.normal, shift)
            apart[:, round_pairs] = (dist - ra - rb) * n1
        rows = assemble(layout, self.q, u, arm_a, arm_b, normal, self.gap, shift, apart)
        # The detection's own arms and normals stay the rows' record (what ``moved`` starts
        # from, and the separation's normals).
        rows.normal, rows.arm_a, rows.arm_b = self.normal, self.arm_a, self.arm_b
        return rows

    @property
    def normal_delassus(self) -> np.ndarray:
        """The normal rows' block A_nn (N, C, C)."""
        return self.delassus[:, 0::3, 0::3]

    def velocity(self, u, layout) -> np.ndarray:
        """Contact-frame velocities J u (N, C, 3) of generalised velocities u (N, n, 6)."""
        return (self.jt @ scaled_velocity(layout, u, self.scale)).reshape(len(u), -1, 3)

    def velocity_change(self, lam, layout) -> np.ndarray:
        """Δu = M^(-1/2) J̃ᵀ λ (N, n, 6) of impulses λ (N, C, 3)."""
        dz = lam.reshape(len(lam), 1, -1) @ self.jt
        dz = dz.reshape(len(lam), -1, 6)
        dv = dz[..., :3] * layout.root_inv_mass[:, None]
        dw = (self.scale @ dz[..., 3:, None])[..., 0]
        return np.concatenate((dv, dw), axis=-1)


def tangents(n, vrel):
    """Sliding direction t₁ (any perpendicular when not sliding) and t₂ = n × t₁, (N, C, 3)."""
    vt = vrel - np.sum(vrel * n, axis=-1, keepdims=True) * n
    speed = np.linalg.norm(vt, axis=-1, keepdims=True)
    helper = np.where(np.abs(n[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    perp = helper - np.sum(helper * n, axis=-1, keepdims=True) * n
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    t1 = np.where(speed > 1e-9, vt / np.where(speed > 1e-9, speed, 1.0), perp)
    return t1, cross(n, t1)


def scaled_velocity(layout, u, scale):
    """z = M^(1/2) u (N, 6n, 1) in the coordinates of J̃, so that J u = J̃ z; ``scale`` = R L,
    z_ω = L⁻¹ Rᵀ ω = (R L)⁻¹ ω."""
    zv = u[..., :3] * np.sqrt(layout.mass)[:, None]
    zw = np.linalg.solve(scale, u[..., 3:, None])[..., 0]
    return np.concatenate((zv, zw), axis=-1).reshape(len(u), -1, 1)


def pair_apart(layout: Layout, gap, normal, shift=None):
    """p_a − p_b of each pair contact (N, P, 3): gap n at the detection, plus the relative
    translation ``shift`` (N, n, 3) of the two bodies since."""
    sl = layout.pair_slice
    apart = np.where(gap[:, sl] < FAR_GAP, gap[:, sl], 0.0)[..., None] * normal[:, sl]
    if shift is not None:
        apart = apart + shift[:, layout.pa] - shift[:, layout.pb]
    return apart


def assemble(layout: Layout, q, u, arm_a, arm_b, normal, gap, shift=None, apart=None) -> Rows:
    """The rows of contacts detected at orientations q (N, n, 4); t₁ follows the sliding of
    the velocities u (N, n, 6). ``shift`` (N, n, 3): the bodies' translation since the
    detection (an impact's time into the step); the rows keep the detected arms and gaps.
    ``apart``: the pair contacts' p_a − p_b, if not ``pair_apart``'s (``Rows.moved``)."""
    raw_a, raw_b = arm_a, arm_b
    if arm_b is not None:
        # Both bodies of a pair take their impulses at one point, the midpoint of the two
        # features (p_a − p_b = gap n + the relative translation since): then no impulse,
        # normal or friction, has a net moment, and angular momentum is conserved at a
        # speculative contact (gap > 0) and at an impact part-way through the step.
        sl = layout.pair_slice
        if apart is None:
            apart = pair_apart(layout, gap, normal, shift)
        arm_a = np.array(arm_a)
        arm_a[:, sl] -= 0.5 * apart
        arm_b = arm_b + 0.5 * apart
    vrel = layout.relative_velocity(u, arm_a, arm_b)
    t1, t2 = tangents(normal, vrel)
    basis = np.stack((normal, t1, t2), axis=-2)  # (N, C, 3, 3)
    scale = quat_to_matrix(q) @ layout.root_inv_inertia  # R L (N, n, 3, 3)
    jt = _scaled_jacobian(layout, basis, arm_a, arm_b, scale)
    return Rows(jt, jt @ np.swapaxes(jt, -1, -2), scale, gap, normal, raw_a, raw_b, q)


def _scaled_jacobian(lay, basis, arm_a, arm_b, scale):
    """J̃ (N, 3C, 6n): linear rows b/√m, angular rows (r × b)ᵀ R L, so that
    (r × b)ᵀ M⁻¹ (r × b) = |row|²; body b's rows enter with the opposite sign."""
    n_rows = 3 * lay.c
    rxb = cross(arm_a[..., None, :], basis)  # (N, C, 3, 3)
    if lay.single_body:
        ang = rxb.reshape(-1, n_rows, 3) @ scale[:, 0]
        lin = basis.reshape(-1, n_rows, 3) * lay.root_inv_mass[0]
        return np.concatenate((lin, ang), axis=-1)
    ja = np.concatenate((basis * lay.root_inv_mass[lay.a, None, None], rxb @ scale[:, lay.a]), -1)
    jz = np.zeros((len(basis), lay.c, lay.n_bodies, 3, 6))
    jz[:, np.arange(lay.c), lay.a] = ja
    if arm_b is not None:
        bp = basis[:, lay.pair_slice]
        rxb_b = cross(arm_b[..., None, :], bp)
        jb = np.concatenate(
            (bp * lay.root_inv_mass[lay.pb, None, None], rxb_b @ scale[:, lay.pb]), axis=-1
        )
        jz[:, np.arange(lay.n_ground, lay.c), lay.pb] = -jb
    return np.swapaxes(jz, -3, -2).reshape(len(basis), n_rows, -1)


__all__ = ["Layout", "Rows", "assemble", "scaled_velocity", "tangents"]
