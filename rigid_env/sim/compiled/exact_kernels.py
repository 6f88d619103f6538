"""The exact torque-free flow per body, and the ``exact`` and ``exact4`` integrators.

The method and its sources are in ``rigid_env.sim.integrators`` (Celledoni, Fassò & Säfström
2008; Leroy's notes). ``exact`` and ``exact4`` are integrator kernels (package docstring)
built like ``splitting``'s Strang step, with the exact flow in place of the axis-by-axis free
rotation. The elliptic functions it needs, to rounding:

* Carlson's symmetric integrals R_F and R_J by the duplication theorem, both from one shared
  duplication of (x, y, z): B. C. Carlson, "Numerical computation of real or complex elliptic
  integrals", Numer. Algorithms 10 (1995) 13–26 (the algorithms of its §2 and §4; the same as
  NIST DLMF §19.36(i)); R_F(x, y, z) = ½ ∫₀^∞ dt / √((t+x)(t+y)(t+z)),
  R_J(x, y, z, p) = 3/2 ∫₀^∞ dt / ((t+p) √((t+x)(t+y)(t+z))) (DLMF 19.16.1–2), both to a few
  units of rounding;
* Jacobi sn, cn, dn by argument halving, Maclaurin series and the duplication formulas
  (Abramowitz & Stegun 16.22.1 and 16.18), written so that nothing cancels near k → 1.

scipy checks them in the tests only.
"""

from __future__ import annotations

import math

import numpy as np

from ..integrators import W0 as YOSHIDA_W0
from ..integrators import W1 as YOSHIDA_W1
from .bodies import (
    INV_MASS,
    INV_MOMENTS,
    MOMENTS,
    PRINCIPAL,
    PRINCIPAL_CONJ,
    PRINCIPAL_QUAT,
    apply_inverse_inertia,
    vec3,
    vec4,
)
from .cache import njit
from .forces import wrench
from .integrators import (
    axpy,
    implicit_half_kick,
    kick,
    load,
    load_body_torque,
    store,
)
from .registry import register_integrator
from .rotation import quat_conjugate, quat_multiply, quat_rotate, quat_to_matrix

# Carlson (1995): stop when 4^-m Q < |A_m| with Q = (3r)^(-1/6) max|A0 - x| for R_F and
# (r/4)^(-1/6) max|A0 - x| for R_J; the truncated series is then accurate to r.
TOLERANCE = float(np.finfo(float).eps / 2)
Q_RF = (3 * TOLERANCE) ** (-1 / 6)
Q_RJ = (TOLERANCE / 4) ** (-1 / 6)
DUPLICATIONS = 60  # convergence is geometric (× 4 per step): 60 is never reached by valid input
# Maclaurin coefficients of sn(x | m) (A&S 16.22.1, continued to x⁹): polynomials in m.
SN1 = (-1 / 6, -1 / 6)
SN2 = (1 / 120, 14 / 120, 1 / 120)
SN3 = (-1 / 5040, -135 / 5040, -135 / 5040, -1 / 5040)
SN4 = (1 / 362880, 1228 / 362880, 5478 / 362880, 1228 / 362880, 1 / 362880)
# |x| <= 2⁻⁵ after halving: the first omitted term, ≈ 0.009 x¹¹ at m = 1 (tanh), is < 1e-17 |x|.
SERIES_RADIUS = 2.0**-5


# --- elliptic functions -------------------------------------------------------------------------


@njit(cache=True)
def rc_one_plus(e):
    """R_C(1, 1 + e) = atan(√e)/√e (e > 0) or atanh(√−e)/√−e (−1 < e < 0), Carlson (1995)
    eq. 2.9; near e = 0 both are 0/0, and the Maclaurin series 1 − e/3 + e²/5 − … is used
    (|e| < 1e-3: the first omitted term e⁶/13 is below 1e-18)."""
    if abs(e) < 1e-3:
        return 1 - e * (1 / 3 - e * (1 / 5 - e * (1 / 7 - e * (1 / 9 - e * (1 / 11)))))
    t = math.sqrt(abs(e))
    if e > 0:
        return math.atan(t) / t
    return math.atanh(min(t, 1.0 - 1e-16)) / t


