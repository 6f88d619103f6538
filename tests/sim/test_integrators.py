"""Each integrator against closed forms, an independent reference, and conservation laws.

Tolerances come from each method's order p: a global error behaves as K Δt^p + O(Δt^(p+1))
with an error constant K that the tests measure from two step sizes and then hold the method
to at a third (``assert_error_follows_its_constant``); where an error is known exactly
(symplectic Euler on a projectile) the test asserts that exact value.
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench import accuracy
from rigid_env.bench import reference as ref
from rigid_env.sim.rotation import quat_angle

# Derived from the integrator records, as every other table of orders.
ORDER = {name: record.order for name, record in sim.INTEGRATOR_RECORDS.items()}
GEOMETRIC = tuple(name for name, record in sim.INTEGRATOR_RECORDS.items() if record.symplectic)
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
# Rounding bound of a relative energy difference: KE = ½ m v² + ½ ωᵀ R M0 Rᵀ ω takes a few
# dozen operations on positive terms, each off by at most ½ ulp, so one evaluation errs by
# ≲ 20 ε relative; two evaluations compared: 40 ε ≈ 9e-15, rounded up to 1e-14.
ENERGY_ROUNDING = 1e-14
# The exact torque-free flow: no truncation error on torque-free problems, so no order to fit
# there; one step errs by ≤ 64 ε (1 + |ω| Δt) plus ≤ 4 ε storing q and ω (tests/sim/test_exact.py).
EXACT_FLOW = ("exact", "exact4")
EPS = np.finfo(float).eps


def exact_flow_bound(steps, omega, dt):
    return steps * (64 * EPS * (1 + omega * dt) + 4 * EPS)


def test_every_integrator_has_a_known_order():
    # Every integrator the simulator offers must have an order, or the tables built from it
    # would skip it: the subset goes this way round (an integrator without an order fails).
    assert set(sim.INTEGRATORS) <= set(ORDER)
    assert all(isinstance(ORDER[name], int) and ORDER[name] >= 1 for name in sim.INTEGRATORS)
    assert accuracy.THEORETICAL_ORDER == ORDER  # the bench reads the same records
    assert set(sim.CONTACT_CAPABLE) == {
        n for n, r in sim.INTEGRATOR_RECORDS.items() if r.semi_implicit
    }
    assert sim.DEFAULT_INTEGRATOR in sim.INTEGRATORS


def assert_error_follows_its_constant(errors, dts, order, omega):
    """``errors`` at step sizes ``dts = (h, h/2, h/4)`` of a method of the given order.

    The global error is e(h) = a h^p + b h^(p+1) + c h^(p+2) + …; a (the method's error
    constant on this problem) and b are fitted to the two coarser runs, and the finest error
    must be their prediction. What the fit leaves out is the c term, relatively ~ |c h²/a| at
    the finest step. In the asymptotic regime each term is smaller than the last, so that is
    below the first correction's own size |b h / a| ≈ 2 |r|, r = e(h) / (2^p e(h/2)) − 1; a
    symmetric method has no odd terms (b ≈ 0, r ≈ 0), and then its next even term, relatively
    (ω h)², bounds it. The observed order must also be p to within 0.1.
    """
    e1, e2, e3 = errors
    h, p = dts[0], order
    assert dts[1] == h / 2 and dts[2] == h / 4
    a, b = np.linalg.solve([[h**p, h ** (p + 1)], [(h / 2) ** p, (h / 2) ** (p + 1)]], [e1, e2])
    predicted = a * (h / 4) ** p + b * (h / 4) ** (p + 1)
    r = e1 / (2**p * e2) - 1
    tolerance = max(2 * abs(r), (omega * h) ** 2)
    assert abs(e3 / predicted - 1) <= tolerance, (errors, predicted, tolerance)
    assert abs(np.log2(e2 / e3) - p) < 0.1, errors


def tumbling_box():
    # Principal moments (0.2, 0.4, 0.52) kg m²: asymmetric, like the Reorient satellite.
    return sim.Body.box((0.3, 0.2, 0.1), 12.0)


def run(scene, state, steps, **load):
    for _ in range(steps):
        state = scene.step(state, **load)
    return state


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_spin_up_under_constant_torque(name):
    """ω(t) = T t / I about a principal axis; the angle T t²/(2I) converges at the method's order."""
    body = tumbling_box()
    inertia, torque, t_end = body.inertia[0, 0], 0.3, 2.0
    errors = []
    for dt in (0.02, 0.01):
        scene = sim.Scene(body, dt, integrator=name)
        state = run(scene, scene.initial_state(), round(t_end / dt), torque=(torque, 0, 0))
        # Torque along a principal axis: no gyroscopic coupling, so ω is exact for every method
        # (a linear function of t); only rounding remains (~1e-15 per step).
        assert np.allclose(state.angular_velocity[0], [torque * t_end / inertia, 0, 0], atol=1e-12)
        q_exact, _ = ref.spin_up(np.diag(body.inertia), 0, torque, np.array([t_end]))
        errors.append(quat_angle(state.orientation[0], q_exact[0]))
    errors = np.array(errors)
    if name in ("splitting", "splitting4", *EXACT_FLOW):
        # Half kicks around an exact rotation integrate a linear ω exactly: rounding only.
        assert errors.max() < 1e-12
        return
    observed = np.log2(errors[0] / errors[1])
    assert abs(observed - ORDER[name]) < 0.3, (errors, observed)
    if ORDER[name] == 1:
        # Symplectic Euler sums Δt ω_k with ω_k = k Δt T/I: θ_N = T t (t + Δt) / (2I), so the
        # error is T t Δt / (2I) (exactly, for `euler`).
        assert errors[0] < 1.05 * torque * t_end * 0.02 / (2 * inertia)


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_projectile(name):
    g = np.array([0.0, 0.0, -9.81])
    x0, v0, dt, steps = np.array([0.0, 0, 10]), np.array([3.0, -1.0, 5.0]), 0.01, 150
    scene = sim.Scene(sim.Body.sphere(0.1, 1.0), dt, integrator=name, gravity=g)
    state = run(scene, scene.initial_state(position=x0, linear_velocity=v0), steps)
    t = dt * steps
    x_exact, v_exact = ref.projectile(x0, v0, g, np.array([t]))
    assert np.allclose(state.linear_velocity[0], v_exact[0], atol=1e-12)
    if ORDER[name] == 1:
        # Symplectic Euler: x_N = x0 + v0 t + ½ g t (t + Δt); the extra ½ g t Δt is exact.
        assert np.allclose(state.position[0] - x_exact[0], 0.5 * g * t * dt, atol=1e-12)
    else:
        assert np.allclose(state.position[0], x_exact[0], atol=1e-12)


