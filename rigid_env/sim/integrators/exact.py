"""The exact flow of the torque-free rigid body, and splittings of it with kicks.

Method: Celledoni, Fassò & Säfström, "Exact computation of the free rigid body motion and its
use in splitting methods", SIAM J. Sci. Comput. 30(4) (2008), with the corrections and the
choice of reference axis of P. Leroy's notes on that article (Principia, 2020). Principal
moments I₁ ≤ I₂ ≤ I₃, body angular momentum m = I Ω, |m| = G, kinetic energy T:

* m(t) by Jacobi elliptic functions (Landau & Lifshitz, *Mechanics*, §37): in a proper,
  signed relabelling of the principal axes in which the axis m circulates about is the third
  (the "dn" axis: I₃ if G² > 2TI₂, else I₁ with the axes reversed) and m₁, m₃ >= 0 at t = 0,
  m = (B₁ cn u, B₂ sn u, B₃ dn u), u = u₀ + λ t, u₀ = F(am u₀ | k²) (Carlson's R_F).
* The attitude R(t) = C R_z(ψ(t)) S(m(t)) with S the shortest rotation taking m/G to e₃ (never
  singular: m₃ > 0 on the dn axis) and C fixed by R(0). With that S (CFS §3; Leroy):

      ψ̇ = G/I₃ + G (I₃ − I₁)/(I₁ I₃) · (1 − a dn u) / (1 + ν sn² u),
      a = B₃/G,  ν = I₃ (I₂ − I₁) / (I₁ (I₃ − I₂)),

  (Leroy's ψ̇ = G/I₃ + (2TI₃ − G²) / (G I₃ (1 + m₃/G)), multiplied through by 1 − a dn and
  using 1 − a² dn² = (B₁/G)² (1 + ν sn²), B₁² = I₁ (2TI₃ − G²)/(I₃ − I₁): the vanishing factor
  2TI₃ − G² cancels analytically instead of numerically),

  whose integral over a step is Π(−ν; am u | k²) − a ∫ dθ/(1 + ν sin² θ): an incomplete
  elliptic integral of the third kind (Carlson's R_F and R_J, DLMF 19.25.14) and an arctangent.
  Written this way nothing divides by a vanishing quantity: ν and the prefactor are constants
  of the body, and the formula is continuous into every limit (k → 0 steady spin, k → 1 the
  separatrix, two equal moments where ν = 0 or k = 0). The constant motions (Ω along a
  principal axis or an eigenplane, the sphere, Ω = 0) take the uniform rotation exp(t Ω).

Every quantity that can become small is formed without cancellation: G² − 2TI_j as sums of
same-signed terms (Leroy), k'² = (I₃ − I₁)(G² − 2TI₂) / ((I₃ − I₂)(G² − 2TI₁)) from
G² − 2TI₂ itself, the Jacobi functions with both k² and k'² (``elliptic``). Over a step the
amplitude is reduced by whole periods 2K so Carlson's forms see |am| <= π/2.

``exact`` is ``splitting``'s Strang step, half kick – exact free flow (with the drift) – half
kick, with this flow as its rotation: second order, exact when no torque acts. ``exact4``
composes it by Yoshida's triple jump (Phys. Lett. A 150, 1990): fourth order; its negative
middle step is exact too. The state keeps ω in world axes, so every step reads m = I Rᵀ ω and
writes ω back; the written ω is refined once so that the next read returns m (see
``splitting._read_back``).

What is left is rounding, and near the separatrix it is amplified: an error that moves m to a
neighbouring orbit (changes (G² − 2TI₂)/G²) shifts every later flip, ~8e4 rad per unit at
t = 15 s on the bench's flip. Measured there over 20 s at dt = 1e-3 (20 000 steps), against
one 80-bit evaluation of this flow (30-digit mpmath agrees with it to 1e-17): 5e-11 to 7e-11
rad from the bench's start, 3e-10 to 2e-9 rad from other start orientations, mostly from the
rounding of the read m = I Rᵀ ω and of the write of ω (a few ulp each). With every step done
in 80-bit arithmetic, rounding only the stored float64 q and ω still gives 1.5e-11 to 7e-11
rad: the floor of a float64 state at this step count.
"""