@njit(cache=True)
def carlson_rf_rj(x, y, z, p):
    """R_F(x, y, z) and R_J(x, y, z, p) (module docstring) for x, y, z >= 0 (at most one
    zero), p > 0; raises ``ArithmeticError`` if the duplication has not converged after
    ``DUPLICATIONS`` steps (two zero arguments)."""
    a_f = (x + y + z) / 3
    a_j = (x + y + z + 2 * p) / 5
    q_f = Q_RF * max(abs(a_f - x), abs(a_f - y), abs(a_f - z))
    q_j = Q_RJ * max(abs(a_j - x), abs(a_j - y), abs(a_j - z), abs(a_j - p))
    delta = (p - x) * (p - y) * (p - z)
    a0_f, a0_j, x0, y0, z0 = a_f, a_j, x, y, z
    total = 0.0
    scale = 1.0
    converged = False
    for _ in range(DUPLICATIONS):
        if scale * q_f < abs(a_f) and scale * q_j < abs(a_j):
            converged = True
            break
        if not (math.isfinite(a_f) and math.isfinite(a_j)):  # NaN out
            converged = True
            break
        sx, sy, sz, sp = math.sqrt(x), math.sqrt(y), math.sqrt(z), math.sqrt(p)
        lam = sx * sy + sy * sz + sz * sx
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = scale**3 * delta / (d * d)
        total = total + scale * rc_one_plus(e) / d
        x, y, z, p = (x + lam) / 4, (y + lam) / 4, (z + lam) / 4, (p + lam) / 4
        a_f, a_j = (a_f + lam) / 4, (a_j + lam) / 4
        scale = scale / 4
    if not converged and not (scale * q_f < abs(a_f) and scale * q_j < abs(a_j)):
        raise ArithmeticError("Carlson duplication did not converge (two zero arguments?)")
    xf = scale * (a0_f - x0) / a_f
    yf = scale * (a0_f - y0) / a_f
    zf = -(xf + yf)
    e2, e3 = xf * yf - zf * zf, xf * yf * zf
    rf = (
        1
        - e2 / 10
        + e3 / 14
        + e2 * e2 / 24
        - 3 * e2 * e3 / 44
        - 5 * e2**3 / 208
        + 3 * e3 * e3 / 104
        + e2 * e2 * e3 / 16
    ) / math.sqrt(a_f)
    xj = scale * (a0_j - x0) / a_j
    yj = scale * (a0_j - y0) / a_j
    zj = scale * (a0_j - z0) / a_j
    pj = -(xj + yj + zj) / 2
    e2 = xj * yj + xj * zj + yj * zj - 3 * pj * pj
    e3 = xj * yj * zj + 2 * e2 * pj + 4 * pj**3
    e4 = (2 * xj * yj * zj + e2 * pj + 3 * pj**3) * pj
    e5 = xj * yj * zj * pj * pj
    series = 1 - 3 * e2 / 14 + e3 / 6 + 9 * e2 * e2 / 88 - 3 * e4 / 22 - 9 * e2 * e3 / 52
    series = series + 3 * e5 / 26
    rj = scale * series / (a_j * math.sqrt(a_j)) + 6 * total
    return rf, rj


@njit(cache=True)
def jacobi_sn_cn_dn(u, m, mc):
    """sn, cn, dn of u with parameter m = k² and its complement mc = 1 − m (both given, so
    that nothing cancels near k → 1): u halved into the series' range, then doubled back."""
    _, n = math.frexp(abs(u) / SERIES_RADIUS)
    n = max(n, 0)
    x = math.ldexp(u, -n)
    x2 = x * x
    s = 0.0
    s = s * x2 + (((SN4[4] * m + SN4[3]) * m + SN4[2]) * m + SN4[1]) * m + SN4[0]
    s = s * x2 + ((SN3[3] * m + SN3[2]) * m + SN3[1]) * m + SN3[0]
    s = s * x2 + (SN2[2] * m + SN2[1]) * m + SN2[0]
    s = s * x2 + (SN1[1] * m + SN1[0])
    s = s * x2 + 1.0
    s = s * x
    c = math.sqrt((1 - s) * (1 + s))
    for _ in range(n):
        d = math.sqrt(c * c + mc * s * s)
        s2, c2 = s * s, c * c
        den = c2 + s2 * d * d
        s_new, c_new = 2 * s * c * d / den, (c2 * c2 - mc * s2 * s2) / den
        norm = math.hypot(s_new, c_new)
        s, c = s_new / norm, c_new / norm
    return s, c, math.sqrt(c * c + mc * s * s)


