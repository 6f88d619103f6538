"""The reference solutions are checked against their ODEs and against each other.

Tolerance sources (measured, then given a margin of 2-10x):
* DOP853 at rtol = atol = 1e-13 is not converged to rounding: halving/doubling the tolerance
  moves Ω by ~1e-9 over 20 s near the separatrix (|Ω| = 5) and ~1e-12 elsewhere. Near the
  separatrix its rounding is amplified (each rounding moves the body to a neighbouring orbit),
  so its error there is not a fixed number across scipy and numpy releases: the bound is twice
  the spread of its own answers at rtol = atol = 1e-13, 5e-14 and 3e-14 (measured 2e-10 to
  1.3e-8 over these cases), computed in the test.
* The Jacobi solution agrees with a 40-digit mpmath evaluation of the same formulas to ~4e-11
  near the separatrix (ellipj sees k² = 1 - 8e-6 only to double precision) and to rounding
  elsewhere.
* Finite differences: 4th-order central, h = 1e-3 s: truncation h⁴ |f⁽⁵⁾| / 30 ~ 1e-10 for
  |ω| <= 5 rad/s, rounding ~ eps / h ~ 1e-13.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rigid_env.bench.reference import (
    damped_spring,
    projectile,
    spin_up,
    symmetric_top,
    torque_free_dop853,
    torque_free_exact,
    torque_free_jacobi,
)
from rigid_env.sim.rotation import (
    quat_conjugate,
    quat_multiply,
    quat_rotate,
    quat_to_matrix,
    random_quaternions,
    rotate_inverse,
)

TIMES = np.linspace(0.0, 20.0, 401)
H = 1e-3


def geodesic(a, b):
    """Rotation angle between unit quaternions, accurate for small angles.

    (``rotation.quat_angle`` uses arccos, whose resolution near 1 is ~4e-8 rad.)
    """
    rel = quat_multiply(quat_conjugate(a), b)
    return 2 * np.arctan2(np.linalg.norm(rel[..., :3], axis=-1), np.abs(rel[..., 3]))


def fd(f, t):
    """4th-order central difference of f (returning arrays with time first) at times t."""
    stencil = np.array([-2, -1, 1, 2]) * H
    vals = f(np.concatenate([t + s for s in stencil])).reshape(4, t.size, -1)
    return (vals[0] - 8 * vals[1] + 8 * vals[2] - vals[3]) / (12 * H)


def kinematics_residual(q_of_t, w_of_t, t):
    """|q̇ - ½ (ω, 0) ∘ q| with ω in the world frame (the notes' convention)."""
    dq = fd(q_of_t, t)
    q, w = q_of_t(t), w_of_t(t)
    return np.abs(dq - 0.5 * quat_multiply(np.concatenate((w, 0 * w[:, :1]), axis=1), q)).max()


# (inertia, Ω0 body). Covers both sides of the separatrix (M² ≷ 2 E I2), sign patterns, sorted,
# odd (3,2,1), (2,1,3) and even (2,3,1) axis orders, and symmetric bodies.
CASES = {
    "dzhanibekov": ((1.0, 2.0, 3.0), (0.01, 5.0, 0.01)),  # M² > 2EI2, flips every ~2 s
    "dzhanibekov_below": ((1.0, 2.0, 3.0), (0.012, 5.0, 0.004)),  # M² < 2EI2, flips
    "dzhanibekov_reversed": ((3.0, 2.0, 1.0), (-0.01, 5.0, 0.01)),  # odd permutation
    "above": ((1.0, 2.0, 3.0), (1.0, 0.5, -3.0)),
    "below": ((1.0, 2.0, 3.0), (-3.0, 0.5, 1.0)),
    "odd_perm": ((2.0, 1.0, 3.0), (-0.3, 4.0, 0.2)),
    "even_perm": ((2.0, 3.0, 1.0), (1.0, -2.0, -0.5)),
    "prolate_sym": ((1.0, 1.0, 2.0), (1.0, 0.5, 3.0)),
    "oblate_sym": ((2.0, 2.0, 1.0), (1.0, 0.5, 3.0)),
}
NEAR_SEPARATRIX = {"dzhanibekov", "dzhanibekov_below", "dzhanibekov_reversed"}


def _initial(name):
    inertia, omega_body = CASES[name]
    rng = np.random.default_rng(sorted(CASES).index(name))
    q0 = random_quaternions(rng)
    omega_world = quat_rotate(q0, np.array(omega_body))
    return np.array(inertia), np.array(omega_body), q0, omega_world


@pytest.fixture(scope="module")
def dop853_runs():
    runs = {}
    for name in CASES:
        inertia, _, q0, w0 = _initial(name)
        runs[name] = torque_free_dop853(inertia, q0, w0, TIMES)
    return runs


def _margin_below_separatrix(inertia, omega):
    """(M² - 2EI2) sign, in sorted axes."""
    order = np.argsort(inertia)
    i, w = inertia[order], omega[order]
    return np.sum(i * (i - i[1]) * w**2)


def test_separatrix_cases_flip_and_cover_both_sides():
    sides = set()
    for name in NEAR_SEPARATRIX:
        inertia, omega, _, _ = _initial(name)
        sides.add(np.sign(_margin_below_separatrix(inertia, omega)))
        intermediate = np.argsort(inertia)[1]
        w = torque_free_jacobi(inertia, omega, TIMES)[:, intermediate]
        assert np.count_nonzero(np.diff(np.sign(w))) >= 4  # the flips happen in the horizon
    assert sides == {-1.0, 1.0}


@pytest.mark.parametrize("name", list(CASES))
def test_jacobi_matches_dop853(name, dop853_runs):
    inertia, omega_body, _, _ = _initial(name)
    q, w = dop853_runs[name]
    omega_dop = rotate_inverse(quat_to_matrix(q), w)
    omega_jac = torque_free_jacobi(inertia, omega_body, TIMES)
    # t = 0 reproduces Ω0 to rounding: near the separatrix dn = √(1 - k² sn²) with k² ≈ 1 loses
    # a few digits to cancellation (measured 6e-14 at |Ω| = 5).
    np.testing.assert_allclose(omega_jac[0], omega_body, rtol=0, atol=2e-13)
    tol = 2e-11  # DOP853's own error, see module doc
    if name in NEAR_SEPARATRIX:
        _, _, q0, w0 = _initial(name)
        answers = [omega_dop]
        for rtol in (5e-14, 3e-14):
            q, w = torque_free_dop853(inertia, q0, w0, TIMES, rtol=rtol, atol=rtol)
            answers.append(rotate_inverse(quat_to_matrix(q), w))
        spread = max(np.abs(a - b).max() for a in answers for b in answers)
        tol = 2 * spread
    assert np.abs(omega_jac - omega_dop).max() < tol


@pytest.mark.parametrize("name", list(CASES))
def test_jacobi_satisfies_euler(name):
    inertia, omega_body, _, _ = _initial(name)
    t = np.linspace(-1.0, 20.0, 97)
    omega = torque_free_jacobi(inertia, omega_body, t)
    domega = fd(lambda s: torque_free_jacobi(inertia, omega_body, s), t)
    residual = inertia * domega - np.cross(inertia * omega, omega)
    assert np.abs(residual).max() < 1e-8  # FD truncation ~1e-10 * |I| and |ω|⁵ ~ 3e3 margin


def test_jacobi_against_mpmath():
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 40
    # Dzhanibekov case in L&L's own form (I1 < I2 < I3, M² > 2EI2, all components positive).
    i1, i2, i3 = (mp.mpf(v) for v in (1, 2, 3))
    w = [mp.mpf(v) for v in (0.01, 5.0, 0.01)]
    d1 = i2 * (i2 - i1) * w[1] ** 2 + i3 * (i3 - i1) * w[2] ** 2
    d3 = i1 * (i3 - i1) * w[0] ** 2 + i2 * (i3 - i2) * w[1] ** 2
    amp = [mp.sqrt(d3 / (i1 * (i3 - i1))), mp.sqrt(d3 / (i2 * (i3 - i2)))]
    amp.append(mp.sqrt(d1 / (i3 * (i3 - i1))))
    rate, m = mp.sqrt((i3 - i2) * d1 / (i1 * i2 * i3)), (i2 - i1) * d3 / ((i3 - i2) * d1)
    tau0 = mp.ellipf(mp.atan2(w[1] / amp[1], w[0] / amp[0]), m)
    t = np.linspace(0.0, 20.0, 21)
    exact = [
        [
            float(a * mp.ellipfun(f, rate * mp.mpf(s) + tau0, m=m))
            for a, f in zip(amp, ("cn", "sn", "dn"), strict=True)
        ]
        for s in t
    ]
    ours = torque_free_jacobi((1.0, 2.0, 3.0), (0.01, 5.0, 0.01), t)
    assert np.abs(ours - np.array(exact)).max() < 2e-10  # measured 3.6e-11


@pytest.mark.parametrize(
    ("inertia", "omega"),
    [
        ((1.0, 2.0, 3.0), (0.0, 4.0, 0.0)),
        ((1.0, 2.0, 3.0), (0.0, 0.0, -2.0)),
        ((2, 2, 2), (1, 2, 3)),
    ],
)
def test_relative_equilibria_are_constant(inertia, omega):
    q0 = random_quaternions(np.random.default_rng(5))
    w0 = quat_rotate(q0, np.array(omega, dtype=float))
    np.testing.assert_array_equal(
        torque_free_jacobi(inertia, omega, TIMES), np.tile(omega, (401, 1))
    )
    q, w = torque_free_exact(inertia, q0, w0, TIMES)
    np.testing.assert_array_equal(w, np.tile(w0, (401, 1)))
    # DOP853 only up to 5 s: spin about the intermediate axis is unstable (growth rate 2.3/s
    # here), so its rounding errors grow like 1e-16 e^{2.3 t}.
    short = TIMES[TIMES <= 5.0]
    q_ref, _ = torque_free_dop853(inertia, q0, w0, short)
    assert geodesic(q[: short.size], q_ref).max() < 1e-10


@pytest.mark.parametrize("name", list(CASES))
def test_exact_orientation_matches_dop853(name, dop853_runs):
    inertia, _, q0, w0 = _initial(name)
    q_dop, w_dop = dop853_runs[name]
    q, w = torque_free_exact(inertia, q0, w0, TIMES)
    np.testing.assert_allclose(q[0], q0, rtol=0, atol=1e-14)
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0)  # sign-continuous
    assert np.abs(q - q_dop).max() < 1e-8  # same sign branch as DOP853, not just same rotation
    assert geodesic(q, q_dop).max() < 1e-8  # measured <= 2e-10 (DOP853 error dominates)
    assert np.abs(w - w_dop).max() < 5e-9


