"""Each integrator against closed forms, an independent reference, and conservation laws.

Tolerances come from each method's order p: a global error behaves as C (ω Δt)^p with C of
order ω T for smooth motion; where an error is known exactly (symplectic Euler on a projectile)
the test asserts that exact value.
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench import reference as ref
from rigid_env.sim.rotation import quat_angle

ORDER = {"euler": 1, "euler_quat": 1, "rk4": 4, "splitting": 2, "splitting4": 4, "implicit_gyro": 1}
GEOMETRIC = ("splitting", "splitting4")
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def test_every_integrator_has_a_known_order():
    assert set(ORDER) <= set(sim.INTEGRATORS)
    assert sim.DEFAULT_INTEGRATOR in sim.INTEGRATORS


def tumbling_box():
    # Principal moments (0.2, 0.4, 0.52) kg m²: asymmetric, like the Reorient satellite.
    return sim.Body.box((0.3, 0.2, 0.1), 12.0)


def run(scene, state, steps, **load):
    for _ in range(steps):
        state = scene.step(state, **load)
    return state


@pytest.mark.parametrize("name", sorted(ORDER))
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
    if name in ("splitting", "splitting4"):
        # Half kicks around an exact rotation integrate a linear ω exactly: rounding only.
        assert errors.max() < 1e-12
        return
    observed = np.log2(errors[0] / errors[1])
    assert abs(observed - ORDER[name]) < 0.3, (errors, observed)
    if ORDER[name] == 1:
        # Symplectic Euler sums Δt ω_k with ω_k = k Δt T/I: θ_N = T t (t + Δt) / (2I), so the
        # error is T t Δt / (2I) (exactly, for `euler`).
        assert errors[0] < 1.05 * torque * t_end * 0.02 / (2 * inertia)


@pytest.mark.parametrize("name", sorted(ORDER))
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


@pytest.mark.parametrize("name", sorted(ORDER))
def test_torque_free_asymmetric_body_against_exact_solution(name):
    """Observed order from two step sizes, near the intermediate axis (the Dzhanibekov flip)."""
    body = tumbling_box()
    t_end = 3.0  # covers the first flip (period ≈ 2.3 s for these moments and spin)
    q_ref, w_ref = ref.torque_free_exact(
        np.diag(body.inertia), IDENTITY, DZHANIBEKOV_OMEGA, np.array([t_end])
    )
    dts = (0.004, 0.002) if ORDER[name] <= 2 else (0.02, 0.01)
    errors = []
    for dt in dts:
        scene = sim.Scene(body, dt, integrator=name)
        state = scene.initial_state(angular_velocity=DZHANIBEKOV_OMEGA)
        state = run(scene, state, round(t_end / dt))
        errors.append(quat_angle(state.orientation[0], q_ref[0]))
    observed = np.log2(errors[0] / errors[1])
    assert abs(observed - ORDER[name]) < 0.3, (name, errors, observed)
    # And the error itself is as small as the order predicts: (ω Δt)^p ω T with ω Δt ≈ 0.006–0.06.
    bound = (3.0 * dts[1]) ** ORDER[name] * 3.0 * t_end * 10
    assert errors[1] < bound


@pytest.mark.parametrize("name", sorted(ORDER))
def test_symmetric_top_precession(name):
    """Symmetric body: the figure axis precesses about L at |L| / I⊥ (closed form)."""
    body = sim.Body.box((0.1, 0.1, 0.3), 3.0)  # I⊥ = I1 = I2 > I3
    i_perp, i_axis = body.inertia[0, 0], body.inertia[2, 2]
    q0 = sim.rotation.quat_from_axis_angle(np.array([1.0, 0.5, 0.0]), 0.4)
    w0 = np.array([0.5, 0.2, 4.0])
    t_end, dt = 2.0, 0.002
    scene = sim.Scene(body, dt, integrator=name)
    state = run(scene, scene.initial_state(orientation=q0, angular_velocity=w0), round(t_end / dt))
    q_ref, w_ref = ref.symmetric_top(i_perp, i_axis, q0, w0, np.array([t_end]))
    error = quat_angle(state.orientation[0], q_ref[0])
    omega = np.linalg.norm(w0)
    assert error < 10 * (omega * dt) ** ORDER[name] * omega * t_end


@pytest.mark.parametrize("name", sorted(ORDER))
def test_torque_free_conservation(name):
    """World L and energy over 5000 steps at ω Δt = 0.03."""
    body = tumbling_box()
    scene = sim.Scene(body, 0.01, integrator=name)
    state = scene.initial_state(angular_velocity=DZHANIBEKOV_OMEGA)
    l0, e0 = scene.angular_momentum(state), scene.kinetic_energy(state)
    energies, momenta = [], []
    for _ in range(50):
        state = run(scene, state, 100)
        energies.append((scene.kinetic_energy(state) - e0) / e0)
        momenta.append(np.linalg.norm(scene.angular_momentum(state) - l0) / np.linalg.norm(l0))
    energies, momenta = np.abs(np.array(energies)), np.array(momenta)
    if name in ("euler", "euler_quat") + GEOMETRIC:
        # L is updated only by torques (here none): rounding only, ~1e-16 per step.
        assert momenta.max() < 1e-11
    if name in GEOMETRIC:
        # Symplectic: the energy error oscillates with amplitude ~ (ω Δt)^p and does not grow.
        assert energies.max() < 10 * 0.03 ** ORDER[name]
        assert energies[25:].max() < 3 * energies[:25].max() + 1e-12
    if name == "implicit_gyro":
        # The implicit gyroscopic term dissipates: energy never grows.
        assert np.all(np.diff(energies) >= -1e-12)
    if name == "rk4":
        assert energies.max() < 10 * 0.03**4 * 3.0 * 50


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


def test_spring_energy_is_conserved_without_damping():
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=50.0, rest_length=0.3, attach=(0.1, 0, 0))
    scene = sim.Scene(tumbling_box(), 1e-3, integrator="splitting", springs=[spring])
    state = scene.initial_state(angular_velocity=(0.5, 1.0, 0.2), linear_velocity=(0.2, 0, 0))
    e0 = scene.energy(state)
    state = run(scene, state, 3000)
    # Symplectic, (ω Δt)² with ω_n = √(k/m) ≈ 2 rad/s and spin ~1 rad/s: ~1e-5 relative.
    assert abs(scene.energy(state) - e0) / e0 < 1e-4


@pytest.mark.parametrize("name", sorted(ORDER))
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