# --- the exact flow -------------------------------------------------------------------------------


@njit(cache=True)
def argsort3(a):
    """The stable argsort of three values."""
    o0, o1, o2 = 0, 1, 2
    if a[o0] > a[o1]:
        o0, o1 = o1, o0
    if a[o1] > a[o2]:
        o1, o2 = o2, o1
    if a[o0] > a[o1]:
        o0, o1 = o1, o0
    return o0, o1, o2


@njit(cache=True)
def relabel(moments, m):
    """The proper signed permutation s_i = sg_i m[order_i] that puts the dn axis last with
    s₁, s₃ >= 0: (order, signs, moments and s in those labels)."""
    o0, o1, o2 = argsort3(moments)
    parity = float(math.copysign(1.0, (o0 - o1) * (o1 - o2) * (o2 - o0)))
    g0, g1, g2 = 1.0, 1.0, parity
    i0, i2 = moments[o0], moments[o2]
    i1 = moments[o1]
    s0, s2 = g0 * m[o0], g2 * m[o2]
    d2 = (i0 - i1) * s0**2 / i0 + (i2 - i1) * s2**2 / i2
    if d2 < 0:
        o0, o2 = o2, o0
        g0, g1, g2 = g2, -g1, g0
    s2 = g2 * m[o2]
    if s2 < 0:
        g1, g2 = -g1, -g2
    s0 = g0 * m[o0]
    if s0 < 0:
        g0, g1 = -g0, -g1
    order = (o0, o1, o2)
    sg = (g0, g1, g2)
    inertia = (moments[o0], moments[o1], moments[o2])
    s = (g0 * m[o0], g1 * m[o1], g2 * m[o2])
    return order, sg, inertia, s


@njit(cache=True)
def swing(n0, n1, n2):
    """The shortest rotation taking the unit vector n (n₂ >= 0) to e₃."""
    w = 1.0 + n2
    scale = 1.0 / math.sqrt(2.0 * w)
    return (n1 * scale, -n0 * scale, 0.0, w * scale)


@njit(cache=True)
def unpermute(order, sg, v):
    """out[order_i] = sg_i v_i."""
    out0 = out1 = out2 = 0.0
    for i in range(3):
        value = sg[i] * v[i]
        if order[i] == 0:
            out0 = value
        elif order[i] == 1:
            out1 = value
        else:
            out2 = value
    return out0, out1, out2


@njit(cache=True)
def free_flow(moments, m, h):
    """The exact torque-free flow of one body over time h (any sign) in principal axes:
    (m(h), dq) with q(h) = q(0) ∘ dq, |m(h)| = |m| to rounding. The flow is homogeneous
    (m(t) = s m̂(s t), q(t) = q̂(s t) for m̂ = m/s): with s a power of two near max|m| the
    scaling is exact, and no square below over- or underflows."""
    _, e = math.frexp(max(abs(m[0]), abs(m[1]), abs(m[2])))
    unit = (math.ldexp(m[0], -e), math.ldexp(m[1], -e), math.ldexp(m[2], -e))
    m_new, dq = unit_flow(moments, unit, math.ldexp(h, e))
    return (math.ldexp(m_new[0], e), math.ldexp(m_new[1], e), math.ldexp(m_new[2], e)), dq


