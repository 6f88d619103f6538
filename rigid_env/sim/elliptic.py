"""Elliptic integrals and Jacobi elliptic functions on batched arrays, to rounding, in numpy only.

* Carlson's symmetric integrals R_F and R_J by the duplication theorem, both from one shared
  duplication of (x, y, z): B. C. Carlson, "Numerical computation of real or complex elliptic
  integrals", Numer. Algorithms 10 (1995) 13–26 (the algorithms of its §2 and §4; the same as
  NIST DLMF §19.36(i)).
* Jacobi sn, cn, dn by argument halving, Maclaurin series and the duplication formulas
  (Abramowitz & Stegun 16.22.1 and 16.18), written so that nothing cancels near k → 1.

Only elementwise arithmetic with a loop whose length is set by the worst element of the batch,
so the same code ports to a per-element compiled kernel; scipy is used by the tests only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

# Carlson (1995): stop when 4^-m Q < |A_m| with Q = (3r)^(-1/6) max|A0 - x| for R_F and
# (r/4)^(-1/6) max|A0 - x| for R_J; the truncated series is then accurate to r.
_TOLERANCE = np.finfo(float).eps / 2
_Q_RF = (3 * _TOLERANCE) ** (-1 / 6)
_Q_RJ = (_TOLERANCE / 4) ** (-1 / 6)
MAX_DUPLICATIONS = 60  # convergence is geometric (× 4 per step): 60 is never reached by valid input


class EllipticConvergenceError(ArithmeticError):
    """Carlson's duplication did not converge: an argument pattern outside its domain."""


def _rc_one_plus(e: np.ndarray) -> np.ndarray:
    """R_C(1, 1 + e) = atan(√e)/√e (e > 0) or atanh(√−e)/√−e (−1 < e < 0); Carlson (1995) eq. 2.9.

    Near e = 0 both forms are 0/0: the Maclaurin series 1 − e/3 + e²/5 − … is used there
    (|e| < 1e-3: the first omitted term e⁶/13 is below 1e-18).
    """
    small = np.abs(e) < 1e-3
    t = np.sqrt(np.where(small, 1.0, np.abs(e)))
    far = np.where(e > 0, np.arctan(t), np.arctanh(np.minimum(t, 1.0 - 1e-16))) / t
    series = 1 - e * (1 / 3 - e * (1 / 5 - e * (1 / 7 - e * (1 / 9 - e * (1 / 11)))))
    return np.where(small, series, far)


def carlson_rf_rj(
    x: ArrayLike, y: ArrayLike, z: ArrayLike, p: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """R_F(x, y, z) and R_J(x, y, z, p), elementwise, for x, y, z >= 0 (at most one zero), p > 0.

    R_F(x, y, z) = ½ ∫₀^∞ dt / √((t+x)(t+y)(t+z)),
    R_J(x, y, z, p) = 3/2 ∫₀^∞ dt / ((t+p) √((t+x)(t+y)(t+z)))   (DLMF 19.16.1–2).

    Both relative errors are a few units of rounding. Raises :class:`EllipticConvergenceError`
    if the duplication has not converged after ``MAX_DUPLICATIONS`` steps (two zero arguments).
    """
    x, y, z, p = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, z, p)))
    a_f = (x + y + z) / 3
    a_j = (x + y + z + 2 * p) / 5
    spread = np.maximum(np.maximum(np.abs(a_f - x), np.abs(a_f - y)), np.abs(a_f - z))
    q_f = _Q_RF * spread
    q_j = _Q_RJ * np.maximum(
        np.maximum(np.maximum(np.abs(a_j - x), np.abs(a_j - y)), np.abs(a_j - z)),
        np.abs(a_j - p),
    )
    delta = (p - x) * (p - y) * (p - z)
    a0_f, a0_j, x0, y0, z0 = a_f, a_j, x, y, z
    total = np.zeros_like(x)
    scale = np.ones_like(x)  # 4^-m, per element
    # Each element stops at its own step count, so a batch gives bit for bit the results of its
    # elements computed alone (the loop runs to the slowest element).
    for _ in range(MAX_DUPLICATIONS):
        # Non-finite input (an overflowed state) is passed through as NaN for the caller's
        # divergence check rather than reported as a convergence failure.
        done = (scale * q_f < np.abs(a_f)) & (scale * q_j < np.abs(a_j))
        going = ~done & np.isfinite(a_f) & np.isfinite(a_j)
        if not np.any(going):
            break
        sx, sy, sz, sp = np.sqrt(x), np.sqrt(y), np.sqrt(z), np.sqrt(p)
        lam = sx * sy + sy * sz + sz * sx
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = scale**3 * delta / (d * d)
        total = np.where(going, total + scale * _rc_one_plus(e) / d, total)
        x, y, z, p = (np.where(going, (a + lam) / 4, a) for a in (x, y, z, p))
        a_f = np.where(going, (a_f + lam) / 4, a_f)
        a_j = np.where(going, (a_j + lam) / 4, a_j)
        scale = np.where(going, scale / 4, scale)
    else:
        raise EllipticConvergenceError(
            f"Carlson duplication did not converge in {MAX_DUPLICATIONS} steps "
            "(R_F/R_J need x, y, z >= 0 with at most one zero and p > 0)"
        )
    # R_F: DLMF 19.36.1 with X + Y + Z = 0.
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
    ) / np.sqrt(a_f)
    # R_J: Carlson (1995) eq. 2.39 with X + Y + Z + 2P = 0.
    xj = scale * (a0_j - x0) / a_j
    yj = scale * (a0_j - y0) / a_j
    zj = scale * (a0_j - z0) / a_j
    pj = -(xj + yj + zj) / 2
    e2 = xj * yj + xj * zj + yj * zj - 3 * pj * pj
    e3 = xj * yj * zj + 2 * e2 * pj + 4 * pj**3
    e4 = (2 * xj * yj * zj + e2 * pj + 3 * pj**3) * pj
    e5 = xj * yj * zj * pj * pj
    series = (
        1 - 3 * e2 / 14 + e3 / 6 + 9 * e2 * e2 / 88 - 3 * e4 / 22 - 9 * e2 * e3 / 52 + 3 * e5 / 26
    )
    rj = scale * series / (a_j * np.sqrt(a_j)) + 6 * total
    return rf, rj


