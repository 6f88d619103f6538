"""Reference solutions for tests and the accuracy benchmark: closed forms and tight ODE solves.

Conventions are the course notes' (see ``rigid_env.sim.rotation``): ``p = x + R r``, quaternions
(x, y, z, w) with the scalar last, ``q̇ = ½ (ω, 0) ∘ q`` with ω in the world frame, body angular
velocity ``Ω = Rᵀ ω``, torque-free Euler equations ``I Ω̇ = (I Ω) × Ω``.

What is exact and what is not:

* ``torque_free_dop853`` is an ODE solve (DOP853, tolerances 1e-13): the "numerical" reference.
* ``torque_free_jacobi`` is exact (Jacobi elliptic functions, Landau & Lifshitz, *Mechanics*,
  §37); ``torque_free_exact`` adds the orientation, exact up to Gauss–Legendre quadrature of one
  smooth scalar rate (error far below 1e-12). Neither uses an ODE solver, so they check DOP853
  independently.
* ``symmetric_top``, ``spin_up``, ``projectile`` and ``damped_spring`` are closed forms.

Every function takes a 1-D array of ``times`` (seconds, measured from the initial state) and
returns arrays with the time axis first.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipkinc

from rigid_env.sim.rotation import (
    matrix_to_quat,
    quat_conjugate,
    quat_exp,
    quat_from_axis_angle,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    quat_to_matrix,
    rotate_inverse,
)

# --- torque-free rigid body: ODE reference ----------------------------------------------------


def _as_times(times: ArrayLike) -> np.ndarray:
    times = np.atleast_1d(np.asarray(times, dtype=float))
    if times.ndim != 1:
        raise ValueError("times must be a 1-D array")
    return times


def torque_free_dop853(
    inertia_diag: ArrayLike,
    q0: ArrayLike,
    omega0_world: ArrayLike,
    times: ArrayLike,
    rtol: float = 1e-13,
    atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """Torque-free body integrated by DOP853 on the state (q, Π = I Ω).

    ``inertia_diag`` are the principal moments (body axes are principal). ``times`` must be
    >= 0, in any order. Returns the unit quaternion (T, 4), sign-continuous from ``q0``, and the
    world angular velocity (T, 3).
    """
    inertia = np.asarray(inertia_diag, dtype=float)
    q0 = quat_normalize(np.asarray(q0, dtype=float))
    times = _as_times(times)
    if np.any(times < 0):
        raise ValueError("torque_free_dop853 integrates forward from t = 0 only")
    pi0 = inertia * rotate_inverse(quat_to_matrix(q0), np.asarray(omega0_world, dtype=float))

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        q, pi = y[:4], y[4:]
        omega_body = pi / inertia
        # Euler: Π̇ = Π × Ω. Kinematics: q̇ = ½ (ω, 0) ∘ q = ½ q ∘ (Ω, 0), which needs no R(q)
        # and so stays polynomial in an unnormalised q (no renormalisation inside the RHS).
        dq = 0.5 * quat_multiply(q, np.append(omega_body, 0.0))
        return np.concatenate((dq, np.cross(pi, omega_body)))

    t_eval, inverse = np.unique(times, return_inverse=True)
    t_end = float(t_eval[-1])
    if t_end == 0.0:
        y = np.concatenate((q0, pi0))[:, None].repeat(t_eval.size, axis=1)
    else:
        sol = solve_ivp(
            rhs,
            (0.0, t_end),
            np.concatenate((q0, pi0)),
            method="DOP853",
            t_eval=t_eval,
            rtol=rtol,
            atol=atol,
        )
        if not sol.success:
            raise RuntimeError(f"DOP853 failed: {sol.message}")
        y = sol.y
    y = y.T[inverse]
    q = quat_normalize(y[:, :4])
    omega_world = quat_rotate(q, y[:, 4:] / inertia)
    return q, omega_world


# --- torque-free rigid body: Jacobi elliptic functions ------------------------------------------


class _JacobiSolution:
    """Exact body angular velocity of the torque-free body (Landau & Lifshitz §37).

    Works in the *sorted* frame ``s = Q1 Ω`` where the moments are ascending, I1 <= I2 <= I3.
    Q1 is the sorting permutation, negated when it is odd: -P is a proper rotation, so the
    Euler equations (which hold only in right-handed frames, through the cross product) keep
    their form. With ``M² = |L|²`` and ``E`` the kinetic energy, L&L (37.10) for M² > 2EI2:

        Ω1 = A1 cn τ,  Ω2 = A2 sn τ,  Ω3 = A3 dn τ,
        A1 = √((2EI3 - M²) / (I1 (I3 - I1))),  A2 = √((2EI3 - M²) / (I2 (I3 - I2))),
        A3 = √((M² - 2EI1) / (I3 (I3 - I1))),  τ = t √((I3 - I2)(M² - 2EI1) / (I1 I2 I3)),
        k² = (I2 - I1)(2EI3 - M²) / ((I3 - I2)(M² - 2EI1)),

    and for M² < 2EI2 the same with the suffixes 1 and 3 interchanged. The "dn" axis (3, resp.
    1) is the one L circulates about; its component never changes sign. Other sign patterns
    follow from the symmetry of the Euler equations under negating two components, and the
    phase from the inverse amplitude: τ0 = F(φ0 | k²) (``ellipkinc``).

    The differences 2EI3 - M², M² - 2EI1 and M² - 2EI2 are formed as Σ I_i (I_j - I_i) Ω_i²,
    where the large terms cancel analytically, so near the separatrix they keep full relative
    precision (forming M² and 2E first would lose ~|M²| / |M² - 2EI2| in all of them).
    """

    def __init__(self, inertia_diag: ArrayLike, omega0_body: ArrayLike) -> None:
        inertia = np.asarray(inertia_diag, dtype=float)
        omega0 = np.asarray(omega0_body, dtype=float)
        order = np.argsort(inertia, kind="stable")
        perm = np.eye(3)[order]  # s = perm @ Ω sorts the axes
        self.q1 = perm * np.linalg.det(perm)  # proper rotation ±P
        self.inertia = inertia[order]
        s0 = self.q1 @ omega0
        self.s0 = s0
        i1, i2, i3 = self.inertia
        l0 = self.inertia * s0
        # Relative equilibria (Ω along a principal axis or in a degenerate eigenplane, including
        # the isotropic body): Ω is constant.
        self.constant = bool(
            np.linalg.norm(np.cross(l0, s0)) <= 1e-14 * np.linalg.norm(l0) * np.linalg.norm(s0)
        )
        if self.constant:
            return
        w2 = s0**2
        d1 = i2 * (i2 - i1) * w2[1] + i3 * (i3 - i1) * w2[2]  # M² - 2EI1 >= 0
        d3 = i1 * (i3 - i1) * w2[0] + i2 * (i3 - i2) * w2[1]  # 2EI3 - M² >= 0
        d2 = i1 * (i1 - i2) * w2[0] + i3 * (i3 - i2) * w2[2]  # M² - 2EI2, either sign
        amp = np.empty(3)
        if d2 >= 0:  # L&L (37.10): L circulates about axis 3
            self.c, self.d = 0, 2
            amp[0] = np.sqrt(d3 / (i1 * (i3 - i1)))
            amp[1] = np.sqrt(d3 / (i2 * (i3 - i2)))
            amp[2] = np.sqrt(d1 / (i3 * (i3 - i1)))
            self.rate = np.sqrt((i3 - i2) * d1 / (i1 * i2 * i3))
            self.m = (i2 - i1) * d3 / ((i3 - i2) * d1)
        else:  # suffixes 1 and 3 interchanged: L circulates about axis 1
            self.c, self.d = 2, 0
            amp[2] = np.sqrt(d1 / (i3 * (i3 - i1)))
            amp[1] = np.sqrt(d1 / (i2 * (i2 - i1)))
            amp[0] = np.sqrt(d3 / (i1 * (i3 - i1)))
            self.rate = np.sqrt((i2 - i1) * d3 / (i1 * i2 * i3))
            self.m = (i3 - i2) * d1 / ((i2 - i1) * d3)
        self.m = float(np.clip(self.m, 0.0, 1.0))  # rounding only; k² <= 1 analytically
        self.amp = amp
        # Negating the sn and dn components together maps solutions to solutions; choosing the
        # sign of the (never-vanishing) dn component fixes the pattern, the phase does the rest.
        self.sign = 1.0 if s0[self.d] >= 0 else -1.0
        phi0 = np.arctan2(self.sign * s0[1] / amp[1], s0[self.c] / amp[self.c])
        tau0 = ellipkinc(phi0, self.m)
        # Two Newton steps on am(τ0) = φ0 (d am / du = dn) polish ellipkinc to ellipj's own
        # inverse, so that t = 0 reproduces Ω0 to rounding.
        for _ in range(2):
            _, _, dn, ph = ellipj(tau0, self.m)
            tau0 = tau0 + (phi0 - ph) / dn
        self.tau0 = float(tau0)

    def __call__(self, times: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Sorted-frame Ω (T, 3) and the Jacobi amplitude am(τ) (T,), continuous in t."""
        times = _as_times(times)
        if self.constant:
            return np.broadcast_to(self.s0, (times.size, 3)).copy(), np.zeros(times.size)
        sn, cn, dn, ph = ellipj(self.rate * times + self.tau0, self.m)
        return self.from_elliptic(sn, cn, dn), ph

    def from_elliptic(self, sn: np.ndarray, cn: np.ndarray, dn: np.ndarray) -> np.ndarray:
        """Sorted-frame Ω at given values of (sn, cn, dn)."""
        s = np.empty((np.size(sn), 3))
        s[:, self.c] = self.amp[self.c] * cn
        s[:, 1] = self.sign * self.amp[1] * sn
        s[:, self.d] = self.sign * self.amp[self.d] * dn
        return s

    def body(self, times: ArrayLike) -> np.ndarray:
        """Ω in the caller's body frame, Ω = Q1ᵀ s."""
        return self(times)[0] @ self.q1