@njit(cache=True)
def unit_flow(moments, m, h):
    """``free_flow`` for max|m| in [½, 1) (or m = 0)."""
    omega = (m[0] / moments[0], m[1] / moments[1], m[2] / moments[2])
    if (
        m[1] * omega[2] - m[2] * omega[1] == 0.0
        and m[2] * omega[0] - m[0] * omega[2] == 0.0
        and m[0] * omega[1] - m[1] * omega[0] == 0.0
    ):
        r = (h * omega[0], h * omega[1], h * omega[2])
        theta = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        half = 0.5 * theta
        sinc = math.sin(half) / theta if theta > 1e-4 else 0.5 - theta**2 / 48
        return m, (sinc * r[0], sinc * r[1], sinc * r[2], math.cos(half))
    order, sg, inertia, s = relabel(moments, m)
    i1, i2, i3 = inertia
    m1, m2, m3 = s
    d1 = (i2 - i1) * m2**2 / i2 + (i3 - i1) * m3**2 / i3
    d3 = (i3 - i1) * m1**2 / i1 + (i3 - i2) * m2**2 / i2
    d2 = (i1 - i2) * m1**2 / i1 + (i3 - i2) * m3**2 / i3
    mc = min(max((i3 - i1) * d2 / ((i3 - i2) * d1), 0.0), 1.0)
    mk = min(max((i2 - i1) * d3 / ((i3 - i2) * d1), 0.0), 1.0)
    if mc <= 0.5:
        mk = 1.0 - mc
    else:
        mc = 1.0 - mk
    b1 = math.sqrt(i1 * d3 / (i3 - i1))
    b2 = math.sqrt(i2 * d3 / (i3 - i2))
    b3 = math.sqrt(i3 * d1 / (i3 - i1))
    big_g = math.sqrt(m1**2 + m2**2 + m3**2)
    if not (math.isfinite(big_g) and math.isfinite(d1) and math.isfinite(d3) and big_g > 0):
        nan = math.nan  # an overflowed state: NaN out, for the driver's divergence check
        return (nan, nan, nan), (nan, nan, nan, nan)
    lam = math.copysign(1.0, i3 - i1) * math.sqrt((i3 - i2) * d1 / (i1 * i2 * i3))
    nu = i3 * (i2 - i1) / (i1 * (i3 - i2))
    if b1 == 0:
        sn0, cn0 = 0.0, 1.0
    else:
        sn0, cn0 = m2 / b2, m1 / b1
    norm = math.hypot(sn0, cn0)
    sn0, cn0 = sn0 / norm, cn0 / norm
    dn0 = math.sqrt(cn0**2 + mc * sn0**2)
    separatrix = mc == 0.0
    rf0, rj0 = carlson_rf_rj(cn0**2, dn0**2, 1.0, 1.0 + nu * sn0**2)
    rfc, rjc = carlson_rf_rj(0.0, 1.0 if separatrix else mc, 1.0, 1.0 + nu)
    u0 = sn0 * rf0
    quarter = 1.0 if separatrix else rfc
    pi_complete = rfc - (nu / 3) * rjc
    u1 = u0 + lam * h
    periods = 0.0 if separatrix else float(round(u1 / (2 * quarter)))
    r = u1 - 2 * quarter * periods
    sn_r, cn_r, dn_r = jacobi_sn_cn_dn(r, mk, mc)
    zero_pair = cn_r == 0.0 and dn_r == 0.0
    rf_r, rj_r = carlson_rf_rj(1.0 if zero_pair else cn_r**2, dn_r**2, 1.0, 1.0 + nu * sn_r**2)
    root_nu = math.sqrt(nu)
    if separatrix:
        p0 = (u0 + root_nu * math.atan(root_nu * sn0)) / (1 + nu)
        p_r = (r + root_nu * math.atan(root_nu * sn_r)) / (1 + nu)
        third = p_r - p0
    else:
        p0 = sn0 * rf0 - (nu / 3) * sn0**3 * rj0
        p_r = sn_r * rf_r - (nu / 3) * sn_r**3 * rj_r
        third = 2 * periods * pi_complete + p_r - p0
    root = math.sqrt(1.0 + nu)
    arc = (
        periods * math.pi / root
        + (math.atan2(root * sn_r, cn_r) - math.atan2(root * sn0, cn0)) / root
    )
    a = b3 / big_g
    dpsi = big_g * h / i3 + big_g * (i3 - i1) / (i1 * i3 * lam) * (third - a * arc)
    sign = -1.0 if periods - 2.0 * math.floor(0.5 * periods) != 0.0 else 1.0
    t0, t1, t2 = b1 * cn_r * sign, b2 * sn_r * sign, b3 * dn_r
    scale = big_g / math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0, t1, t2 = t0 * scale, t1 * scale, t2 * scale
    half = 0.5 * dpsi
    spin = (0.0, 0.0, math.sin(half), math.cos(half))
    start = swing(m1 / big_g, m2 / big_g, m3 / big_g)
    end = swing(t0 / big_g, t1 / big_g, t2 / big_g)
    dq_s = quat_multiply(quat_multiply(quat_conjugate(start), spin), end)
    m_new = unpermute(order, sg, (t0, t1, t2))
    v = unpermute(order, sg, (dq_s[0], dq_s[1], dq_s[2]))
    return m_new, (v[0], v[1], v[2], dq_s[3])


