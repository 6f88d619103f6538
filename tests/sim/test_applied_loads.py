"""Applied loads on touching bodies: a pushed, torqued or tipped body moves as Newton–Euler says.

Bodies pushed *from* rest (and along their motion), against closed forms, on the compiled step
(``conftest``). The energy guard (``contacts.energy``) must never take away the work of
applied forces, torques and body torques: a resting body's contact-free step falls and loses
½ m g² Δt², and every load that did less work than that used to be scaled away.

Tolerances. Semi-implicit Euler is exact on these cases (constant accelerations): its discrete
solution is the closed form below, so what is left is rounding, ~n ε relative after n steps
(n ≤ 240 here: below 1e-13), and the contact solve's stated tolerance, 1e-12 of the element's
velocity scale (its largest free contact velocity, ~g Δt), which enters only where a contact
carries the motion (rolling, sticking, torsional friction): 1e-12 g Δt per step. The bounds
used (1e-12 relative, 1e-11 m/s) sit above both.
"""

import dataclasses

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.rotation import quat_exp, quat_rotate, quat_to_matrix

G = 9.81
DOWN = (0.0, 0.0, -G)
MASS = 0.5
HALF = np.array([0.1, 0.15, 0.2])  # the box: 0.5 kg
FLAT = np.array([0.2, 0.2, 0.1])  # flat enough not to tip at μ = 0.5 (μ h < w)


def _box(half=HALF, mass=MASS):
    return sim.Body.box(half, mass)


def _resting(scene, half, batch):
    return scene.initial_state(position=(0.0, 0.0, half[2]), batch_shape=(batch,))


def _along_x(values):
    out = np.zeros((len(values), 1, 3))
    out[:, 0, 0] = values
    return out


def _about_z(values):
    out = np.zeros((len(values), 1, 3))
    out[:, 0, 2] = values
    return out


def _discrete(a, dt, n, v0=0.0):
    """Semi-implicit Euler's own solution under a constant acceleration a from speed v0:
    v_n = v0 + a n Δt and x_n = v0 n Δt + a Δt² n (n + 1) / 2."""
    return v0 * n * dt + a * dt**2 * n * (n + 1) / 2, v0 + a * n * dt


# --- frictionless ground -------------------------------------------------------------------------


