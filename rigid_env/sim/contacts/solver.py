"""Sequential impulses with accumulated clamping, Coulomb friction and Newton restitution.

The notes' impulse ("Impacto"): at a contact with normal n and arms r_a, r_b, an impulse j n
changes the normal relative velocity by j (1/m_a + 1/m_b + nᵀ(M_a⁻¹(r_a×n))×r_a + …); the
ground is body b with infinite mass (its terms vanish). With several simultaneous contacts the
impulses are found by projected Gauss–Seidel (Catto, "Iterative Dynamics with Temporal
Coherence", GDC 2005; Box2D v3's solver), batched: each slot of the padded manifold is one
vectorised update over every batch element at once. Sweeps alternate direction so that no
contact order is favoured.

A step (semi-implicit Euler: forces → velocities → contacts → positions):

1. *Main pass* on the post-force velocities u₁: normal target ``v_n ≥ −d/Δt`` for a gap d > 0
   (speculative contact: the body may close the gap this step, no more — no tunnelling), and
   ``v_n ≥ 0`` for d ≤ 0. Friction ("Fricción"): per contact, the tangential impulse that
   cancels the sliding velocity, in two rows each clamped to ``|j_t| ≤ μ j_n``; the first row
   is along the sliding direction, so there the law is Coulomb's exactly, the impulse opposes
   sliding and never reverses it (across it, the pyramid admits up to √2 μ j_n in total).
2. Positions drift with the solved velocities: x ← x₁ + Δt (v_s − v₁), q ← exp(Δt (ω_s − ω₁)) q₁,
   which equals x₀ + Δt v_s for the semi-implicit integrators this stage accepts.
3. *Restitution pass* (velocities only, Box2D v3's ``applyRestitution``): a contact that carried
   impulse and was approached faster than the material's threshold gets ``v_n = −ε v_impact``.
   The impact speed is the normal approach speed interpolated to the instant the gap closes
   under constant normal acceleration, ``v_impact² = v_n0² − 2 a d`` with a = (v_n1 − v_n0)/Δt,
   so that a ball dropped with ε = 1 leaves the ground with the speed it hit it (energy is not
   lost or gained by where in the step the impact fell).
4. Energy guard: if the restitution impulse would leave more kinetic energy than the step had
   before contact (Newton's law can do so at simultaneous contacts), it is scaled down until it
   does not. Positions are never pushed apart by velocity: any remaining penetration is removed
   by moving the body (projection), which changes no velocity and so adds no kinetic energy.
"""

from __future__ import annotations

import numpy as np

from ..rotation import cross, quat_exp, quat_multiply, quat_normalize, quat_to_matrix
from ..state import State

ITERATIONS = 10
_UP = np.array([0.0, 0.0, 1.0])