@njit(cache=True)
def exact_rotation(moments, qp, m, h):
    """The exact flow of (qp, m) over h, qp renormalised."""
    m, dq = free_flow(moments, m, h)
    q = quat_multiply(qp, dq)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n), m


@njit(cache=True)
def read_back(moments, inv, qp, pi, w):
    """ω refined so that the next step reads back Π from it."""
    r = quat_rotate(quat_conjugate(qp), w)
    e = (
        (moments[0] * r[0] - pi[0]) * inv[0],
        (moments[1] * r[1] - pi[1]) * inv[1],
        (moments[2] * r[2] - pi[2]) * inv[2],
    )
    c = quat_rotate(qp, e)
    return (w[0] - c[0], w[1] - c[1], w[2] - c[2])


# --- integrator kernels (the Strang step with the exact rotation) ----------------------


@njit(cache=True, error_model="numpy")
def exact_strang(bd, b, fds, x, q, v, w, fa, ta, tb, dt, velocity_dependent):
    """half kick, exact flow, half kick."""
    f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
    im = bd[b, INV_MASS]
    v = kick(v, 0.5 * dt, im, f)
    x = axpy(x, dt, v)
    principal = bd[b, PRINCIPAL] != 0.0
    qp = quat_multiply(q, vec4(bd, b, PRINCIPAL_QUAT)) if principal else q
    conj = quat_conjugate(qp)
    moments = vec3(bd, b, MOMENTS)
    r = quat_rotate(conj, w)
    pi = (moments[0] * r[0], moments[1] * r[1], moments[2] * r[2])
    pi = axpy(pi, 0.5 * dt, quat_rotate(conj, t))
    inv = vec3(bd, b, INV_MOMENTS)
    qp, pi = exact_rotation(moments, qp, pi, dt)
    w = quat_rotate(qp, (pi[0] * inv[0], pi[1] * inv[1], pi[2] * inv[2]))
    w = read_back(moments, inv, qp, pi, w)
    q = quat_multiply(qp, vec4(bd, b, PRINCIPAL_CONJ)) if principal else qp
    if velocity_dependent:
        v, w = implicit_half_kick(bd, b, fds, x, q, v, w, fa, ta, tb, dt)
        return x, q, v, w
    f, t = wrench(b, x, q, v, w, fa, ta, tb, fds)
    v = kick(v, 0.5 * dt, im, f)
    w = axpy(w, 0.5 * dt, apply_inverse_inertia(bd, b, quat_to_matrix(q), t))
    return x, q, v, w


def exact(tag, e, st, d):
    """Strang splitting of the exact flow, second order."""
    (bd, prm, sd), fds = d
    dt, vdep = prm[0], prm[1] != 0.0
    for b in range(st[0].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = exact_strang(bd, b, fds, x, q, v, w, fa, ta, tb, dt, vdep)
        store(st, e, b, x, q, v, w)


def exact4(tag, e, st, d):
    """Yoshida's triple jump of ``exact``."""
    (bd, prm, sd), fds = d
    dt, vdep = prm[0], prm[1] != 0.0
    for b in range(st[0].shape[1]):
        x, q, v, w, fa, ta = load(st, e, b)
        tb = load_body_torque(st, e, b)
        x, q, v, w = exact_strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt, vdep)
        x, q, v, w = exact_strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W0 * dt, vdep)
        x, q, v, w = exact_strang(bd, b, fds, x, q, v, w, fa, ta, tb, YOSHIDA_W1 * dt, vdep)
        store(st, e, b, x, q, v, w)


register_integrator("exact", globals(), one=exact)
register_integrator("exact4", globals(), one=exact4)