def torque_free_jacobi(
    inertia_diag: ArrayLike, omega0_body: ArrayLike, times: ArrayLike
) -> np.ndarray:
    """Exact body-frame angular velocity (T, 3) of the torque-free body (L&L §37).

    Any positive principal moments, in any order (ties included); any ``times`` (negative too).
    """
    return _JacobiSolution(inertia_diag, omega0_body).body(times)


# --- torque-free rigid body: exact orientation ------------------------------------------------


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)


def _cumulative_integral(
    f: Callable[[np.ndarray], np.ndarray], times: np.ndarray, step: float
) -> np.ndarray:
    """∫_0^t f for each t in ``times``: composite 16-point Gauss–Legendre on pieces <= ``step``.

    For an integrand analytic on a strip around the real axis the error per piece falls like
    ρ^-32 (ρ > 1 depends on step × the integrand's time scale); at the steps used here this is
    at rounding level.
    """
    grid = np.unique(np.concatenate(([0.0], times)))
    lengths = np.diff(grid)
    if lengths.size == 0:
        return np.zeros_like(times)
    pieces = np.maximum(1, np.ceil(lengths / step).astype(int))
    starts = np.concatenate(
        [
            a + (b - a) * np.arange(n) / n
            for a, b, n in zip(grid[:-1], grid[1:], pieces, strict=True)
        ]
    )
    widths = np.repeat(lengths / pieces, pieces)
    nodes = starts[:, None] + 0.5 * widths[:, None] * (_GL_NODES + 1.0)
    piece_integrals = 0.5 * widths * (f(nodes.ravel()).reshape(nodes.shape) @ _GL_WEIGHTS)
    per_interval = np.add.reduceat(piece_integrals, np.concatenate(([0], np.cumsum(pieces)[:-1])))
    cumulative = np.concatenate(([0.0], np.cumsum(per_interval)))
    cumulative -= cumulative[np.searchsorted(grid, 0.0)]
    return cumulative[np.searchsorted(grid, times)]