DZHANIBEKOV_OMEGA = np.array([0.05, 3.0, 0.05])  # near the unstable intermediate axis


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_torque_free_asymmetric_body_against_exact_solution(name):
    """Error constant and order from three step sizes, near the intermediate axis (the
    Dzhanibekov flip) against the exact solution."""
    body = tumbling_box()
    t_end = 3.0  # covers the first flip (period ≈ 2.3 s for these moments and spin)
    q_ref, _ = ref.torque_free_exact(
        np.diag(body.inertia), IDENTITY, DZHANIBEKOV_OMEGA, np.array([t_end])
    )
    dts = (0.004, 0.002, 0.001) if ORDER[name] <= 2 else (0.02, 0.01, 0.005)
    errors = []
    for dt in dts:
        scene = sim.Scene(body, dt, integrator=name)
        state = scene.initial_state(angular_velocity=DZHANIBEKOV_OMEGA)
        state = run(scene, state, round(t_end / dt))
        errors.append(quat_angle(state.orientation[0], q_ref[0]))
    omega = np.linalg.norm(DZHANIBEKOV_OMEGA)
    if name in EXACT_FLOW:
        # Rounding only, plus the reference's own error near the separatrix (4e-11, see
        # tests/bench/test_reference.py); ω doubles as the flip's phase sensitivity here.
        assert max(errors) < 4e-11 + exact_flow_bound(round(t_end / dts[-1]), omega, dts[-1])
        return
    assert_error_follows_its_constant(errors, dts, ORDER[name], omega)


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_symmetric_top_precession(name):
    """Symmetric body: the figure axis precesses about L at |L| / I⊥ (closed form)."""
    body = sim.Body.box((0.1, 0.1, 0.3), 3.0)  # I⊥ = I1 = I2 > I3
    i_perp, i_axis = body.inertia[0, 0], body.inertia[2, 2]
    q0 = sim.rotation.quat_from_axis_angle(np.array([1.0, 0.5, 0.0]), 0.4)
    w0 = np.array([0.5, 0.2, 4.0])
    t_end = 2.0
    q_ref, _ = ref.symmetric_top(i_perp, i_axis, q0, w0, np.array([t_end]))
    dts = (0.004, 0.002, 0.001) if ORDER[name] <= 2 else (0.04, 0.02, 0.01)
    errors = []
    for dt in dts:
        scene = sim.Scene(body, dt, integrator=name)
        state = scene.initial_state(orientation=q0, angular_velocity=w0)
        state = run(scene, state, round(t_end / dt))
        errors.append(quat_angle(state.orientation[0], q_ref[0]))
    if name in EXACT_FLOW:  # rounding only, against a closed form
        omega = np.linalg.norm(w0)
        assert max(errors) < exact_flow_bound(round(t_end / dts[-1]), omega, dts[-1])
        return
    assert_error_follows_its_constant(errors, dts, ORDER[name], np.linalg.norm(w0))


