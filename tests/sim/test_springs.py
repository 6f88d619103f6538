"""Stiff springs: linearised backward Euler stays bounded where symplectic Euler diverges."""

import numpy as np
import pytest

from rigid_env import sim


def _spring_scene(ratio, integrator, damping=0.0, dt=0.01, mass=1.0):
    k = ratio * mass / dt**2  # ratio = k Δt² / m = (ω_n Δt)²
    ball = sim.Body.sphere(0.1, mass)
    spring = sim.Spring(0, (0, 0, 0), k, damping=damping)
    return sim.Scene(ball, dt, integrator=integrator, springs=[spring])


def test_implicit_bounded_at_huge_stiffness():
    scene = _spring_scene(1e6, "implicit")
    state = scene.initial_state(position=(0.1, 0, 0), linear_velocity=(0, 1.0, 0))
    e0 = scene.energy(state)
    for _ in range(200):
        state = scene.step(state)
        assert scene.energy(state) <= e0  # backward Euler only dissipates
    assert np.abs(state.position).max() < 0.1


@pytest.mark.parametrize("omega_dt,grows", [(1.9, False), (2.1, True)])
def test_symplectic_euler_limit_is_omega_dt_2(omega_dt, grows):
    # Symplectic Euler on x'' = −ω² x has eigenvalues of modulus 1 for ω Δt < 2 (amplitude
    # bounded by A / sqrt(1 − (ωΔt/2)²)) and a real eigenvalue < −1 beyond.
    scene = _spring_scene(omega_dt**2, "euler_quat")
    state = scene.initial_state(position=(0.1, 0, 0))
    peak = 0.0
    try:
        for _ in range(200):
            state = scene.step(state)
            peak = max(peak, np.abs(state.position).max())
    except sim.DivergenceError:
        peak = np.inf
    bound = 0.1 / np.sqrt(1 - min(omega_dt / 2, 0.999) ** 2)
    assert (peak > 10 * bound) == grows


def test_damping_in_physical_units():
    # m = 1 kg, k = 100 N/m, c = 2 N s/m: amplitude envelope exp(−c t / 2m). Backward Euler
    # adds a numerical decay rate ω² Δt / 2 = 0.05 /s at Δt = 1e-3 on top of c/2m = 1 /s.
    m, k, c, dt = 1.0, 100.0, 2.0, 1e-3
    scene = _spring_scene(k * dt**2 / m, "implicit", damping=c, dt=dt, mass=m)
    state = scene.initial_state(position=(0.1, 0, 0))
    e0 = scene.energy(state)[()]
    for _ in range(2000):  # 2 s, about 3 periods
        state = scene.step(state)
    ratio = scene.energy(state)[()] / e0  # energy decays like exp(−c t / m) averaged
    expected = np.exp(-c / m * 2.0)
    assert expected * np.exp(-0.1 * 2.0) * 0.8 < ratio < expected * 1.25


def test_implicit_matches_free_fall_and_spin():
    body = sim.Body.box((0.1, 0.2, 0.3), 2.0)
    scene = sim.Scene(body, 0.01, integrator="implicit", gravity=(0, 0, -9.81))
    state = scene.initial_state(angular_velocity=(0, 0, 1.0))
    for _ in range(100):
        state = scene.step(state)
    np.testing.assert_allclose(state.linear_velocity[0], (0, 0, -9.81), atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity[0], (0, 0, 1.0), atol=1e-12)
