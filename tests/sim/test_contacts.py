"""Contacts against closed forms and conservation laws.

Time discretisation: the contact stage follows a semi-implicit Euler step, whose velocity is the
mean over the step; closed forms hold up to O(v Δt) in distance and O(g Δt) in velocity, and
tolerances below are a small multiple of those bounds (derived in each test).
"""

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigid_env import sim
from rigid_env.sim.rotation import quat_exp, quat_multiply
from rigid_env.sim.scenes import landing_scene

G = 9.81
GRAVITY = (0.0, 0.0, -G)


def _apexes(z):
    return np.array([z[i] for i in range(1, len(z) - 1) if z[i - 1] <= z[i] > z[i + 1]])


def test_stages_and_integrator_choice():
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    assert sim.Scene(box, 0.01).stages == ("integrate",)
    scene = sim.Scene(box, 0.01, gravity=GRAVITY, ground=sim.Ground())
    assert scene.stages == (
        "gravity",
        "integrate_velocity",
        "collide_ground",
        "assemble_contacts",
        "restitute",
        "solve_contacts",
        "limit_energy",
        "integrate_position",
        "separate_contacts",
    )
    assert scene.integrator == sim.CONTACT_INTEGRATOR
    balls = [sim.Body.sphere(0.1, 1.0), sim.Body.sphere(0.1, 1.0)]
    pairs = sim.Scene(balls, 0.01, contacts=sim.Material())
    assert pairs.stages == (
        "integrate_velocity",
        "collide_pairs",
        "assemble_contacts",
        "restitute",
        "solve_contacts",
        "limit_energy",
        "integrate_position",
        "separate_contacts",
    )
    for name in ("splitting", "splitting4", "rk4"):
        with pytest.raises(ValueError, match="integrator"):
            sim.Scene(box, 0.01, integrator=name, ground=sim.Ground())
    with pytest.raises(ValueError, match="restitution"):
        sim.Ground(restitution=1.5)
    with pytest.raises(ValueError, match="contacts"):
        sim.Scene(box, 0.01, contacts=0.5)


# The issue asks for 100 000 steps; the suite runs REST_STEPS (a few seconds) and the full run
# is `RIGID_ENV_REST_STEPS=100000 python -m pytest tests/sim/test_contacts.py -k rest`.
REST_STEPS = int(os.environ.get("RIGID_ENV_REST_STEPS", "2000"))