# What each integrator keeps in torque-free motion (the integrators' table): every one must
# claim something, or the test below would pass it unchecked.
CONSERVES_L = ("euler", "euler_quat", "splitting", "splitting4", *EXACT_FLOW)
NEVER_GAINS_ENERGY = ("implicit_gyro", "implicit")


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_torque_free_conservation(name):
    """World L and energy over 5000 steps at ω Δt = 0.03."""
    assert name in CONSERVES_L + NEVER_GAINS_ENERGY + ("rk4",)
    body = tumbling_box()
    scene = sim.Scene(body, 0.01, integrator=name)
    state = scene.initial_state(angular_velocity=DZHANIBEKOV_OMEGA)
    l0, e0 = scene.angular_momentum(state), scene.kinetic_energy(state)
    energies, momenta = [], []
    for _ in range(50):
        state = run(scene, state, 100)
        energies.append((scene.kinetic_energy(state) - e0) / e0)
        momenta.append(np.linalg.norm(scene.angular_momentum(state) - l0) / np.linalg.norm(l0))
    gain, momenta = np.array(energies), np.array(momenta)  # signed: > 0 is energy gained
    if name in CONSERVES_L:
        # L is updated only by torques (here none): rounding only, ~1e-16 per step.
        assert momenta.max() < 1e-11
    if name in GEOMETRIC:
        # Symplectic: the energy error oscillates with amplitude ~ (ω Δt)^p and does not grow.
        assert np.abs(gain).max() < 10 * 0.03 ** ORDER[name]
        assert np.abs(gain[25:]).max() < 3 * np.abs(gain[:25]).max() + 1e-12
    if name in NEVER_GAINS_ENERGY:
        # The implicit gyroscopic term dissipates: energy never exceeds its start, and never
        # rises from one sample to the next, beyond the rounding of its evaluation.
        assert gain.max() <= ENERGY_ROUNDING
        assert np.diff(gain).max() <= ENERGY_ROUNDING
        assert gain[-1] < -1e-3  # and it does dissipate (a check that could be false)
    if name == "rk4":
        assert np.abs(gain).max() < 10 * 0.03**4 * 3.0 * 50


