"""The contact solve: projected block Gauss–Seidel to a stated tolerance, per batch element.

Problem (one batch element, contacts i with rows n, t₁, t₂, Delassus A, free velocities b):
find impulses λ with v = b + A λ such that, per contact,

* normal: λ_n ≥ 0, v_n ≥ target, λ_n (v_n − target) = 0 (Signorini; the target is −gap/Δt for a
  speculative contact ahead, 0 for a touching one, or a bounce velocity);
* friction: |λ_t| ≤ μ (λ_n + extra) with λ_t = −μ (λ_n + extra) v_t / |v_t| when sliding, v_t = 0
  when sticking (Coulomb's law with the isotropic cone; ``extra`` is the impact impulse the
  contact already carried this step, see ``restitution.py``).

Gauss–Seidel visits the contacts in turn (Erleben, "Velocity-based shock propagation for
multibody dynamics animation", ACM TOG 2007; Catto's sequential impulses, GDC 2005): the normal
row by its exact 1-D solve, then the tangent pair by a projected gradient step of length
1/ρ(A_tt) onto the disk. That step keeps the fixed point exactly Coulomb's (the impulse opposes
the sliding velocity, so a box sliding diagonally keeps its yaw), where a 2×2 solve followed by
a radial projection would skew it. Each sweep is a descent step of a convex quadratic over a
product of convex sets, so the iteration converges (Jourdan, Alart & Jean, 1998 for the
frictional case with fixed cone radii).

Stopping: a batch element has converged when a whole sweep changes no contact velocity by more
than ``tolerance`` times its velocity scale (the largest free contact velocity or target of that
element). Converged elements drop out; an element that reaches ``max_iterations`` is reported
(``Report``) and its impulse, if it would add kinetic energy, is cut back along its own
direction (``dissipative``).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

MAX_ITERATIONS = 200
TOLERANCE = 1e-12
MAX_IMPACTS = 32


@dataclass(frozen=True)
class SolverSettings:
    """Settings of the contact solve.

    Parameters
    ----------
    max_iterations : Gauss–Seidel sweeps at most per solve (≥ 1). A solve that stops here
        instead of at the tolerance is reported (``Scene``'s contact report and a
        :class:`ContactSolverWarning`).
    tolerance : relative stopping tolerance in (0, 1): a solve has converged when one sweep
        changes no contact velocity by more than ``tolerance`` × the element's largest free
        contact velocity (m/s). The default 1e-12 sits a few hundred roundings above machine
        precision.
    max_impacts : impacts resolved in time order within one step per batch element (≥ 1); a
        step with more (a long Newton's cradle at a large Δt) is reported like an iteration cap.
    """

    max_iterations: int = MAX_ITERATIONS
    tolerance: float = TOLERANCE
    max_impacts: int = MAX_IMPACTS

    def __post_init__(self):
        for name in ("max_iterations", "max_impacts"):
            value = getattr(self, name)
            try:
                as_int = operator.index(value)
            except TypeError:
                raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}") from None
            if isinstance(value, bool) or as_int < 1:
                raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}")
            object.__setattr__(self, name, int(as_int))
        try:
            tol = float(self.tolerance)
        except (TypeError, ValueError):
            raise ValueError(
                f"tolerance must be a number in (0, 1), got {self.tolerance!r}"
            ) from None
        if not 0 < tol < 1:
            raise ValueError(f"tolerance must be a number in (0, 1), got {self.tolerance!r}")
        object.__setattr__(self, "tolerance", tol)


def gauss_seidel(delassus, free, target, mu, lam, settings, extra=None):
    """Solve the contact problem of the module docstring for every element of a batch.

    ``delassus`` (N, rC, rC) with r = 3 rows per contact (normal, t₁, t₂) or r = 1 (normal
    only: ``mu`` ignored); ``free`` (N, C, r) the velocities before the impulses, ``target``
    (N, C) the normal targets (−∞ where a contact is out of play), ``mu`` (C,), ``lam`` (N, C, r)
    the start, ``extra`` (N, C) normal impulse already carried (friction budget) or None.
    Returns ``(lam, sweeps, converged)``: sweeps (N,) used, converged (N,) bool.
    """
    size, c, r = free.shape
    lam = np.array(lam, dtype=float)
    sweeps = np.zeros(size, int)
    converged = np.zeros(size, bool)
    if size == 0:
        return lam, sweeps, converged
    finite = np.isfinite(target)
    scale = np.max(np.abs(free.reshape(size, -1)), axis=-1)
    scale = np.maximum(scale, np.max(np.where(finite, np.abs(target), 0.0), axis=-1))
    scale = np.maximum(scale, 1e-300)
    diag = np.diagonal(delassus, axis1=-2, axis2=-1).reshape(size, c, r)
    inv_n = 1.0 / diag[..., 0]
    if r == 3:
        att = np.stack(
            [delassus[:, 3 * i + 1 : 3 * i + 3, 3 * i + 1 : 3 * i + 3] for i in range(c)], 1
        )
        half_tr = 0.5 * (att[..., 0, 0] + att[..., 1, 1])
        half_df = 0.5 * (att[..., 0, 0] - att[..., 1, 1])
        rho = half_tr + np.sqrt(half_df**2 + att[..., 0, 1] ** 2)  # ρ(A_tt) per contact
        inv_t = 1.0 / rho
        coupling = np.stack([delassus[:, 3 * i + 1 : 3 * i + 3, 3 * i] for i in range(c)], 1)
        budget = np.zeros((size, c)) if extra is None else extra
    idx = np.arange(size)
    data = [delassus, free, target, inv_n, scale]
    if r == 3:
        data += [inv_t, coupling, budget]
    work = lam.copy()
    for sweep in range(1, settings.max_iterations + 1):
        a, b, t, i_n, sc = data[:5]
        change = np.zeros(len(idx))
        flat = work.reshape(len(idx), -1)
        for i in range(c):
            rows = slice(r * i, r * i + r)
            v = b[:, i] + np.einsum("nrk,nk->nr", a[:, rows], flat)
            ln_old = flat[:, r * i]
            ln = np.maximum(ln_old - (v[:, 0] - t[:, i]) * i_n[:, i], 0.0)
            dn = ln - ln_old
            flat[:, r * i] = ln
            step = np.abs(dn) / i_n[:, i]
            if r == 3:
                i_t, cp, bud = data[5:]
                vt = v[:, 1:] + cp[:, i] * dn[:, None]
                lt_old = flat[:, r * i + 1 : r * i + 3]
                lt = lt_old - vt * i_t[:, i, None]
                norm = np.sqrt(np.sum(lt * lt, axis=-1))
                cap = mu[i] * (ln + bud[:, i])
                shrink = np.where(norm > cap, cap / np.where(norm > 0, norm, 1.0), 1.0)
                lt = lt * shrink[:, None]
                dt_ = lt - lt_old
                flat[:, r * i + 1 : r * i + 3] = lt
                step = np.maximum(step, np.sqrt(np.sum(dt_ * dt_, axis=-1)) / i_t[:, i])
            change = np.maximum(change, step)
        done = change <= settings.tolerance * sc
        sweeps[idx] = sweep
        if done.any():
            lam[idx[done]] = work[done]
            converged[idx[done]] = True
            keep = ~done
            if not keep.any():
                return lam, sweeps, converged
            idx = idx[keep]
            work = work[keep]
            data = [d[keep] for d in data]
    lam[idx] = work
    return lam, sweeps, converged


def dissipative(lam, dz, z):
    """Cut an unconverged impulse back so it adds no kinetic energy.

    In z = M^(1/2) u coordinates KE = ½|z|² and an impulse moves z by dz = J̃ᵀ λ, so
    ΔKE = z·dz + ½|dz|². At a solution every term of λᵀ v⁺ is ≤ 0 (λ_n > 0 only where v_n⁺ =
    target ≤ 0; friction opposes v_t⁺), so ΔKE = λᵀ v⁺ − ½ λᵀ A λ ≤ 0. An impulse that adds
    energy is no solution; it is scaled to the most dissipative point of its own ray,
    s = −z·dz / |dz|² clipped to [0, 1]. ``lam`` (N, …), ``dz`` and ``z`` (N, 6n)."""
    lin = np.sum(z * dz, axis=-1)
    quad = np.sum(dz * dz, axis=-1)
    gains = lin + 0.5 * quad > 1e-12 * np.sum(z * z, axis=-1)
    if not np.any(gains):
        return lam, dz
    s = np.where(gains, np.clip(-lin / np.where(quad > 0, quad, 1.0), 0.0, 1.0), 1.0)
    shape = (-1,) + (1,) * (lam.ndim - 1)
    return lam * s.reshape(shape), dz * s[:, None]


__all__ = ["SolverSettings", "dissipative", "gauss_seidel"]