def test_resting_boxes_stay_at_rest():
    # Six boxes in one batch, on each of the three face pairs, yawed, placed exactly or dropped
    # from 1e-3 m. Resting is a fixed point of the step (the warm start is the exact impulse),
    # so after REST_STEPS the state must be unchanged to rounding: no jitter (velocities
    # < 1e-12), no creep (x, y within 1e-12 m), no sinking (height within 1e-12 m).
    half = np.array([0.1, 0.15, 0.2])
    box = sim.Body.box(half, 1.0)
    scene = sim.Scene(box, 1 / 240, gravity=GRAVITY, ground=sim.Ground(0.3, 0.5))
    yaw = quat_exp(np.array([0.0, 0.0, 0.7]))
    faces = [
        (np.array([0.0, 0.0, 0.0]), half[2]),
        (np.array([np.pi / 2, 0.0, 0.0]), half[1]),
        (np.array([0.0, np.pi / 2, 0.0]), half[0]),
    ]
    orientation, height, drop = [], [], []
    for rotvec, h in faces:
        for d in (0.0, 1e-3):
            orientation.append(quat_multiply(yaw, quat_exp(rotvec)))
            height.append(h)
            drop.append(d)
    height = np.array(height)
    position = np.zeros((6, 1, 3))
    position[:, 0, 2] = height + np.array(drop)
    position[:, 0, 0] = np.linspace(-1.0, 1.0, 6)
    state = scene.initial_state(
        position=position, orientation=np.array(orientation)[:, None], batch_shape=(6,)
    )
    for _ in range(240):  # let the dropped ones land
        state = scene.step(state)
    start = state.copy()
    np.testing.assert_allclose(start.position[..., 0, 2], height, rtol=0, atol=1e-12)
    for _ in range(REST_STEPS):
        state = scene.step(state)
    np.testing.assert_allclose(state.position, start.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.position[..., 0, 2], height, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        np.abs(np.sum(state.orientation * start.orientation, -1)), 1.0, rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("eps", [0.5, 0.8])
def test_bounce_apexes_scale_by_eps_squared(eps):
    # Free flight of semi-implicit Euler conserves ½v² + g z − ½ g Δt v, so apexes sampled at
    # steps are off by ≤ g Δt²/8 + the half-step term, 4e-5 m at Δt = 1/1000 (tolerance).
    ball = sim.Body.sphere(0.1, 1.0)
    scene = sim.Scene(ball, 1e-3, gravity=GRAVITY, ground=sim.Ground(eps, 0.0, 0.0))
    state = scene.initial_state(position=(0, 0, 1.1))
    z = []
    for _ in range(3500):
        state = scene.step(state)
        z.append(state.position[0, 2] - 0.1)
    apex = _apexes(np.array(z))
    first = apex[0]
    assert abs(first - eps**2) < 5e-3  # the drop's own flight error is O(v Δt) = 4.4e-3
    apex = apex[:5]
    k = np.arange(len(apex))
    assert len(apex) == 5
    assert np.all(np.abs(apex - first * eps ** (2 * k)) <= 4e-5 * (k + 1))


def test_elastic_sphere_keeps_its_height_to_first_order():
    # ε = 1: the impact itself keeps the ball's energy (restitution.py), but the step's energy
    # guard (energy.py) removes what a bounce step would end with above its start,
    # m g Δt v⁺ with v⁺ ≤ √(2 g h) = 4.43 m/s: at most Δt v⁺ = 1.85e-2 m of apex per bounce,
    # and never a gain.
    ball = sim.Body.sphere(0.1, 1.0)
    scene = sim.Scene(ball, 1 / 240, gravity=GRAVITY, ground=sim.Ground(1.0, 0.0))
    state = scene.initial_state(position=(0, 0, 1.1))
    z = []
    for _ in range(240 * 8):
        state = scene.step(state)
        z.append(state.position[0, 2])
    apex = _apexes(np.array(z)) - 0.1
    assert len(apex) >= 7
    k = np.arange(1, len(apex) + 1)
    assert np.all(apex <= 1.0 + 1e-12)
    assert np.all(1.0 - apex <= k * (4.43 / 240 + G / 240**2))  # + sampling, g Δt² a bounce


def test_sliding_box_stops_at_closed_form():
    mu, v0, dt = 0.5, 2.0, 1e-3
    box = sim.Body.box((0.2, 0.2, 0.1), 1.0)
    scene = sim.Scene(box, dt, gravity=GRAVITY, ground=sim.Ground(0.0, mu))
    state = scene.initial_state(position=(0, 0, 0.1), linear_velocity=(v0, 0, 0))
    t = 0.0
    # The step where the corners stick leaves a Gauss–Seidel residual (measured 3e-5 m/s, gone
    # three steps later): below 1e-4 m/s counts as stopped; that changes the distance by < 1e-7.
    while state.linear_velocity[0, 0] > 1e-4:
        state = scene.step(state)
        t += dt
    # Velocity decreases by μ g Δt per step exactly; stop time to ± Δt, distance to ± v0 Δt.
    assert abs(t - v0 / (mu * G)) <= 1.5 * dt
    assert abs(state.position[0, 0] - v0**2 / (2 * mu * G)) <= v0 * dt
    for _ in range(10):
        state = scene.step(state)
    assert abs(state.linear_velocity[0, 0]) < 1e-12
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)


def test_sliding_sphere_rolls_at_five_sevenths():
    r, v0 = 0.1, 3.0
    ball = sim.Body.sphere(r, 1.0)
    scene = sim.Scene(ball, 1e-3, gravity=GRAVITY, ground=sim.Ground(0.0, 0.3))
    state = scene.initial_state(position=(0, 0, r), linear_velocity=(v0, 0, 0))
    for _ in range(1500):  # slip ends at t = 2 v0 / (7 μ g) = 0.29 s
        state = scene.step(state)
    v, w = state.linear_velocity[0], state.angular_velocity[0]
    # Rolling: contact point at rest, v = ω r; then nothing dissipates: v = 5/7 v0 up to the
    # last slipping step's μ g Δt = 3e-3.
    assert abs(v[0] - w[1] * r) < 1e-9
    assert abs(v[0] - 5 / 7 * v0) < 0.3 * G * 1e-3


def test_fast_box_does_not_tunnel():
    box = sim.Body.box((0.05, 0.05, 0.05), 1.0)
    scene = sim.Scene(box, 1 / 60, gravity=GRAVITY, ground=sim.Ground(0.0, 0.5))
    tilt = quat_exp(np.array([0.3, 0.1, 0.0]))
    state = scene.initial_state(
        position=(0, 0, 1.0), orientation=tilt, linear_velocity=(0, 0, -100.0)
    )
    lowest = []
    for _ in range(30):
        state = scene.step(state)
        corners = state.point_position(sim.Box(np.full(3, 0.05)).vertices[:, None, :])
        lowest.append(corners[..., 2].min())
    # Caught: the linearised end-of-step depth misses only the rotation's curvature,
    # O((ω Δt)² r) with ω Δt < 0.01 here, so at most ~1e-6 m below the plane.
    assert min(lowest) > -1e-6
    assert state.position[0, 2] < 0.1  # it landed, it did not bounce away