@pytest.mark.parametrize("name", ["dzhanibekov", "below", "prolate_sym"])
def test_exact_orientation_satisfies_kinematics(name):
    inertia, _, q0, w0 = _initial(name)
    t = np.linspace(0.0, 20.0, 41)[1:]
    residual = kinematics_residual(
        lambda s: torque_free_exact(inertia, q0, w0, s)[0],
        lambda s: torque_free_exact(inertia, q0, w0, s)[1],
        t,
    )
    assert residual < 1e-8  # FD truncation, see module doc


@pytest.mark.parametrize("name", list(CASES))
def test_references_conserve_energy_and_momentum(name, dop853_runs):
    inertia, _, q0, w0 = _initial(name)
    for q, w in (dop853_runs[name], torque_free_exact(inertia, q0, w0, TIMES)):
        omega_body = rotate_inverse(quat_to_matrix(q), w)
        energy = 0.5 * np.sum(inertia * omega_body**2, axis=1)
        momentum = quat_rotate(q, inertia * omega_body)  # world L: constant vector
        assert np.abs(energy / energy[0] - 1).max() < 1e-11
        assert np.abs(momentum - momentum[0]).max() < 1e-11 * np.linalg.norm(momentum[0])


# --- closed forms -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("i_perp", "i_axis", "omega_body"),
    [(1.0, 2.0, (1.0, 0.5, 3.0)), (2.0, 1.0, (-1.0, 0.5, 3.0)), (1.5, 1.5, (1.0, 2.0, 0.5))],
)
def test_symmetric_top(i_perp, i_axis, omega_body):
    q0 = random_quaternions(np.random.default_rng(1))
    w0 = quat_rotate(q0, np.array(omega_body))
    q, w = symmetric_top(i_perp, i_axis, q0, w0, TIMES)
    q_dop, w_dop = torque_free_dop853((i_perp, i_perp, i_axis), q0, w0, TIMES)
    np.testing.assert_allclose(q[0], q0, rtol=0, atol=1e-15)
    assert geodesic(q, q_dop).max() < 1e-9
    assert np.abs(q - q_dop).max() < 1e-9  # same sign branch
    assert np.abs(w - w_dop).max() < 1e-10
    t = TIMES[1::20]
    assert (
        kinematics_residual(
            lambda s: symmetric_top(i_perp, i_axis, q0, w0, s)[0],
            lambda s: symmetric_top(i_perp, i_axis, q0, w0, s)[1],
            t,
        )
        < 1e-9
    )
    # World L = R I Rᵀ ω is constant (torque-free).
    inertia = np.array([i_perp, i_perp, i_axis])
    momentum = quat_rotate(q, inertia * rotate_inverse(quat_to_matrix(q), w))
    assert np.abs(momentum - momentum[0]).max() < 1e-12 * np.linalg.norm(momentum[0])


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_spin_up(axis):
    inertia, torque = np.array([1.0, 2.0, 3.0]), 1.5
    t = np.linspace(0.0, 5.0, 51)
    q, w = spin_up(inertia, axis, torque, t)
    # Kinematics and Euler's equation in the world frame: d(Mω)/dt = τ, M = R M0 Rᵀ.
    assert (
        kinematics_residual(
            lambda s: spin_up(inertia, axis, torque, s)[0],
            lambda s: spin_up(inertia, axis, torque, s)[1],
            t,
        )
        < 1e-8
    )

    def momentum(s):
        qq, ww = spin_up(inertia, axis, torque, s)
        rot = quat_to_matrix(qq)
        return np.einsum("tij,j,tkj,tk->ti", rot, inertia, rot, ww)

    np.testing.assert_allclose(
        fd(momentum, t), np.tile(torque * np.eye(3)[axis], (t.size, 1)), atol=1e-9
    )

    # Independent route: DOP853 on (q, ω_body) with the world torque mapped to the body.
    def rhs(_t, y):
        qq, om = y[:4], y[4:]
        tau_body = rotate_inverse(quat_to_matrix(qq / np.linalg.norm(qq)), torque * np.eye(3)[axis])
        dom = (tau_body + np.cross(inertia * om, om)) / inertia
        return np.concatenate((0.5 * quat_multiply(qq, np.append(om, 0.0)), dom))

    sol = solve_ivp(rhs, (0, 5), [0, 0, 0, 1, 0, 0, 0], "DOP853", t_eval=t, rtol=1e-12, atol=1e-12)
    assert geodesic(q, sol.y[:4].T / np.linalg.norm(sol.y[:4], axis=0)[:, None]).max() < 1e-9