from __future__ import annotations

import numpy as np

from ..elliptic import carlson_rf_rj, jacobi_sn_cn_dn
from ..rotation import cross, quat_conjugate, quat_exp, quat_multiply
from .common import INTEGRATE, Integrator
from .splitting import integrate2, integrate4

# Stand-ins for the elements that take the constant branch, so that the elliptic branch never
# sees a degenerate body (its result is discarded there).
_SAFE_MOMENTS = np.array([1.0, 2.0, 3.0])
_SAFE_MOMENTUM = np.array([1.0, 1.0, 1.0])


def _relabel(moments, m):
    """Proper signed permutation s_i = sg_i m[order_i] putting the dn axis last, s₁, s₃ >= 0.

    Returns (order, sg, moments in the new labels, s).
    """
    order = np.argsort(moments, axis=-1, kind="stable")
    o0, o1, o2 = order[..., 0], order[..., 1], order[..., 2]
    parity = np.sign((o0 - o1) * (o1 - o2) * (o2 - o0)).astype(float)  # +1 even, −1 odd
    sg = np.stack((np.ones_like(parity), np.ones_like(parity), parity), axis=-1)
    i = np.take_along_axis(moments, order, axis=-1)
    s = sg * np.take_along_axis(m, order, axis=-1)
    d2 = (i[..., 0] - i[..., 1]) * s[..., 0] ** 2 / i[..., 0] + (i[..., 2] - i[..., 1]) * s[
        ..., 2
    ] ** 2 / i[..., 2]
    # G² < 2TI₂: m circulates about the smallest moment; reverse the axes, (s₃, −s₂, s₁).
    about_first = (d2 < 0)[..., None]
    order = np.where(about_first, order[..., ::-1], order)
    sg = np.where(about_first, sg[..., ::-1] * np.array([1.0, -1.0, 1.0]), sg)
    s = sg * np.take_along_axis(m, order, axis=-1)
    # Rotations by π about axis 1, then axis 3, make s₃ >= 0 (the dn component never changes
    # sign) and s₁ >= 0 (so the amplitude am u₀ is in [−π/2, π/2]).
    flip3 = np.where(s[..., 2] < 0, -1.0, 1.0)
    sg = sg * np.stack((np.ones_like(flip3), flip3, flip3), axis=-1)
    s = sg * np.take_along_axis(m, order, axis=-1)
    flip1 = np.where(s[..., 0] < 0, -1.0, 1.0)
    sg = sg * np.stack((flip1, flip1, np.ones_like(flip1)), axis=-1)
    s = sg * np.take_along_axis(m, order, axis=-1)
    return order, sg, np.take_along_axis(moments, order, axis=-1), s


def _swing(n):
    """Quaternion of the shortest rotation taking the unit vector n (n₃ >= 0) to e₃."""
    w = 1.0 + n[..., 2]
    scale = 1.0 / np.sqrt(2.0 * w)
    return np.stack((n[..., 1] * scale, -n[..., 0] * scale, np.zeros_like(w), w * scale), axis=-1)


def free_flow(moments, m, h):
    """Exact torque-free flow over time h (any sign) in principal axes.

    ``moments`` (…, 3) principal moments (any order, ties allowed), ``m`` (…, 3) the body
    angular momentum in the same axes. Returns (m(h), dq) with dq the body-frame increment of
    the attitude: q(h) = q(0) ∘ dq, and |m(h)| = |m| to rounding.
    """
    moments, m = np.broadcast_arrays(np.asarray(moments, float), np.asarray(m, float))
    # The flow is homogeneous: m(t) = s m̂(s t) and q(t) = q̂(s t) for m̂ = m/s. With s a power
    # of two near max|m| the scaling is exact, and no square below over- or underflows.
    _, exponent = np.frexp(np.max(np.abs(m), axis=-1))
    m = np.ldexp(m, -exponent[..., None])
    h = np.ldexp(np.broadcast_to(np.asarray(h, float), exponent.shape), exponent)
    m_new, dq = _unit_flow(moments, m, h)
    return np.ldexp(m_new, exponent[..., None]), dq