def test_box_dropped_flat_does_not_spin():
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    scene = sim.Scene(box, 1 / 240, gravity=GRAVITY, ground=sim.Ground(0.3, 0.5))
    state = scene.initial_state(position=(0, 0, 1.0))
    for _ in range(480):
        state = scene.step(state)
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(state.position[0], (0, 0, 0.2), atol=1e-12)


def test_newton_cradle_exchanges_velocity():
    balls = [sim.Body.sphere(0.1, 1.0) for _ in range(3)]
    scene = sim.Scene(balls, 1e-3, contacts=sim.Material(1.0, 0.0, 0.0))
    state = scene.initial_state(
        position=[(-0.3, 0, 0), (0.2, 0, 0), (0.4, 0, 0)],
        linear_velocity=[(1.0, 0, 0), (0, 0, 0), (0, 0, 0)],
    )
    for _ in range(600):
        state = scene.step(state)
    v = state.linear_velocity[:, 0]
    # Sequential elastic impulses between equal masses swap velocities exactly.
    np.testing.assert_allclose(v, [0.0, 0.0, 1.0], atol=1e-9)


def test_two_body_impact_conserves_momentum():
    a, b = sim.Body.sphere(0.1, 1.0), sim.Body.box((0.1, 0.2, 0.15), 3.0)
    scene = sim.Scene([a, b], 1e-3, contacts=sim.Material(0.6, 0.4, 0.0))
    state = scene.initial_state(
        position=[(-0.4, 0.05, 0.03), (0, 0, 0)],
        orientation=[(0, 0, 0, 1), tuple(quat_exp(np.array([0.2, 0.4, 0.1])))],
        linear_velocity=[(2.0, 0.3, 0.1), (-0.5, 0, 0)],
        angular_velocity=[(0, 0, 5.0), (1, 0, 0)],
    )
    p0, l0 = scene.linear_momentum(state), scene.angular_momentum(state)
    for _ in range(400):
        state = scene.step(state)
    assert np.linalg.norm(state.linear_velocity[0] - (2.0, 0.3, 0.1)) > 0.5  # they did collide
    # Equal and opposite impulses at one point: momentum exact to rounding (the gyroscopic
    # step of implicit_gyro changes L of a tumbling box by O(Δt) per step, hence 1e-2).
    np.testing.assert_allclose(scene.linear_momentum(state), p0, atol=1e-12)
    np.testing.assert_allclose(scene.angular_momentum(state), l0, atol=2e-2)


@settings(max_examples=25, deadline=None)
@given(
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.lists(st.floats(-3, 3), min_size=6, max_size=6),
    st.booleans(),
)
def test_no_energy_gain_in_impacts(eps, mu, motion, is_box):
    body = sim.Body.box((0.1, 0.15, 0.2), 1.0) if is_box else sim.Body.sphere(0.15, 1.0)
    dt = 1 / 240
    scene = sim.Scene(body, dt, gravity=GRAVITY, ground=sim.Ground(eps, mu))
    state = scene.initial_state(
        position=(0, 0, 0.6),
        orientation=quat_exp(np.array(motion[:3]) * 0.5),
        linear_velocity=(motion[0], motion[1], -2.0 + motion[2]),
        angular_velocity=np.array(motion[3:]) * 3,
    )
    e0 = scene.energy(state)[()]
    top = 0.0
    for _ in range(240):
        state = scene.step(state)
        top = max(top, scene.energy(state)[()] - e0)
    # Allowance: the semi-implicit flight's energy varies by ½ g Δt |v| (|v| <= 10 m/s) and
    # the restitution guard admits one step of gravity work m g |v| Δt: 1.5 m g |v| Δt.
    assert top <= 1.5 * G * 10 * dt


def test_batch_equals_single():
    scene, init = landing_scene()
    batch = init((3,), np.random.default_rng(1))
    singles = [batch[i] for i in range(3)]
    for _ in range(300):
        batch = scene.step(batch)
        singles = [scene.step(s) for s in singles]
    for i in range(3):
        for got, want in zip(batch[i].arrays(), singles[i].arrays(), strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_landing_scene_comes_to_rest_on_a_face():
    scene, init = landing_scene()
    state = init((8,), np.random.default_rng(0))
    for _ in range(240 * 4):
        state = scene.step(state)
    z = state.position[..., 0, 2]
    faces = np.array([0.1, 0.15, 0.2])
    assert np.all(np.min(np.abs(z[:, None] - faces), axis=1) < 1e-9)
    assert np.all(scene.kinetic_energy(state) < 1e-20)


def test_bad_state_left_unchanged():
    scene, init = landing_scene()
    state = init()
    before = [a.copy() for a in state.arrays()]
    with pytest.raises(ValueError, match="torque"):
        scene.step(state, torque=np.full(3, np.nan))
    for a, b in zip(state.arrays(), before, strict=True):
        np.testing.assert_array_equal(a, b)