def test_implicit_gyro_is_stable_for_a_needle_where_euler_is_not():
    """Catto (GDC 2015): an elongated body spun off-axis at a game time step."""
    needle = sim.Body(1.0, np.diag([1.0, 1.0, 1e-3]))  # inertia ratio 1e-3
    w0 = np.array([0.0, 2.0, 40.0])
    dt = 1 / 60
    energies = {}
    for name in ("euler_quat", "implicit_gyro"):
        scene = sim.Scene(needle, dt, integrator=name)
        state = scene.initial_state(angular_velocity=w0)
        e0 = scene.kinetic_energy(state)
        state = run(scene, state, 600)
        energies[name] = scene.kinetic_energy(state) / e0
    assert energies["implicit_gyro"] <= 1.0
    assert energies["euler_quat"] > 2.0  # the explicit gyroscopic term pumps energy in


def test_notes_euler_keeps_rotation_orthonormal_and_matches_quaternion_form_to_first_order():
    body = tumbling_box()
    states = {}
    for name in ("euler", "euler_quat"):
        scene = sim.Scene(body, 1e-3, integrator=name)
        states[name] = run(scene, scene.initial_state(angular_velocity=(1.0, 0.5, 0.2)), 500)
        rot = states[name].rotation[0]
        assert np.allclose(rot.T @ rot, np.eye(3), atol=1e-13)
    # Both are first-order approximations of the same flow: they differ by O(ω Δt) ω T.
    assert quat_angle(states["euler"].orientation[0], states["euler_quat"].orientation[0]) < 1e-3


def test_angular_damping_decays_momentum_exponentially():
    """L̇ = −γ L: |L(t)| = |L0| e^{−γ t}, with L's direction fixed (closed form)."""
    gamma, dt, steps = 0.5, 1e-3, 2000
    scene = sim.Scene(tumbling_box(), dt, integrator="splitting", angular_damping=gamma)
    state = scene.initial_state(angular_velocity=(0.3, 2.0, 0.1))
    l0 = scene.angular_momentum(state)
    state = run(scene, state, steps)
    expected = l0 * np.exp(-gamma * dt * steps)
    # Second order in γ Δt = 5e-4 over γ t = 1: relative error ~ (γΔt)² ≈ 2.5e-7.
    assert np.allclose(scene.angular_momentum(state), expected, rtol=1e-6)


@pytest.mark.parametrize("damping", [0.0, 0.8, 4.0, 6.0])
def test_damped_spring_oscillator(damping):
    """A sphere on a zero-length spring at its centre: x'' = −(k x + c x')/m (closed form)."""
    m, k, dt, steps = 1.0, 4.0, 1e-3, 3000  # ω_n = 2 rad/s; c = 4 is critical
    spring = sim.Spring(0, anchor=(0, 0, 0), stiffness=k, damping=damping)
    scene = sim.Scene(sim.Body.sphere(0.1, m), dt, integrator="splitting", springs=[spring])
    state = scene.initial_state(position=(0.5, 0, 0), linear_velocity=(0, 0.3, 0))
    state = run(scene, state, steps)
    t = np.array([dt * steps])
    x_exact, _ = ref.damped_spring(m, k, damping, np.array([0.5, 0, 0]), np.array([0, 0.3, 0]), t)
    # Velocity Verlet with a velocity-dependent force: second order, (ω_n Δt)² ω_n t ≈ 2.4e-5.
    assert np.allclose(state.position[0], x_exact[0], atol=1e-4)
    assert scene.stages == ("springs", "integrate")