def _quat_axis(axis: int, angle: np.ndarray) -> np.ndarray:
    return quat_from_axis_angle(np.eye(3)[axis], angle)


def torque_free_exact(
    inertia_diag: ArrayLike, q0: ArrayLike, omega0_world: ArrayLike, times: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Exact orientation and world angular velocity of the torque-free body, without an ODE solver.

    L&L §37 with Euler angles about the fixed L: R(t) = A Rz(φ) Rx(θ) Rz(ψ), where θ and ψ
    come from the body direction of L (L_body = M (sin θ sin ψ, sin θ cos ψ, cos θ)), so from
    the Jacobi Ω(t), and the precession angle obeys L&L (37.16):

        φ̇ = M (I1 Ω1² + I2 Ω2²) / (I1² Ω1² + I2² Ω2²),

    integrated by Gauss–Legendre quadrature. The Euler angles are taken in a right-handed frame
    whose third axis is the one L circulates about (the "dn" axis), so θ stays away from the
    gimbal-lock values 0 and π. The constant A is fixed by R(0) = R(q0). Returns (q (T, 4)
    sign-continuous from q0, omega_world (T, 3)).
    """
    inertia = np.asarray(inertia_diag, dtype=float)
    q0 = quat_normalize(np.asarray(q0, dtype=float))
    omega0_world = np.asarray(omega0_world, dtype=float)
    times = _as_times(times)
    sol = _JacobiSolution(inertia, rotate_inverse(quat_to_matrix(q0), omega0_world))
    if sol.constant:  # Ω and ω constant: a uniform rotation about ω
        q = quat_multiply(quat_exp(times[:, None] * omega0_world), q0)
        return q, np.broadcast_to(omega0_world, (times.size, 3)).copy()

    # Polar frame y = C s, C cyclic (proper), putting the dn axis last.
    cyc = np.eye(3)[[(sol.d + 1) % 3, (sol.d + 2) % 3, sol.d]]
    to_polar = cyc @ sol.q1  # y = to_polar @ Ω_body
    iy = cyc @ sol.inertia

    def polar_omega(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, ph = sol(t)
        return s @ cyc.T, ph

    big_m = np.linalg.norm(iy * (cyc @ sol.s0))

    def phi_rate(t: np.ndarray) -> np.ndarray:  # L&L (37.16)
        y, _ = polar_omega(t)
        a, b = iy[0] * y[:, 0] ** 2, iy[1] * y[:, 1] ** 2
        return big_m * (a + b) / (iy[0] * a + iy[1] * b)

    # A quadrature piece of a fraction of the fastest time scale (rate of τ, or |ω|).
    scale = max(sol.rate, np.linalg.norm(omega0_world))
    phi = _cumulative_integral(phi_rate, times, 0.25 / scale)

    def theta_psi(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = iy * y / big_m
        theta = np.arctan2(np.hypot(n[:, 0], n[:, 1]), n[:, 2])
        return theta, np.arctan2(n[:, 0], n[:, 1])

    # ψ from atan2 jumps by 2π; lift it with the amplitude α = am(τ), which is continuous. The
    # in-plane components are (a cos α, ±b sin α) up to a quarter turn, so ψ - σα - ψ(α=0)
    # stays in (-π/2, π/2) (σ = ±1: winding direction) and wrapping it recovers the lift.
    # ψ at α = 0 and α = π/2 (sn, cn = 0, 1 and 1, 0; dn only moves the polar component):
    y_ref = sol.from_elliptic(np.array([0.0, 1.0]), np.array([1.0, 0.0]), np.ones(2)) @ cyc.T
    _, psi_ref = theta_psi(y_ref)
    sigma = np.sign(np.sin(psi_ref[1] - psi_ref[0]))

    def lift(raw: np.ndarray, a: np.ndarray) -> np.ndarray:
        base = sigma * a + psi_ref[0]
        return base + np.angle(np.exp(1j * (raw - base)))

    y, alpha = polar_omega(times)
    theta, psi = theta_psi(y)
    psi = lift(psi, alpha)
    y0, alpha0 = polar_omega(np.array([0.0]))
    theta0, psi0 = theta_psi(y0)
    psi0 = lift(psi0, alpha0)

    q_polar = matrix_to_quat(to_polar)  # body → polar frame, as a rotation
    b0 = quat_multiply(quat_multiply(_quat_axis(0, theta0), _quat_axis(2, psi0)), q_polar)
    q_a = quat_multiply(q0, quat_conjugate(b0))[0]
    q = quat_multiply(
        quat_multiply(quat_multiply(q_a, _quat_axis(2, phi)), _quat_axis(0, theta)),
        quat_multiply(_quat_axis(2, psi), q_polar),
    )
    q = quat_normalize(q)
    omega_world = quat_rotate(q, sol.body(times))
    return q, omega_world


# --- closed forms -----------------------------------------------------------------------------


def symmetric_top(
    I_perp: float, I_axis: float, q0: ArrayLike, omega0_world: ArrayLike, times: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Torque-free symmetric body (I1 = I2 = I_perp, body z the symmetry axis), exact.

    In the body frame Ω⊥ turns about e3 at λ = (I_axis - I_perp) / I_perp · Ω3 (Euler's
    equations with I1 = I2), so Ω(t) = Rz(λt) Ω0. Writing L_body = I_perp Ω + (I_axis - I_perp)
    Ω3 e3 gives ω = R Ω = L / I_perp - λ R e3, which is exactly the angular velocity of

        R(t) = Rot(L̂, |L| t / I_perp) R0 Rz(-λ t),

    and R(0) = R0, so this is the solution. In quaternions q(t) = exp(L t / 2I_perp) ∘ q0 ∘
    exp(-λ t e3 / 2), continuous in t and equal to q0 at t = 0.
    """
    q0 = quat_normalize(np.asarray(q0, dtype=float))
    times = _as_times(times)
    omega0_world = np.asarray(omega0_world, dtype=float)
    omega0_body = rotate_inverse(quat_to_matrix(q0), omega0_world)
    inertia = np.array([I_perp, I_perp, I_axis], dtype=float)
    ang_mom = quat_rotate(q0, inertia * omega0_body)  # world L, constant
    lam = (I_axis - I_perp) / I_perp * omega0_body[2]
    precession = quat_exp(times[:, None] * ang_mom / I_perp)
    spin = quat_exp(-lam * times[:, None] * np.array([0.0, 0.0, 1.0]))
    q = quat_multiply(quat_multiply(precession, q0), spin)
    omega_world = ang_mom / I_perp - lam * quat_rotate(q, np.array([0.0, 0.0, 1.0]))
    return q, omega_world


def spin_up(
    inertia_diag: ArrayLike, axis_body_principal: int, torque_magnitude: float, times: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Body at rest, identity orientation, constant world torque T along principal axis ``a``.

    ω stays along e_a (the gyroscopic term ω × Iω vanishes for ω ∥ e_a), so I_a ω̇ = T:
    ω(t) = T t / I_a, angle θ(t) = T t² / (2 I_a). Returns (q (T, 4), omega_world (T, 3)).
    """
    times = _as_times(times)
    inertia_axis = float(np.asarray(inertia_diag, dtype=float)[axis_body_principal])
    axis = np.eye(3)[axis_body_principal]
    rate = torque_magnitude / inertia_axis
    q = quat_from_axis_angle(axis, 0.5 * rate * times**2)
    return q, rate * times[:, None] * axis


def projectile(
    x0: ArrayLike, v0: ArrayLike, g: ArrayLike, times: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Free flight under constant acceleration g: x = x0 + v0 t + ½ g t², v = v0 + g t.

    x0, v0, g broadcast together (e.g. (3,) or (N, 3)); results are (T, *broadcast shape).
    """
    times = _as_times(times)
    x0, v0, g = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x0, v0, g)))
    t = times.reshape((-1,) + (1,) * x0.ndim)
    return x0 + v0 * t + 0.5 * g * t**2, v0 + g * t