# Maclaurin coefficients of sn(x | m) (A&S 16.22.1, continued to x⁹): polynomials in m.
_SN_SERIES = (
    (1.0,),
    (-1 / 6, -1 / 6),
    (1 / 120, 14 / 120, 1 / 120),
    (-1 / 5040, -135 / 5040, -135 / 5040, -1 / 5040),
    (1 / 362880, 1228 / 362880, 5478 / 362880, 1228 / 362880, 1 / 362880),
)
# |x| <= 2⁻⁵ after halving: the first omitted term, ≈ 0.009 x¹¹ at m = 1 (tanh), is < 1e-17 |x|.
_SERIES_RADIUS = 2.0**-5


def halvings(u: ArrayLike) -> np.ndarray:
    """Per element, how many times ``u`` must be halved to enter the series' range."""
    a = np.abs(u)
    _, exponent = np.frexp(
        np.where(np.isfinite(a), a, 0.0) / _SERIES_RADIUS
    )  # a / radius = f 2^e, f in [0.5, 1)
    return np.maximum(exponent, 0)


def jacobi_sn_cn_dn(
    u: ArrayLike, m: ArrayLike, mc: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sn, cn, dn of u for parameter m = k² in [0, 1], given also mc = 1 − m (exactly).

    Passing mc separately keeps full precision near the separatrix (k → 1), where 1 − m would
    lose every digit mc has. Accuracy: the argument is halved N times to |x| <= 2⁻⁵, where the
    Maclaurin series is exact to rounding; then N duplications (A&S 16.18.3 rewritten without
    cancellation, using sn² + cn² = 1 and dn² = cn² + mc sn²):

        sn 2x = 2 s c d / D,  cn 2x = (c⁴ − mc s⁴) / D,  D = c² + s² d²  (= 1 − m s⁴),

    with (sn, cn) renormalised each time, and dn = √(cn² + mc sn²) (never cancels; dn > 0).
    The phase error grows like N ε |u|, i.e. rounding in u. The sign of cn follows u's range:
    cn >= 0 for |u| <= K(m), as for the exact function. N is per element (bit for bit the same
    result in any batch).
    """
    u, m, mc = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (u, m, mc)))
    n = halvings(u)
    x = np.ldexp(u, -n)
    x2 = x * x
    s = np.zeros_like(x)
    for coefficients in reversed(_SN_SERIES):
        poly = np.zeros_like(m)
        for coefficient in reversed(coefficients):
            poly = poly * m + coefficient
        s = s * x2 + poly
    s = s * x
    c = np.sqrt((1 - s) * (1 + s))
    for k in range(int(np.max(n, initial=0))):
        d = np.sqrt(c * c + mc * s * s)
        s2, c2 = s * s, c * c
        den = c2 + s2 * d * d
        s_new, c_new = 2 * s * c * d / den, (c2 * c2 - mc * s2 * s2) / den
        norm = np.hypot(s_new, c_new)
        going = k < n
        s, c = np.where(going, s_new / norm, s), np.where(going, c_new / norm, c)
    # A non-finite u (an overflowed state upstream) gives NaN, for the caller's divergence check.
    bad = ~np.isfinite(u)
    s, c = np.where(bad, np.nan, s), np.where(bad, np.nan, c)
    return s, c, np.sqrt(c * c + mc * s * s)