def _tangents(n, vrel):
    """Sliding direction t1 (any perpendicular when not sliding) and t2 = n × t1."""
    vt = vrel - np.sum(vrel * n, axis=-1, keepdims=True) * n
    speed = np.linalg.norm(vt, axis=-1, keepdims=True)
    helper = np.where(np.abs(n[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    perp = helper - np.sum(helper * n, axis=-1, keepdims=True) * n
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    t1 = np.where(speed > 1e-9, vt / np.where(speed > 1e-9, speed, 1.0), perp)
    return t1, cross(n, t1)


class _Set:
    """One group of contacts sharing bodies (a, b): Jacobians and effective masses per slot."""

    def __init__(self, a, b, arm_a, arm_b, normal, gap, material, model, inv_inertia, u0, u1, dt):
        self.a, self.b, self.gap, self.material = a, b, gap, material
        self.arm_a, self.arm_b, self.normal = arm_a, arm_b, normal
        ua1 = u1 if a is None else u1[..., a, :]
        vrel = ua1[..., None, :3] + cross(ua1[..., None, 3:], arm_a)
        if b is not None:
            ub1 = u1[..., b, :]
            vrel = vrel - ub1[..., None, :3] - cross(ub1[..., None, 3:], arm_b)
        t1, t2 = _tangents(normal, vrel)
        basis = np.stack((np.broadcast_to(normal, t1.shape), t1, t2), axis=-2)  # (…,G,K,3,3)
        self.jac_a, self.w_a = self._rows(basis, arm_a, a, model, inv_inertia, 1.0)
        eff = np.einsum("...ik,...jk->...ij", self.jac_a, self.w_a)
        if b is not None:
            self.jac_b, self.w_b = self._rows(basis, arm_b, b, model, inv_inertia, -1.0)
            eff = eff + np.einsum("...ik,...jk->...ij", self.jac_b, self.w_b)
        self.b_nn = eff[..., 0, 0]
        self.b_nt = eff[..., 0, 1:]
        self.b_tt = np.stack((eff[..., 1, 1], eff[..., 2, 2]), axis=-1)
        self.b_12 = eff[..., 1, 2]
        self.vn0 = self.normal_velocity(u0)
        self.vn1 = self.normal_velocity(u1)
        self.target = np.where(gap > 0, -gap / dt, 0.0)

    @staticmethod
    def _rows(basis, arm, idx, model, inv_inertia, sign):
        rxb = cross(arm[..., None, :], basis)
        inv_m = model.inv_mass if idx is None else model.inv_mass[idx]
        iinv = inv_inertia if idx is None else inv_inertia[..., idx, :, :]
        jac = np.concatenate((basis, rxb), axis=-1)
        w = np.concatenate(
            (basis * inv_m[:, None, None, None], rxb @ iinv[..., :, None, :, :]), axis=-1
        )
        return sign * jac, sign * w

    def velocity(self, u):
        """Relative velocity in the contact basis (n, t1, t2), (…, G, K, 3)."""
        ua = u if self.a is None else u[..., self.a, :]
        c = np.einsum("...kij,...j->...ki", self.jac_a, ua)
        if self.b is not None:
            c = c + np.einsum("...kij,...j->...ki", self.jac_b, u[..., self.b, :])
        return c

    def normal_velocity(self, u):
        return self.velocity(u)[..., 0]

    def slots(self):
        """Per-slot views, sliced once so the Gauss–Seidel loop only does arithmetic."""
        out = []
        for k in range(self.gap.shape[-1]):
            out.append(
                {
                    "a": self.a,
                    "b": self.b,
                    "jac_a": self.jac_a[..., k, :, :],
                    "w_a": self.w_a[..., k, :, :],
                    "jac_b": None if self.b is None else self.jac_b[..., k, :, :],
                    "w_b": None if self.b is None else self.w_b[..., k, :, :],
                    "b_nn": self.b_nn[..., k],
                    "b_nt": self.b_nt[..., k, :],
                    "b_tt": self.b_tt[..., k, :],
                    "b_12": self.b_12[..., k],
                    "target": self.target[..., k],
                    "mu": self.material.friction,
                    "lam_n": np.zeros(self.gap.shape[:-1]),
                    "lam_t": np.zeros((*self.gap.shape[:-1], 2)),
                }
            )
        return out


def _relative(slot, u):
    a, b = slot["a"], slot["b"]
    ua = u if a is None else u[..., a, :]
    c = np.einsum("...ij,...j->...i", slot["jac_a"], ua)
    if b is not None:
        c = c + np.einsum("...ij,...j->...i", slot["jac_b"], u[..., b, :])
    return c


def _apply(slot, u, delta):
    a, b = slot["a"], slot["b"]
    du = np.einsum("...i,...ij->...j", delta, slot["w_a"])
    if a is None:
        u += du
    else:
        u[..., a, :] += du
    if b is not None:
        u[..., b, :] += np.einsum("...i,...ij->...j", delta, slot["w_b"])


def _sweep_order(n_slots, iterations):
    forward = list(range(n_slots))
    for i in range(iterations):
        yield from (forward if i % 2 == 0 else forward[::-1])


def _main_pass(slots, u, iterations):
    for s in _sweep_order(len(slots), iterations):
        slot = slots[s]
        c = _relative(slot, u)
        lam_n = slot["lam_n"]
        new_n = np.maximum(lam_n + (slot["target"] - c[..., 0]) / slot["b_nn"], 0.0)
        d_n = new_n - lam_n
        # Friction sees the tangential velocity after this normal update (B couples them).
        # Two friction rows, the first along the sliding direction (an aligned pyramid: along
        # the slip it is exactly Coulomb's |j_t| <= μ j_n), each clamped to ±μ j_n.
        limit = slot["mu"] * new_n
        lam_t = slot["lam_t"]
        b_nt, b_tt = slot["b_nt"], slot["b_tt"]
        vt1 = c[..., 1] + b_nt[..., 0] * d_n
        t1 = np.clip(lam_t[..., 0] - vt1 / b_tt[..., 0], -limit, limit)
        d1 = t1 - lam_t[..., 0]
        vt2 = c[..., 2] + b_nt[..., 1] * d_n + slot["b_12"] * d1
        t2 = np.clip(lam_t[..., 1] - vt2 / b_tt[..., 1], -limit, limit)
        new_t = np.stack((t1, t2), axis=-1)
        delta = np.concatenate((d_n[..., None], new_t - lam_t), axis=-1)
        slot["lam_n"], slot["lam_t"] = new_n, new_t
        _apply(slot, u, delta)


def _restitution_pass(slots, u, iterations):
    zero_t = None
    for s in _sweep_order(len(slots), iterations):
        slot = slots[s]
        c = _relative(slot, u)
        lam = slot["lam_r"]
        new = np.maximum(lam + (slot["bounce"] - c[..., 0]) / slot["b_nn"], 0.0)
        if zero_t is None:
            zero_t = np.zeros((*new.shape, 2))
        slot["lam_r"] = new
        _apply(slot, u, np.concatenate(((new - lam)[..., None], zero_t), axis=-1))


class ContactStage:
    """``stage(old, new) -> State``: the contact response appended to a semi-implicit step."""

    def __init__(self, model, dt, ground=None, pairs=None, iterations=ITERATIONS):
        self.model, self.dt, self.ground, self.pairs = model, dt, ground, pairs
        self.iterations = iterations
        self.inv_inertia_body = model.inv_inertia  # (n, 3, 3)

    def _inverse_inertia(self, q):
        rot = quat_to_matrix(q)
        return rot @ self.inv_inertia_body @ np.swapaxes(rot, -1, -2)

    def _sets(self, x0, q0, u0, u1, inv_inertia):
        sets, model, dt = [], self.model, self.dt
        if self.ground is not None:
            arm, gap = self.ground.detect(x0, q0)
            a = None if self.ground.all_bodies else self.ground.bodies
            sets.append(
                _Set(a, None, arm, None, _UP, gap, model.ground, model, inv_inertia, u0, u1, dt)
            )
        if self.pairs is not None:
            for a, b, arm_a, arm_b, n, gap in self.pairs.detect(x0, q0):
                for p in range(len(a)):
                    sl = (Ellipsis, slice(p, p + 1), slice(None), slice(None))
                    sets.append(
                        _Set(
                            a[p : p + 1],
                            b[p : p + 1],
                            arm_a[sl],
                            arm_b[sl],
                            n[sl],
                            gap[sl[:-1]],
                            model.contacts,
                            model,
                            inv_inertia,
                            u0,
                            u1,
                            dt,
                        )
                    )
        return sets

    def __call__(self, old: State, new: State) -> State:
        dt = self.dt
        x0, q0, v0, w0 = old.arrays()
        x1, q1, v1, w1 = new.arrays()
        u0 = np.concatenate((v0, w0), axis=-1)
        u1 = np.concatenate((v1, w1), axis=-1)
        inv_inertia = self._inverse_inertia(q0)
        sets = self._sets(x0, q0, u0, u1, inv_inertia)
        # Nothing within reach this step anywhere in the batch: the free step stands.
        if not any(np.any(s.gap + dt * np.minimum(s.vn1, 0.0) < 0) for s in sets):
            return new
        slots = [slot for s in sets for slot in s.slots()]
        u = u1.copy()
        self._warm_start(sets, slots, u, "target", "lam_n", sets[0].vn1 if sets else None)
        _main_pass(slots, u, self.iterations)
        v, w = u[..., :3], u[..., 3:]
        x = x1 + dt * (v - v1)
        turned = quat_normalize(quat_multiply(quat_exp(dt * (w - w1)), q1))
        # Bodies the contacts left alone keep q₁ bit for bit, as when nothing in the batch is in
        # reach (the early return above): an element's step must not depend on the rest of the
        # batch (a vector env equals single envs); renormalising q₁ would change its last bits.
        q = np.where(np.any(w != w1, axis=-1, keepdims=True), turned, q1)
        x = self._project(sets, slots, u, x)
        u = self._restitute(sets, slots, u, u1, q0, v0, w0)
        return State(x, q, np.array(u[..., :3]), np.array(u[..., 3:]))

    def _warm_start(self, sets, slots, u, target, key, vn):
        """Start each ground manifold from the impulse that stops it as a particle, shared
        equally by its violated slots: exact for a box resting or landing flat (corners
        symmetric about the centre of mass), so Gauss–Seidel starts at the answer there and
        only polishes elsewhere. Without it, 10 sweeps leave a resting box jittering at
        ~3e-3 rad/s (friction couples the corners through the torques of their arms)."""
        s = sets[0]
        if s.b is not None or s.gap.shape[-1] == 1:
            return
        goal = np.stack([slots[k][target] for k in range(s.gap.shape[-1])], axis=-1)
        short = goal - vn  # (…, G, K): normal velocity missing per slot
        violated = short > 0
        count = np.sum(violated, axis=-1, keepdims=True)
        mass = self.model.mass if s.a is None else self.model.mass[s.a]
        need = mass[:, None] * np.max(np.where(violated, short, 0.0), axis=-1, keepdims=True)
        share = np.where(violated, need / np.maximum(count, 1), 0.0)
        zero_t = np.zeros((*share.shape[:-1], 2))
        for k in range(share.shape[-1]):
            slots[k][key] = share[..., k]
            _apply(slots[k], u, np.concatenate((share[..., k, None], zero_t), axis=-1))

    def _project(self, sets, slots, u, x):
        """Remove penetration left after the step by moving bodies along the normal."""
        dt, model = self.dt, self.model
        x = np.array(x)
        for s in sets:
            depth = -(s.gap + dt * s.normal_velocity(u))  # linearised end-of-step penetration
            if not np.any(depth > 0):
                continue
            if s.b is None:
                lift = np.maximum(np.max(depth, axis=-1), 0.0)  # (…, G)
                if s.a is None:
                    x[..., 2] += lift
                else:
                    x[..., s.a, 2] += lift
            else:
                push = np.maximum(depth[..., 0], 0.0)[..., None] * s.normal[..., 0, :]
                ma, mb = model.mass[s.a], model.mass[s.b]
                x[..., s.a, :] += push * (mb / (ma + mb))[:, None]
                x[..., s.b, :] -= push * (ma / (ma + mb))[:, None]
        return x

    def _restitute(self, sets, slots, u, u1, q0, old_v, old_w):
        i = 0
        any_bounce = False
        for s in sets:
            eps, threshold = s.material.restitution, s.material.restitution_threshold
            # Semi-implicit velocities are step means: v₀ ≈ v(t₀ − Δt/2), v₁ ≈ v(t₀ + Δt/2).
            accel = (s.vn1 - s.vn0) / self.dt
            v_mid = 0.5 * (s.vn0 + s.vn1)
            v_end = v_mid + accel * self.dt  # v(t₀ + Δt): the impact lies between
            lo = np.minimum(v_mid**2, v_end**2)
            hi = np.maximum(v_mid**2, v_end**2)
            v_impact = -np.sqrt(np.clip(v_mid**2 - 2 * accel * np.maximum(s.gap, 0.0), lo, hi))
            # The stored velocity after the step is v(t₁ − Δt/2) on the outgoing trajectory,
            # which leaves the contact at t₁ with −ε v_impact: hence the −a Δt/2.
            out = -eps * v_impact - 0.5 * accel * self.dt
            for k in range(s.gap.shape[-1]):
                slot = slots[i]
                i += 1
                bouncing = (slot["lam_n"] > 0) & (v_impact[..., k] < -threshold) & (eps > 0)
                bouncing &= s.vn1[..., k] < 0
                slot["bounce"] = np.where(bouncing, out[..., k], -np.inf)
                slot["lam_r"] = np.zeros_like(slot["lam_n"])
                any_bounce = any_bounce or bool(np.any(bouncing))
        if not any_bounce:
            return u
        before = u.copy()
        self._warm_start(sets, slots, u, "bounce", "lam_r", sets[0].normal_velocity(u))
        _restitution_pass(slots, u, self.iterations)
        # Energy guard: KE(before + s Δ) <= KE(u1) with the largest s in [0, 1].
        delta = u - before
        inertia = quat_to_matrix(q0) @ self.model.inertia @ np.swapaxes(quat_to_matrix(q0), -1, -2)
        m = self.model.mass[:, None]

        def dot_m(p, r):
            lin = np.sum(m * p[..., :3] * r[..., :3], axis=(-1, -2))
            ang = np.einsum("...i,...ij,...j->...", p[..., 3:], inertia, r[..., 3:]).sum(-1)
            return lin + ang

        # Allowance: one more step of the non-contact forces (2u₁ − u₀), the size of the
        # half-step offsets above; a genuine multi-contact energy gain is larger and is cut.
        u0 = np.concatenate((old_v, old_w), axis=-1)
        ke_in = np.maximum(dot_m(u1, u1), dot_m(2 * u1 - u0, 2 * u1 - u0))
        limit = 0.5 * ke_in * (1 + 1e-12) - 0.5 * dot_m(before, before)
        lin = dot_m(before, delta)
        quad = 0.5 * dot_m(delta, delta)
        over = lin + quad > limit
        if np.any(over):
            disc = np.sqrt(np.maximum(lin**2 + 4 * quad * np.maximum(limit, 0.0), 0.0))
            scale = np.where(quad > 0, (-lin + disc) / np.where(quad > 0, 2 * quad, 1.0), 0.0)
            scale = np.where(over, np.clip(scale, 0.0, 1.0), 1.0)
            u = before + scale[..., None, None] * delta
        return u