def damped_spring(
    mass: float,
    stiffness: float,
    damping: float,
    x0: ArrayLike,
    v0: ArrayLike,
    times: ArrayLike,
) -> tuple[np.ndarray, np.ndarray]:
    """1-D mass on a linear spring with viscous damping: m ẍ = -k x - c ẋ, exact in all regimes.

    With γ = c / 2m, ω0² = k / m and ν² = ω0² - γ² (any sign), the solution is

        x = e^{-γt} (x0 C + (v0 + γ x0) S),   v = e^{-γt} (v0 C - (γ v0 + ω0² x0) S),

    C = cos νt, S = sin(νt) / ν (under-damped); C = cosh μt, S = sinh(μt) / μ with μ² = -ν²
    (over-damped); C = 1, S = t (critical). (Check: C' = -ν² S, S' = C.) These forms stay
    accurate as ν → 0 from either side, with no cancelling exponentials.
    x0, v0 may be arrays (broadcast); results are (T, *shape).
    """
    times = _as_times(times)
    x0, v0 = np.broadcast_arrays(np.asarray(x0, dtype=float), np.asarray(v0, dtype=float))
    t = times.reshape((-1,) + (1,) * x0.ndim)
    gamma = damping / (2.0 * mass)
    omega0_sq = stiffness / mass
    nu_sq = omega0_sq - gamma**2
    if nu_sq > 0:
        nu = np.sqrt(nu_sq)
        c, s = np.cos(nu * t), np.sin(nu * t) / nu
    elif nu_sq < 0:
        mu = np.sqrt(-nu_sq)
        c, s = np.cosh(mu * t), np.sinh(mu * t) / mu
    else:
        c, s = np.ones_like(t), t
    decay = np.exp(-gamma * t)
    x = decay * (x0 * c + (v0 + gamma * x0) * s)
    v = decay * (v0 * c - (gamma * v0 + omega0_sq * x0) * s)
    return x, v
