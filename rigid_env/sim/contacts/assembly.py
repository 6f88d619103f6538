"""The contact layout of a scene (``Layout``): which bodies each contact slot touches, its
material, and the bodies' mass factors the rows are scaled by. The rows themselves are built per
element by ``compiled/contact_assembly.py``.

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

import numpy as np

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
        # Per pair slot: a sphere–sphere contact, whose normal follows the centres at an
        # impact (``compiled.contact_impacts.round_closing``).
        self.round_pairs = np.concatenate(round_pairs) if round_pairs else np.zeros(0, bool)
        self.mu, self.eps = np.concatenate(mu), np.concatenate(eps)
        self.threshold = np.concatenate(thr)
        self.c = len(self.a)
        # Square roots of the inverse mass matrix: 1/√m and L with L Lᵀ = M0⁻¹ (body axes).
        self.root_inv_mass = 1.0 / np.sqrt(model.mass)
        self.root_inv_inertia = np.linalg.cholesky(model.inv_inertia)
        self.root_inertia = np.linalg.inv(self.root_inv_inertia)  # L⁻¹
        # ‖L‖₂ = 1/√(least principal moment): |ω| ≤ ‖L‖₂ |z_ω| (the compiled solve's reach)
        self.spin = np.linalg.norm(self.root_inv_inertia, 2, axis=(-2, -1))