@pytest.mark.parametrize("damping", [0.8, 4.0])
@pytest.mark.parametrize("name", GEOMETRIC)
def test_splittings_keep_their_order_with_damping(name, damping):
    """Damped spring (closed form; c = 4 is critical): the closing half kick is the implicit
    adjoint of the explicit opening one, so the Strang step stays symmetric and Yoshida's
    composition fourth order (the Heun corrector it replaces measured 2.95 here)."""
    m, k, t_end = 1.0, 4.0, 3.0
    x0, v0 = np.array([0.5, 0, 0]), np.array([0, 0.3, 0])
    x_exact, _ = ref.damped_spring(m, k, damping, x0, v0, np.array([t_end]))
    dts = (0.02, 0.01, 0.005) if ORDER[name] == 2 else (0.04, 0.02, 0.01)
    errors = []
    for dt in dts:
        spring = sim.Spring(0, anchor=(0, 0, 0), stiffness=k, damping=damping)
        scene = sim.Scene(sim.Body.sphere(0.1, m), dt, integrator=name, springs=[spring])
        state = run(scene, scene.initial_state(position=x0, linear_velocity=v0), round(t_end / dt))
        errors.append(np.linalg.norm(state.position[0] - x_exact[0]))
    assert_error_follows_its_constant(errors, dts, ORDER[name], np.sqrt(k / m))


def test_splitting4_is_fourth_order_with_coupled_damping():
    """A tumbling box on an offset spring with rest length, spring damping, linear and angular
    damping and gravity (no closed form): against splitting4 at Δt/32, whose own error is
    32⁻⁴ ≈ 1e-6 of the coarsest run's, 2.5e-4 of the finest run's (1/256 of it)."""
    body = tumbling_box()
    spring = sim.Spring(0, (0, 0, 1), 50.0, damping=3.0, rest_length=0.3, attach=(0.1, 0.05, 0))

    def final(dt, t_end=1.0):
        scene = sim.Scene(
            body,
            dt,
            integrator="splitting4",
            springs=[spring],
            gravity=(0, 0, -9.81),
            linear_damping=0.3,
            angular_damping=0.5,
        )
        state = scene.initial_state(angular_velocity=(0.5, 1.0, 0.2), linear_velocity=(0.2, 0, 0))
        return run(scene, state, round(t_end / dt))

    dts = (0.04, 0.02, 0.01)
    best = final(dts[0] / 32)
    errors = []
    for dt in dts:
        state = final(dt)
        errors.append(
            np.linalg.norm(state.position - best.position)
            + quat_angle(state.orientation[0], best.orientation[0])
        )
    # Fastest rate in the problem: the spring's √(k/m) ≈ 2 rad/s, the spin ≈ 1.1 rad/s.
    assert_error_follows_its_constant(errors, dts, 4, 2.5)


def test_spring_energy_is_conserved_without_damping():
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=50.0, rest_length=0.3, attach=(0.1, 0, 0))
    scene = sim.Scene(tumbling_box(), 1e-3, integrator="splitting", springs=[spring])
    state = scene.initial_state(angular_velocity=(0.5, 1.0, 0.2), linear_velocity=(0.2, 0, 0))
    e0 = scene.energy(state)
    state = run(scene, state, 3000)
    # Symplectic, (ω Δt)² with ω_n = √(k/m) ≈ 2 rad/s and spin ~1 rad/s: ~1e-5 relative.
    assert abs(scene.energy(state) - e0) / e0 < 1e-4


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_batch_equals_single(name):
    rng = np.random.default_rng(7)
    body = tumbling_box()
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=20.0, damping=0.3, attach=(0.1, 0.0, 0.05))
    scene = sim.Scene(body, 0.01, integrator=name, gravity=(0, 0, -9.81), springs=[spring])
    batch = scene.initial_state(
        position=rng.standard_normal((5, 1, 3)),
        orientation=rng.standard_normal((5, 1, 4)),
        linear_velocity=rng.standard_normal((5, 1, 3)),
        angular_velocity=3 * rng.standard_normal((5, 1, 3)),
    )
    torque = rng.standard_normal((5, 1, 3))
    stepped = run(scene, batch, 20, torque=torque)
    for i in range(5):
        single = run(scene, batch[i], 20, torque=torque[i])
        for a, b in zip(stepped[i].arrays(), single.arrays(), strict=True):
            assert np.array_equal(a, b)  # bit for bit: elementwise arithmetic only