def _unit_flow(moments, m, h):
    """:func:`free_flow` for max|m| in [½, 1) (or m = 0)."""
    omega = m / moments
    constant = np.all(cross(m, omega) == 0.0, axis=-1)
    safe = constant[..., None]
    order, sg, inertia, s = _relabel(
        np.where(safe, _SAFE_MOMENTS, moments), np.where(safe, _SAFE_MOMENTUM, m)
    )
    i1, i2, i3 = inertia[..., 0], inertia[..., 1], inertia[..., 2]
    m1, m2, m3 = s[..., 0], s[..., 1], s[..., 2]
    # Leroy: G² − 2TI_j as sums of same-signed terms.
    d1 = (i2 - i1) * m2**2 / i2 + (i3 - i1) * m3**2 / i3  # G² − 2TI₁
    d3 = (i3 - i1) * m1**2 / i1 + (i3 - i2) * m2**2 / i2  # 2TI₃ − G²
    d2 = (i1 - i2) * m1**2 / i1 + (i3 - i2) * m3**2 / i3  # G² − 2TI₂
    mc = np.clip((i3 - i1) * d2 / ((i3 - i2) * d1), 0.0, 1.0)  # k'²
    mk = np.clip((i2 - i1) * d3 / ((i3 - i2) * d1), 0.0, 1.0)  # k²
    mk = np.where(mc <= 0.5, 1.0 - mc, mk)
    mc = np.where(mc <= 0.5, mc, 1.0 - mk)
    b1 = np.sqrt(i1 * d3 / (i3 - i1))
    b2 = np.sqrt(i2 * d3 / (i3 - i2))
    b3 = np.sqrt(i3 * d1 / (i3 - i1))
    big_g = np.sqrt(m1**2 + m2**2 + m3**2)
    lam = np.sign(i3 - i1) * np.sqrt((i3 - i2) * d1 / (i1 * i2 * i3))
    nu = i3 * (i2 - i1) / (i1 * (i3 - i2))

    # Phase at t = 0: (sn, cn) = (m₂/B₂, m₁/B₁), cn >= 0; B₁ = B₂ = 0 only for steady spin
    # about the dn axis, where any phase is right.
    flat = b1 == 0
    sn0 = np.where(flat, 0.0, m2 / np.where(flat, 1.0, b2))
    cn0 = np.where(flat, 1.0, m1 / np.where(flat, 1.0, b1))
    norm = np.hypot(sn0, cn0)
    sn0, cn0 = sn0 / norm, cn0 / norm
    dn0 = np.sqrt(cn0**2 + mc * sn0**2)

    separatrix = mc == 0.0  # K = ∞: no period to reduce by
    mc_safe = np.where(separatrix, 1.0, mc)
    rf, rj = carlson_rf_rj(
        np.stack((cn0**2, np.zeros_like(mc))),
        np.stack((dn0**2, mc_safe)),
        1.0,
        np.stack((1.0 + nu * sn0**2, 1.0 + nu)),
    )
    u0 = sn0 * rf[0]
    quarter = np.where(separatrix, 1.0, rf[1])  # K(k); unused (no reduction) when K = ∞
    pi_complete = rf[1] - (nu / 3) * rj[1]  # Π(−ν | k²)
    u1 = u0 + lam * h
    periods = np.where(separatrix, 0.0, np.round(u1 / (2 * quarter)))
    r = u1 - 2 * quarter * periods
    sn_r, cn_r, dn_r = jacobi_sn_cn_dn(r, mk, mc)
    # Two zero arguments (cn = dn = 0) happen only on the separatrix at the equilibrium, where
    # the closed form below is used instead.
    zero_pair = (cn_r == 0.0) & (dn_r == 0.0)
    rf_r, rj_r = carlson_rf_rj(np.where(zero_pair, 1.0, cn_r**2), dn_r**2, 1.0, 1.0 + nu * sn_r**2)
    p0 = sn0 * rf[0] - (nu / 3) * sn0**3 * rj[0]
    p_r = sn_r * rf_r - (nu / 3) * sn_r**3 * rj_r
    # On the separatrix sn = tanh u and ∫ du / (1 + ν tanh² u) is elementary.
    root_nu = np.sqrt(nu)
    p0 = np.where(separatrix, (u0 + root_nu * np.arctan(root_nu * sn0)) / (1 + nu), p0)
    p_r = np.where(separatrix, (r + root_nu * np.arctan(root_nu * sn_r)) / (1 + nu), p_r)
    root = np.sqrt(1.0 + nu)
    third = np.where(separatrix, 0.0, 2 * periods * np.where(separatrix, 0.0, pi_complete))
    third = third + p_r - p0
    arc = (
        periods * np.pi / root
        + (np.arctan2(root * sn_r, cn_r) - np.arctan2(root * sn0, cn0)) / root
    )
    a = b3 / big_g
    dpsi = big_g * h / i3 + big_g * (i3 - i1) / (i1 * i3 * lam) * (third - a * arc)

    sign = np.where(np.fmod(periods, 2.0) != 0.0, -1.0, 1.0)
    s1 = np.stack((b1 * cn_r * sign, b2 * sn_r * sign, b3 * dn_r), axis=-1)
    s1 = s1 * (big_g / np.linalg.norm(s1, axis=-1))[..., None]
    half = 0.5 * dpsi
    spin = np.stack((np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)), axis=-1)
    g = big_g[..., None]
    dq_s = quat_multiply(quat_multiply(quat_conjugate(_swing(s / g)), spin), _swing(s1 / g))

    # Back to the caller's axes: m_order[i] = sg_i s_i; rotation axes transform alike.
    inverse = np.argsort(order, axis=-1)
    m_new = np.take_along_axis(sg * s1, inverse, axis=-1)
    dq_vec = np.take_along_axis(sg * dq_s[..., :3], inverse, axis=-1)
    dq = np.concatenate((dq_vec, dq_s[..., 3:]), axis=-1)
    # Constant motions: Ω fixed in the body, the body turns uniformly about it.
    m_new = np.where(safe, m, m_new)
    dq = np.where(safe, quat_exp(h[..., None] * omega), dq)
    return m_new, dq


def exact_rotation(model, qp, m, h):
    """``splitting``'s free-rotation hook: the exact flow of (qp, m) over h, qp renormalised."""
    m, dq = free_flow(model.principal_moments, m, h)
    qp = quat_multiply(qp, dq)
    # Renormalised for the reason given in ``splitting.free_rotation``.
    return qp / np.linalg.norm(qp, axis=-1, keepdims=True), m


def _integrate2(ctx) -> None:
    integrate2(ctx, exact_rotation)


def _integrate4(ctx) -> None:
    integrate4(ctx, exact_rotation)


EXACT = Integrator(
    "exact",
    ((INTEGRATE, _integrate2),),
    order=2,
    symplectic=True,
    summary="Strang splitting of the exact torque-free flow with kicks; exact without torque",
)
EXACT4 = Integrator(
    "exact4",
    ((INTEGRATE, _integrate4),),
    order=4,
    symplectic=True,
    summary="Yoshida's triple jump of the exact Strang step; 3 × exact",
)
RECORDS = (EXACT, EXACT4)