def test_projectile():
    x0, v0, g = (
        np.array([[0.0, 1.0, 2.0], [1.0, -1.0, 0.0]]),
        np.array([3.0, 0.0, 4.0]),
        np.array([0, 0, -9.81]),
    )
    t = np.linspace(0.0, 2.0, 11)
    x, v = projectile(x0, v0, g, t)
    assert x.shape == (11, 2, 3)
    np.testing.assert_array_equal(x[0], x0)
    np.testing.assert_allclose(
        fd(lambda s: projectile(x0, v0, g, s)[0].reshape(s.size, -1), t),
        v.reshape(11, -1),
        atol=1e-11,
    )
    acc = fd(lambda s: projectile(x0, v0, g, s)[1].reshape(s.size, -1), t)
    np.testing.assert_allclose(acc, np.tile(g, (11, 2)), atol=1e-11)


@pytest.mark.parametrize(
    ("mass", "stiffness", "damping"),
    [
        (2.0, 50.0, 0.0),  # undamped
        (2.0, 50.0, 3.0),  # under-damped
        (2.0, 50.0, 20.0),  # critical: c² = 4 k m
        (2.0, 50.0, 20.0 + 1e-7),  # barely over-damped: no cancellation trouble
        (2.0, 50.0, 60.0),  # over-damped
    ],
)
def test_damped_spring(mass, stiffness, damping):
    x0, v0 = np.array([0.3, -1.0]), np.array([-2.0, 0.5])
    t = np.linspace(0.0, 4.0, 81)
    x, v = damped_spring(mass, stiffness, damping, x0, v0, t)
    np.testing.assert_array_equal(x[0], x0)
    np.testing.assert_allclose(v[0], v0, rtol=0, atol=1e-15)

    def f(s):
        return np.concatenate(damped_spring(mass, stiffness, damping, x0, v0, s), axis=1)

    d = fd(f, t)
    np.testing.assert_allclose(d[:, :2], v, atol=1e-9)  # ẋ = v
    np.testing.assert_allclose(mass * d[:, 2:], -stiffness * x - damping * v, atol=1e-7)  # |a| ~ 50
    for i in range(2):
        sol = solve_ivp(
            lambda _t, y: [y[1], -(stiffness * y[0] + damping * y[1]) / mass],
            (0, 4),
            [x0[i], v0[i]],
            "DOP853",
            t_eval=t,
            rtol=1e-13,
            atol=1e-14,
        )
        np.testing.assert_allclose(x[:, i], sol.y[0], atol=1e-11)
        np.testing.assert_allclose(v[:, i], sol.y[1], atol=1e-10)


def test_damped_spring_continuous_across_critical():
    t = np.linspace(0.0, 4.0, 41)
    crit = damped_spring(2.0, 50.0, 20.0, 0.3, -2.0, t)
    for c in (20.0 - 1e-6, 20.0 + 1e-6):
        near = damped_spring(2.0, 50.0, c, 0.3, -2.0, t)
        assert np.abs(near[0] - crit[0]).max() < 1e-6 and np.abs(near[1] - crit[1]).max() < 1e-6