@pytest.mark.parametrize("integrator", sim.CONTACT_CAPABLE)
@pytest.mark.parametrize("dt", [1 / 240, 1 / 60])
def test_a_box_pushed_from_rest_on_frictionless_ground_moves_as_in_the_closed_form(integrator, dt):
    # The forces: 1, 3 and 4.8 N (below the 4.9 N weight) left the box in place, 5 N
    # moved it 1.19 m instead of 1.25. Each moves it x = a Δt² n (n + 1)/2 for 0.5 s, with no
    # rotation and no change of height (the ground holds it exactly: rest is a step's exact
    # solution). A box already sliding at 0.1 m/s and pushed along its motion (it ended 5 %
    # short) adds v₀ n Δt.
    scene = sim.Scene(_box(), dt, integrator, gravity=DOWN, ground=sim.Ground(0.0, 0.0))
    forces = np.array([1.0, 3.0, 4.8, 5.0, 3.0])
    v0 = np.array([0.0, 0.0, 0.0, 0.0, 0.1])
    state = _resting(scene, HALF, len(forces))
    state = dataclasses.replace(state, linear_velocity=_along_x(v0))
    n = round(0.5 / dt)
    for _ in range(n):
        state = scene.step(state, force=_along_x(forces))
    x, v = _discrete(forces / MASS, dt, n, v0)
    np.testing.assert_allclose(state.position[:, 0, 0], x, rtol=1e-12, atol=0)
    np.testing.assert_allclose(state.linear_velocity[:, 0, 0], v, rtol=1e-12, atol=0)
    np.testing.assert_allclose(state.position[:, 0, 1:], [[0.0, HALF[2]]] * 5, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.linear_velocity[:, 0, 1:], 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.orientation[:, 0, 3], 1.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("integrator", sim.CONTACT_CAPABLE)
def test_a_yaw_torque_spins_a_resting_box_on_frictionless_ground_at_tau_over_i(integrator):
    # ω_n = τ n Δt / I_zz from rest, for world torques of 0.01–0.1 N m (which did nothing)
    # and the same as a body torque (z is a principal axis that stays vertical); the box
    # stays where it is (the ground carries no torque about z without friction).
    dt = 1 / 240
    box = _box()
    scene = sim.Scene(box, dt, integrator, gravity=DOWN, ground=sim.Ground(0.0, 0.0))
    taus = np.array([0.01, 0.03, 0.1])
    i_zz = box.inertia[2, 2]
    n = 120
    for kind in ("torque", "body_torque"):
        state = _resting(scene, HALF, len(taus))
        for _ in range(n):
            state = scene.step(state, **{kind: _about_z(taus)})
        want = taus * n * dt / i_zz
        np.testing.assert_allclose(state.angular_velocity[:, 0, 2], want, rtol=1e-12, atol=0)
        np.testing.assert_allclose(state.angular_velocity[:, 0, :2], 0.0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(state.position[:, 0, :2], 0.0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(state.position[:, 0, 2], HALF[2], rtol=0, atol=1e-12)


# --- friction -------------------------------------------------------------------------------------


def test_inside_the_friction_cone_the_box_stays_outside_it_slides_at_f_minus_mu_m_g():
    # μ m g = 2.45 N. Below it the exact answer is rest (sticking: the active-set start is
    # exact, a converged solve leaves at most 1e-12 g Δt); above it (3 and 4.8 N, which the
    # old guard left in place) each step's friction impulse is μ times the normal impulse
    # m g Δt, so the box slides by the closed form with a = (F − μ m g)/m.
    dt, mu = 1 / 240, 0.5
    scene = sim.Scene(_box(FLAT), dt, gravity=DOWN, ground=sim.Ground(0.0, mu))
    forces = np.array([1.0, 2.4, 3.0, 4.8])
    state = _resting(scene, FLAT, len(forces))
    n = 120
    for _ in range(n):
        state = scene.step(state, force=_along_x(forces))
    a = np.maximum(forces - mu * MASS * G, 0.0) / MASS
    x, v = _discrete(a, dt, n)
    np.testing.assert_allclose(state.position[:, 0, 0], x, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.linear_velocity[:, 0, 0], v, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-11)
    np.testing.assert_allclose(state.position[:, 0, 2], FLAT[2], rtol=0, atol=1e-12)


def test_the_energy_the_contacts_removed_is_the_friction_work_and_nothing_when_frictionless():
    # ``ContactReport.energy_removed`` per element: a box sliding at v₀ = 1 m/s on μ = 0.5
    # (no push) loses μ m g Δt (v_k + v_(k+1))/2 per step, the friction impulse's work at the
    # step's mean velocity; pushed on frictionless ground, 0 (rounding: 1e-15 J). Over a call
    # of several steps, the sum.
    dt, mu = 1 / 240, 0.5
    rough = sim.Scene(_box(FLAT), dt, gravity=DOWN, ground=sim.Ground(0.0, mu))
    state = dataclasses.replace(_resting(rough, FLAT, 1), linear_velocity=_along_x([1.0]))
    for _ in range(3):
        new = rough.step(state)
        v0, v1 = state.linear_velocity[0, 0, 0], new.linear_velocity[0, 0, 0]
        want = mu * MASS * G * dt * (v0 + v1) / 2
        got = rough.report["contacts"].energy_removed
        np.testing.assert_allclose(got, [want], rtol=1e-12)
        state = new
    new = rough.step(state, steps=4)
    speeds = [state.linear_velocity[0, 0, 0] - k * mu * G * dt for k in range(5)]
    want = sum(mu * MASS * G * dt * (speeds[k] + speeds[k + 1]) / 2 for k in range(4))
    np.testing.assert_allclose(rough.report["contacts"].energy_removed, [want], rtol=1e-12)
    smooth = sim.Scene(_box(FLAT), dt, gravity=DOWN, ground=sim.Ground(0.0, 0.0))
    state = _resting(smooth, FLAT, 2)
    for _ in range(5):
        state = smooth.step(state, force=_along_x([1.0, 3.0]))
        np.testing.assert_allclose(smooth.report["contacts"].energy_removed, 0.0, atol=1e-15)


def test_a_sphere_pushed_at_its_centre_on_rough_ground_rolls_at_five_sevenths_f_over_m():
    # Rolling without slipping: m a = F − f, I α = f r with I = 2/5 m r², a = α r, so
    # a = 5 F / (7 m) and ω = v / r about y; the friction needed, 2F/7, is inside the cone
    # (μ m g = 4.9 N) for these pushes. Each step's sticking friction solves this exactly.
    dt, r, m = 1 / 240, 0.1, 1.0
    scene = sim.Scene(sim.Body.sphere(r, m), dt, gravity=DOWN, ground=sim.Ground(0.0, 0.5))
    forces = np.array([0.5, 2.0, 10.0])
    state = scene.initial_state(position=(0.0, 0.0, r), batch_shape=(len(forces),))
    n = 120
    for _ in range(n):
        state = scene.step(state, force=_along_x(forces))
    x, v = _discrete(5 * forces / (7 * m), dt, n)
    np.testing.assert_allclose(state.position[:, 0, 0], x, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.linear_velocity[:, 0, 0], v, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.angular_velocity[:, 0, 1], v / r, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(state.position[:, 0, 2], r, rtol=0, atol=1e-12)


def test_torsional_friction_holds_a_yaw_torque_below_mu_m_g_rho_and_slips_above():
    # Each supporting corner, at ρ = √(a² + b²) from the vertical axis, slides tangentially
    # once the box spins, so the friction torque is μ ρ times the weight whatever the split
    # of the normal load among the corners: μ m g ρ = 0.442 N m. Below it the box stays;
    # above it ω_n = (τ − μ m g ρ) n Δt / I_zz.
    dt, mu = 1 / 240, 0.5
    box = _box()
    scene = sim.Scene(box, dt, gravity=DOWN, ground=sim.Ground(0.0, mu))
    rho = np.hypot(HALF[0], HALF[1])
    limit = mu * MASS * G * rho
    taus = np.array([0.3, 0.43, 0.6, 1.0])
    state = _resting(scene, HALF, len(taus))
    n = 120
    for _ in range(n):
        state = scene.step(state, body_torque=_about_z(taus))
    want = np.maximum(taus - limit, 0.0) * n * dt / box.inertia[2, 2]
    np.testing.assert_allclose(state.angular_velocity[:, 0, 2], want, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=1e-11)
    np.testing.assert_allclose(state.position[:, 0, :2], 0.0, rtol=0, atol=1e-11)


# --- tipping --------------------------------------------------------------------------------------


def _tilt(state):
    """Rotation angle about y of each element's box (its x axis' pitch)."""
    axis = quat_to_matrix(state.orientation[:, 0])[:, :, 0]
    return np.arctan2(axis[:, 2], axis[:, 0])


def _pivot_reference(tau, times):
    """θ(t) of a box pivoting from rest on its edge x = −a (μ holds it) under a couple τ
    about −y, by DOP853: I_edge θ̈ = τ − m g d cos(α₀ + θ), d = √(a² + c²) from the edge to
    the centre, α₀ = atan(c/a), I_edge = I_yy + m d² = 4/3 m d² for a box."""
    from scipy.integrate import solve_ivp

    a, c = HALF[0], HALF[2]
    d, alpha = np.hypot(a, c), np.arctan2(c, a)
    i_edge = 4 / 3 * MASS * d**2

    def rhs(_, y):
        return [y[1], (tau - MASS * G * d * np.cos(alpha + y[0])) / i_edge]

    sol = solve_ivp(rhs, (0, times[-1]), [0.0, 0.0], "DOP853", times, rtol=1e-12, atol=1e-12)
    return sol.y[0]


def test_a_couple_below_the_tipping_moment_leaves_the_box_still_and_above_it_pivots_on_its_edge():
    # A reaction wheel's torque about the body y axis. Below m g a (0.9 of it) the ground's
    # normal load can shift to the edge and hold the box: rest, to the solve's tolerance.
    # Above it (1.5 m g a), on μ = 1 ground that keeps the edge from sliding, the box pivots
    # on the edge x = −a as the pivot ODE says. Semi-implicit Euler is first order: the error
    # against DOP853 halves with Δt (order 0.8–1.2 between Δt = 1/480 and 1/960), and the
    # edge stays on the ground: each step's rotation lifts it by at most ½ Δt² ω² d before
    # the next step's speculative contact takes it back.
    a = HALF[0]
    tipping = MASS * G * a
    errors = []
    for dt in (1 / 480, 1 / 960):
        scene = sim.Scene(_box(), dt, gravity=DOWN, ground=sim.Ground(0.0, 1.0))
        taus = np.array([0.9 * tipping, 1.5 * tipping])
        state = _resting(scene, HALF, 2)
        n = round(0.3 / dt)
        thetas = []
        edge = []
        omega = []
        for _ in range(n):
            state = scene.step(state, body_torque=-np.array([0.0, 1.0, 0.0]) * taus[:, None, None])
            thetas.append(_tilt(state))
            corners = state.position[:, None, 0] + quat_rotate(
                state.orientation[:, None, 0], _box().shape.vertices
            )
            edge.append(np.sort(corners[1, :, 2])[:2])
            omega.append(np.linalg.norm(state.angular_velocity[1, 0]))
        np.testing.assert_allclose(state.linear_velocity[0], 0.0, atol=1e-11)
        np.testing.assert_allclose(state.angular_velocity[0], 0.0, atol=1e-11)
        thetas = np.array(thetas)
        times = dt * np.arange(1, n + 1)
        want = _pivot_reference(1.5 * tipping, times)
        assert thetas[-1, 1] > 0.2  # it tipped well past the start
        errors.append(np.abs(thetas[:, 1] - want).max())
        d = np.hypot(a, HALF[2])
        bound = 0.5 * dt**2 * max(omega) ** 2 * d
        assert np.all(np.abs(np.array(edge)) <= bound + 1e-12)
    order = np.log2(errors[0] / errors[1])
    assert 0.8 < order < 1.2, (errors, order)


# --- the same path on the ground and in space -----------------------------------------------------


def test_a_box_on_frictionless_ground_follows_its_path_in_space_under_the_same_loads():
    # Frictionless ground carries no horizontal force and no yaw torque, so under the same
    # horizontal forces and yaw torques (random, changing every step, world and body
    # frame) a resting box follows the path of the same box in space without gravity:
    # positions, yaw and velocities agree to rounding.
    dt = 1 / 240
    rng = np.random.default_rng(7)
    ground = sim.Scene(_box(), dt, gravity=DOWN, ground=sim.Ground(0.0, 0.0))
    space = sim.Scene(_box(), dt, ground.integrator)
    on_ground = _resting(ground, HALF, 4)
    in_space = on_ground.copy()
    for _ in range(240):
        force = np.zeros((4, 1, 3))
        force[..., :2] = rng.normal(0.0, 3.0, (4, 1, 2))
        torque = _about_z(rng.normal(0.0, 0.05, 4))
        body = _about_z(rng.normal(0.0, 0.05, 4))
        loads = dict(force=force, torque=torque, body_torque=body)
        on_ground = ground.step(on_ground, **loads)
        in_space = space.step(in_space, **loads)
    np.testing.assert_allclose(on_ground.position[..., :2], in_space.position[..., :2], atol=1e-12)
    np.testing.assert_allclose(on_ground.orientation, in_space.orientation, atol=1e-12)
    np.testing.assert_allclose(on_ground.linear_velocity, in_space.linear_velocity, atol=1e-12)
    np.testing.assert_allclose(on_ground.angular_velocity, in_space.angular_velocity, atol=1e-12)
    assert np.abs(in_space.position[..., :2]).max() > 0.1  # it went somewhere


def test_a_box_resting_on_a_box_pushed_follows_its_path_in_space():
    # Body–body contact. The upper box on a lower box on frictionless ground, contacts
    # frictionless too: pushed horizontally, the upper box follows its path in space, and the
    # lower one stays where it is. With friction between them (μ = 0.5, no friction on the
    # ground), a push on the lower box below what friction can pass on (a = F/(m₁ + m₂) ≤ μ g)
    # carries both at a = F/(m₁ + m₂).
    dt = 1 / 240
    half = FLAT
    boxes = [_box(half), _box(half)]
    start = [(0.0, 0.0, half[2]), (0.0, 0.0, 3 * half[2])]
    n = 120
    push = np.array([[0.0, 0.0, 0.0], [0.4, -0.2, 0.0]])  # 0.1 m in 0.5 s: still on top
    smooth = sim.Scene(
        boxes, dt, gravity=DOWN, ground=sim.Ground(0.0, 0.0), contacts=sim.Material(0.0, 0.0)
    )
    space = sim.Scene(boxes[1], dt, smooth.integrator)
    state = smooth.initial_state(position=start)
    alone = space.initial_state(position=start[1])
    for _ in range(n):
        state = smooth.step(state, force=push)
        alone = space.step(alone, force=push[1])
    np.testing.assert_allclose(state.position[1, :2], alone.position[0, :2], atol=1e-12)
    np.testing.assert_allclose(state.linear_velocity[1], alone.linear_velocity[0], atol=1e-12)
    np.testing.assert_allclose(state.position[0], start[0], atol=1e-12)
    np.testing.assert_allclose(state.position[1, 2], start[1][2], atol=1e-12)
    rough = sim.Scene(
        boxes, dt, gravity=DOWN, ground=sim.Ground(0.0, 0.0), contacts=sim.Material(0.0, 0.5)
    )
    state = rough.initial_state(position=start)
    force = np.array([[4.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # a = 4 N / 1 kg ≤ μ g = 4.9 m/s²
    for _ in range(n):
        state = rough.step(state, force=force)
    x, v = _discrete(4.0 / (2 * MASS), dt, n)
    np.testing.assert_allclose(state.position[:, 0], x, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(state.linear_velocity[:, 0], v, rtol=1e-12, atol=1e-11)


def test_a_push_on_a_body_in_the_air_acts_while_another_body_of_its_scene_rests():
    # The guard is per batch element: a box resting on the ground and a sphere in flight in
    # the same element. The pushed sphere falls and drifts as without the box (its own
    # scene, no ground within reach), the box stays.
    dt = 1 / 240
    ball = sim.Body.sphere(0.1, 1.0)
    scene = sim.Scene([_box(), ball], dt, gravity=DOWN, ground=sim.Ground(0.0, 0.5))
    alone = sim.Scene(ball, dt, scene.integrator, gravity=DOWN)
    start = [(0.0, 0.0, HALF[2]), (1.0, 0.0, 2.0)]
    state = scene.initial_state(position=start)
    free = alone.initial_state(position=start[1])
    push = np.array([[0.0, 0.0, 0.0], [15.0, 4.0, 0.0]])  # work well above ½ m g² Δt² a step
    for _ in range(60):
        state = scene.step(state, force=push)
        free = alone.step(free, force=push[1])
    np.testing.assert_allclose(state.position[1], free.position[0], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(state.linear_velocity[1], free.linear_velocity[0], atol=1e-14)
    np.testing.assert_allclose(state.position[0], start[0], atol=1e-12)
    assert scene.report["contacts"].engaged == 1


# --- the invariant itself ---------------------------------------------------------------------------


def _guard_energy(scene, state):
    """E = KE + gravity PE (a spring's potential is a load's work here, ``contacts.energy``)."""
    x = state.position
    return scene.kinetic_energy(state) - np.sum(scene.model.mass * (x @ scene.model.gravity), -1)


def _work(scene, start, state, loads, dt):
    """W(u) = Δt Σ_b (F_b·v_b + τ_b·ω_b), loads at the start pose (springs' elastic part)."""
    shape = start.position.shape
    force = np.broadcast_to(loads.get("force", np.zeros(3)), shape).copy()
    torque = np.broadcast_to(loads.get("torque", np.zeros(3)), shape).copy()
    body = loads.get("body_torque")
    if body is not None:
        torque += quat_rotate(start.orientation, np.broadcast_to(body, shape))
    for sp in scene.model.springs:
        q = start.orientation[:, sp.body]
        arm = quat_rotate(q, sp.attach)
        d = start.position[:, sp.body] + arm - sp.anchor
        f = -sp.stiffness * d  # rest length 0 below
        force[:, sp.body] += f
        torque[:, sp.body] += np.cross(arm, f)
    rate = force * state.linear_velocity + torque * state.angular_velocity
    return dt * rate.sum(axis=(-1, -2))


# A capped solve is still guarded (its impulse cut back, ``solve.dissipative``).
@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
@pytest.mark.parametrize("dt", [1 / 240, 1 / 30, 0.5])
@pytest.mark.parametrize("eps", [0.0, 0.5, 1.0])
def test_no_step_gains_energy_from_contacts_under_random_loads(dt, eps):
    # The invariant the guard enforces, from outside, per step: E_end − W(u) ≤
    # max(E_start, E_free − W(u₁)), E_free and u₁ from the same step without the ground
    # (its kinetic energy at the start orientation, as the guard takes it). Tumbling boxes and
    # a sphere thrown at the ground, a spring on the sphere, random forces, world torques and
    # body torques every step. Bound: the guard's slack, 1e-12 |E_start| (rounding of the
    # energies), twice for the test's own rounding.
    rng = np.random.default_rng(round(1 / dt) + int(10 * eps))
    bodies = [_box(), sim.Body.sphere(0.15, 2.0)]
    spring = sim.Spring(1, (0.0, 0.0, 1.5), stiffness=20.0)
    kwargs = dict(gravity=DOWN, springs=[spring])
    scene = sim.Scene(bodies, dt, ground=sim.Ground(eps, rng.uniform(0, 1)), **kwargs)
    free = sim.Scene(bodies, dt, scene.integrator, **kwargs)
    batch = 6
    state = scene.initial_state(
        position=np.array([(0.0, 0.0, 0.8), (1.0, 0.0, 0.7)]) + rng.normal(0, 0.1, (batch, 2, 3)),
        orientation=quat_exp(rng.normal(0, 1.0, (batch, 2, 3))),
        linear_velocity=rng.normal(0, 2.0, (batch, 2, 3)),
        angular_velocity=rng.normal(0, 4.0, (batch, 2, 3)),
    )
    engaged = 0
    for _ in range(round(1.5 / dt) + 3):
        loads = dict(
            force=rng.normal(0, 5.0, (batch, 2, 3)),
            torque=rng.normal(0, 0.5, (batch, 2, 3)),
            body_torque=rng.normal(0, 0.5, (batch, 2, 3)),
        )
        new = scene.step(state, **loads)
        ref = free.step(state, **loads)
        engaged += scene.report["contacts"].engaged
        at_start = sim.State(
            ref.position, state.orientation, ref.linear_velocity, ref.angular_velocity
        )
        e_start = _guard_energy(scene, state)
        e_free = _guard_energy(scene, at_start) - _work(scene, state, at_start, loads, dt)
        e_end = _guard_energy(scene, new) - _work(scene, state, new, loads, dt)
        slack = 2e-12 * np.abs(e_start) + 1e-14
        assert np.all(e_end <= np.maximum(e_start, e_free) + slack)
        state = new
    assert engaged > 0
