"""The contact solve against closed forms: static friction, rest, sliding, bounces, impacts.

Tolerances are derived in each test from the solve's stated tolerance (``SolverSettings``,
relative 1e-12 of the element's contact velocities), from the step's own discretisation, or
from rounding; none is tuned.
"""

import os
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigid_env import sim
from rigid_env.bench.contact_solve import l_prism, tetrahedron
from rigid_env.sim.rotation import quat_angle, quat_exp, quat_multiply, quat_rotate
from rigid_env.sim.scenes import landing_scene

G = 9.81
DOWN = (0.0, 0.0, -G)
HALF = np.array([0.1, 0.15, 0.2])


def _yaws(values):
    return np.array([quat_exp(np.array([0.0, 0.0, y])) for y in values])


# The laws hold with the warm start too (``SolverSettings.warm_start``: a call's steps after
# its first start from the previous step's impulses). Cold, the tests step one call per step;
# warm, in calls of CHUNK steps (BoxLanding's frame_skip), checked after each call.
WARM = pytest.mark.parametrize("warm", [False, True], ids=["cold", "warm"])
CHUNK = 8


def _calls(steps, warm):
    """Steps per ``Scene.step`` call: ``steps`` in all, one per call cold, CHUNK warm."""
    if not warm:
        return [1] * steps
    return [CHUNK] * (steps // CHUNK) + ([steps % CHUNK] if steps % CHUNK else [])


# --- static friction -----------------------------------------------------------------------------


@WARM
def test_static_friction_holds_inside_the_cone_and_not_outside(warm):
    # An incline of angle θ, emulated by tilting gravity. Inside the cone (tan 0.3 = 0.31 <
    # μ = 0.5) the exact answer is v = 0: sticking is an equality the active-set start solves
    # exactly, and a converged solve leaves at most 1e-12 × g Δt = 4e-14 m/s; the bar
    # is 1e-9 m/s. Outside (tan 0.7 = 0.84 > μ) the box slides with a = g (sin θ − μ cos θ):
    # each step the normal impulse is m g cos θ Δt and friction μ times it, so the speed grows
    # by exactly a Δt per step (to rounding, 1e-15 of g Δt per step). The box is flat (half
    # height 0.1, half width 0.2 in every yaw) so that gravity's line stays inside its base:
    # a tall box would tip over instead (tan 0.7 > 0.1 / 0.2 for the landing box).
    box = sim.Body.box((0.2, 0.2, 0.1), 1.0)
    yaw = _yaws([0.0, 0.4, 1.2, 2.5])
    for theta, holds in ((0.3, True), (0.7, False)):
        scene = sim.Scene(
            box,
            1 / 240,
            gravity=(G * np.sin(theta), 0.0, -G * np.cos(theta)),
            ground=sim.Ground(0.0, 0.5),
            contact_solver=sim.SolverSettings(warm_start=warm),
        )
        state = scene.initial_state(
            position=(0, 0, 0.1), orientation=yaw[:, None], batch_shape=(4,)
        )
        start = state.copy()
        steps = 480
        for k in _calls(steps, warm):
            state = scene.step(state, steps=k)
            if holds:
                assert np.max(np.abs(state.linear_velocity)) < 1e-9
                assert np.max(np.abs(state.angular_velocity)) < 1e-9
        if holds:
            np.testing.assert_allclose(state.position, start.position, rtol=0, atol=1e-9)
        else:
            a = G * (np.sin(theta) - 0.5 * np.cos(theta))
            np.testing.assert_allclose(
                state.linear_velocity[..., 0, 0], a * steps / 240, rtol=1e-12
            )
            # Across the slope and normal to it: each step's solve leaves at most its
            # tolerance, 1e-12 of the contact velocities (≤ a t = 5.2 m/s), summed over steps.
            bound = steps * 1e-12 * a * steps / 240
            np.testing.assert_allclose(state.linear_velocity[..., 0, 1:], 0.0, atol=bound)


# --- rest ----------------------------------------------------------------------------------------

# The issue asks for drift below 1e-9 m over 1e5 steps, 1e-14 m per step; the suite runs
# REST_STEPS steps against that per-step bound, the full run is
# `RIGID_ENV_REST_STEPS=100000 python -m pytest tests/sim/test_contact_laws.py -k rest`.
REST_STEPS = int(os.environ.get("RIGID_ENV_REST_STEPS", "1000"))
DRIFT_PER_STEP = 1e-9 / 1e5


def _resting(body, orientation, warm=False):
    scene = sim.Scene(
        body,
        1 / 240,
        gravity=DOWN,
        ground=sim.Ground(0.3, 0.5),
        contact_solver=sim.SolverSettings(warm_start=warm),
    )
    low = -np.min(quat_rotate(orientation[:, None, :], _points(body))[..., 2], axis=-1)
    position = np.zeros((len(orientation), 1, 3))
    position[:, 0, 2] = low
    position[:, 0, 0] = np.arange(len(orientation))
    state = scene.initial_state(
        position=position, orientation=orientation[:, None], batch_shape=(len(orientation),)
    )
    return scene, state


def _points(body):
    shape = body.shape
    if isinstance(shape, sim.Sphere):
        return np.array([[0.0, 0.0, -shape.radius]])
    return np.asarray(shape.vertices)


@WARM
@pytest.mark.parametrize("shape", ["box", "sphere", "tetrahedron", "l_prism"])
def test_resting_bodies_of_every_shape_stay_put(shape, warm):
    # Placed exactly on the ground at rest. Rest is the exact solution of each step (v = 0,
    # the weight's impulse carried by the support), which the active-set start finds: the
    # bodies may not drift more than DRIFT_PER_STEP per step, nor turn more than that over
    # their size (0.1 m), nor sink.
    yaw = _yaws([0.0, 0.7, 2.0])
    faces = [np.array([0.0, 0.0, 0.0]), np.array([np.pi / 2, 0, 0]), np.array([0, np.pi / 2, 0])]
    bodies = {
        "box": (
            sim.Body.box(HALF, 1.0),
            [quat_multiply(y, quat_exp(f)) for y in yaw for f in faces],
        ),
        "sphere": (sim.Body.sphere(0.1, 1.0), list(yaw)),
        "tetrahedron": (tetrahedron(), list(yaw)),
        "l_prism": (l_prism(), list(yaw)),
    }
    body, orientation = bodies[shape]
    scene, state = _resting(body, np.array(orientation), warm)
    start = state.copy()
    for k in _calls(REST_STEPS, warm):
        state = scene.step(state, steps=k)
    bound = REST_STEPS * DRIFT_PER_STEP
    np.testing.assert_allclose(state.position, start.position, rtol=0, atol=bound)
    assert np.max(quat_angle(state.orientation, start.orientation)) * 0.1 <= bound
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-12)


# --- sliding -------------------------------------------------------------------------------------


@WARM
def test_box_sliding_in_any_direction_keeps_its_yaw_and_stops_at_closed_form(warm):
    # Coulomb friction opposes the sliding velocity exactly (the friction-disk step of
    # solve.py), so a box sliding flat in any direction, yawed or not, decelerates along its
    # path at μ g: the speed drops by μ g Δt each step, no sideways force, no torque about z.
    # Positions follow x_{k+1} = x_k + Δt v_{k+1}, so the stopping distance is the closed form
    # v0²/(2 μ g) to first order in Δt: within v0 Δt of it.
    mu, v0, dt = 0.5, 2.0, 1e-3
    box = sim.Body.box((0.2, 0.15, 0.1), 1.0)
    solver = sim.SolverSettings(warm_start=warm)
    scene = sim.Scene(box, dt, gravity=DOWN, ground=sim.Ground(0.0, mu), contact_solver=solver)
    heading = np.array([0.0, np.pi / 4, 2.0, -2.6, 0.0, np.pi / 4, 2.0, -2.6])
    yaw = _yaws([0.0] * 4 + [0.4, 0.4, 1.1, -0.7])
    direction = np.stack((np.cos(heading), np.sin(heading), 0 * heading), -1)
    state = scene.initial_state(
        position=(0.0, 0.0, 0.1),
        orientation=yaw[:, None],
        linear_velocity=(v0 * direction)[:, None],
        batch_shape=(8,),
    )
    start = state.copy()
    for k in _calls(int(v0 / (mu * G) / dt) + 20, warm):
        state = scene.step(state, steps=k)
    travel = state.position[:, 0] - start.position[:, 0]
    along = np.sum(travel * direction, axis=-1)
    assert np.all(np.abs(along - v0**2 / (2 * mu * G)) <= v0 * dt)
    np.testing.assert_allclose(travel - along[:, None] * direction, 0.0, atol=1e-9)
    assert np.max(quat_angle(state.orientation, start.orientation)) < 1e-9
    np.testing.assert_allclose(state.linear_velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)


# --- restitution ---------------------------------------------------------------------------------


@pytest.mark.parametrize("eps", [0.5, 0.8])
def test_bounce_apexes_are_eps_to_the_2k_times_h_at_any_impact_phase(eps):
    # A ball dropped from h = 1 m above the ground, its impact instant swept over one step
    # (8 phases). Semi-implicit Euler's positions sample the exact parabola; the impact
    # applies Newton's law at the instant the gap closes (restitution.py) and the step after
    # it puts the ball on the outgoing parabola up to (Δt − τ) a τ / 2 ≤ g Δt²/8; sampling
    # the apex at steps misses at most g Δt²/8 more. Bound per bounce g Δt²/4, summed over
    # the k bounces (errors shrink by ε² each bounce, so the sum is an upper bound).
    r, h, dt, phases = 0.1, 1.0, 1e-3, 8
    ball = sim.Body.sphere(r, 1.0)
    scene = sim.Scene(ball, dt, gravity=DOWN, ground=sim.Ground(eps, 0.0, 0.0))
    t_hit = np.sqrt(2 * h / G) + dt * np.arange(phases) / phases
    drop = 0.5 * G * t_hit**2
    position = np.zeros((phases, 1, 3))
    position[:, 0, 2] = r + drop
    state = scene.initial_state(position=position, batch_shape=(phases,))
    z = []
    for _ in range(int(2.2 / dt)):
        state = scene.step(state)
        z.append(state.position[:, 0, 2] - r)
    z = np.array(z)
    for p in range(phases):
        top = np.array(
            [z[i, p] for i in range(1, len(z) - 1) if z[i - 1, p] <= z[i, p] > z[i + 1, p]]
        )
        top = top[:3]
        k = np.arange(1, len(top) + 1)
        assert len(top) == 3
        assert np.all(np.abs(top - drop[p] * eps ** (2 * k)) <= k * G * dt**2 / 4)


def _kinetic(scene, state, v, w):
    return scene.kinetic_energy(sim.State(state.position, state.orientation, v, w))


@settings(max_examples=20, deadline=None)
@given(
    st.sampled_from([0.0, 0.3, 0.7, 1.0]),
    st.floats(0.0, 1.0),
    st.lists(st.floats(-3, 3), min_size=6, max_size=6),
    st.booleans(),
)
def test_no_impact_adds_energy(eps, mu, motion, is_box):
    # Per step, with the velocities evaluated at the step's start orientation as the solve
    # does: the contact response leaves no more kinetic energy than the step's forces gave
    # (the free step's), and the step ends with no more KE + PE than it started with. Both
    # relative 1e-12 (rounding of the energies). Tumbling boxes with ε = 1 included.
    body = sim.Body.box(HALF, 1.0) if is_box else sim.Body.sphere(0.15, 1.0)
    dt = 1 / 240
    scene = sim.Scene(body, dt, gravity=DOWN, ground=sim.Ground(eps, mu, 0.0))
    free = sim.Scene(body, dt, integrator=scene.integrator, gravity=DOWN)
    state = scene.initial_state(
        position=(0, 0, 0.35),
        orientation=quat_exp(np.array(motion[:3]) * 0.5),
        linear_velocity=(motion[0], motion[1], -2.0 + motion[2]),
        angular_velocity=np.array(motion[3:]) * 3,
    )
    for _ in range(150):
        new, ref = scene.step(state), free.step(state)
        got = _kinetic(scene, state, new.linear_velocity, new.angular_velocity)
        want = _kinetic(scene, state, ref.linear_velocity, ref.angular_velocity)
        assert got <= want * (1 + 1e-12) + 1e-300
        e0, e1 = scene.energy(state), scene.energy(new)
        assert e1 <= e0 + 1e-12 * max(abs(e0), abs(e1))
        state = new


@pytest.mark.parametrize(("eps", "masses"), [(1.0, (1.0, 1.0)), (0.7, (1.0, 3.0))])
def test_an_oblique_sphere_impact_is_exact_at_any_phase_within_the_step(eps, masses):
    # Frictionless spheres in space, b at rest, a striking it off centre (impact parameter
    # 0.6 of the radii's sum, in y and z). At the instant they touch, n is the line of centres
    # and the impulse J = −(1 + ε) m_red (v_rel·n) acts along it through both centres: no
    # spin, and the exit velocities are the closed form's, whatever the phase of the impact
    # within the step (8 phases), to rounding (measured 2e-16; the bar 1e-12). With the
    # normal of the step's start, or the linearised closing time, the spheres spun at 0.8
    # rad/s and the exits missed by up to 1e-2 m/s, depending on the phase.
    r, dt, phases = 0.05, 1 / 240, 8
    scene = sim.Scene(
        [sim.Body.sphere(r, m) for m in masses], dt, contacts=sim.Material(eps, 0.0, 0.0)
    )
    offset = np.array([0.0, 0.048, 0.036])  # |offset| = 0.06 = 0.6 (2r)
    position = np.zeros((phases, 2, 3))
    position[:, 1] = offset
    position[:, 0, 0] = -0.2 - dt * np.arange(phases) / phases
    velocity = np.zeros((phases, 2, 3))
    velocity[:, 0, 0] = 1.0
    state = scene.initial_state(position=position, linear_velocity=velocity, batch_shape=(phases,))
    for _ in range(int(0.3 / dt)):
        state = scene.step(state)
    along = np.sqrt((2 * r) ** 2 - offset @ offset)
    n = (np.array([-along, 0.0, 0.0]) - offset) / (2 * r)  # from b to a at the touch
    m_red = masses[0] * masses[1] / sum(masses)
    impulse = -(1 + eps) * m_red * n[0]  # v_rel·n = n_x (a moves at (1, 0, 0))
    want = np.array([(1.0, 0.0, 0.0) + impulse / masses[0] * n, -impulse / masses[1] * n])
    np.testing.assert_allclose(
        state.linear_velocity, np.broadcast_to(want, state.linear_velocity.shape), atol=1e-12
    )
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)


def _cradle(gap, dt, phases, n=5, r=0.05, v=1.0):
    balls = [sim.Body.sphere(r, 1.0) for _ in range(n)]
    scene = sim.Scene(balls, dt, contacts=sim.Material(1.0, 0.0, 0.0))
    position = np.zeros((phases, n, 3))
    position[..., 0] = np.arange(n) * (2 * r + gap)
    # The striker starts 2 cm away, shifted by a fraction of one step's travel per element.
    position[:, 0, 0] -= 0.02 + v * dt * np.arange(phases) / phases
    velocity = np.zeros((phases, n, 3))
    velocity[:, 0, 0] = v
    state = scene.initial_state(position=position, linear_velocity=velocity, batch_shape=(phases,))
    return scene, state


@pytest.mark.parametrize(("gap", "dt"), [(3e-3, 1 / 240), (3e-3, 1 / 60), (0.0, 1e-3)])
def test_newtons_cradle_passes_the_strikers_velocity_to_the_last_ball(gap, dt):
    # Equal spheres, ε = 1, μ = 0, a few mm apart (or touching). At Δt = 1/240 the striker
    # travels 4.2 mm a step, at 1/60 17 mm: several impacts fall in one step, and each is
    # resolved at its own instant (restitution.py). Between equal masses each impact swaps
    # velocities exactly, so the last ball leaves with v and the others stop, to rounding
    # (1e-15 of v per impact; 1e-9 is the bar), energy to 1e-9 relative, momentum
    # exact (equal and opposite impulses: 1e-15), whatever the phase.
    scene, state = _cradle(gap, dt, phases=16)
    ke0, p0 = scene.kinetic_energy(state), scene.linear_momentum(state)
    for _ in range(int(0.12 / dt) + 5):
        state = scene.step(state)
    want = np.zeros(5)
    want[-1] = 1.0
    np.testing.assert_allclose(
        state.linear_velocity[..., 0], np.broadcast_to(want, (16, 5)), atol=1e-9
    )
    np.testing.assert_allclose(state.linear_velocity[..., 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(scene.kinetic_energy(state), ke0, rtol=1e-9)
    np.testing.assert_allclose(scene.linear_momentum(state), p0, rtol=0, atol=1e-14)


def test_touching_elastic_bodies_keep_momentum_and_never_gain_energy():
    # Unequal touching spheres (1, 2, 3 kg) struck by a fourth, ε = 1, off-axis so the normals
    # differ: impulses are equal and opposite (momentum exact to rounding, 1e-14) and no step
    # may gain kinetic energy (relative 1e-12).
    balls = [sim.Body.sphere(0.05, m) for m in (1.0, 1.0, 2.0, 3.0)]
    scene = sim.Scene(balls, 1 / 240, contacts=sim.Material(1.0, 0.3, 0.0))
    state = scene.initial_state(
        position=[(-0.15, 0.01, 0.0), (0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.19, 0.04, 0.0)],
        linear_velocity=[(2.0, 0.0, 0.0), (0, 0, 0), (0, 0, 0), (0, 0, 0)],
    )
    p0 = scene.linear_momentum(state)
    ke = scene.kinetic_energy(state)
    for _ in range(120):
        state = scene.step(state)
        new = scene.kinetic_energy(state)
        assert new <= ke * (1 + 1e-12)
        ke = new
    assert np.abs(state.linear_velocity[3, 0]) > 0.1  # the impacts reached the last ball
    np.testing.assert_allclose(scene.linear_momentum(state), p0, rtol=0, atol=1e-14)


# --- large steps ---------------------------------------------------------------------------------


@WARM
@pytest.mark.parametrize("dt", [1 / 60, 0.1, 0.5, 1.0])
def test_any_step_up_to_one_second_never_gains_energy_or_tunnels(dt, warm):
    # The landing scene (tumbling boxes, ε = 0.3) at steps up to 1 s: inaccurate, but each
    # step ends with no more KE + PE than it started with (relative 1e-12: rounding), and no
    # corner ends below the ground (1e-12 m: rounding of the separation's lift). Warm, in
    # calls of 2 steps (the steps are long: few of them), checked after each call against
    # twice the one step's bound.
    scene, init = landing_scene(dt=dt, contact_solver=sim.SolverSettings(warm_start=warm))
    state = init((4,), np.random.default_rng(3))
    box = scene.model.bodies[0].shape
    e = scene.energy(state)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        k = 2 if warm else 1
        for _ in range(int(2 / dt) + 10):
            state = scene.step(state, steps=k)
            e_new = scene.energy(state)
            assert np.all(e_new <= e + k * 1e-12 * np.maximum(np.abs(e), np.abs(e_new)))
            e = e_new
            corners = state.position[..., None, :] + quat_rotate(
                state.orientation[..., None, :], box.vertices
            )
            assert corners[..., 2].min() >= -1e-12


EDGE_HEIGHT = 0.9e-3  # m: the far edge above the ground (the bench's frozen boxes: 0.3–1 mm)


def test_box_at_rest_on_an_edge_at_a_large_step_topples_flat_instead_of_freezing():
    # A box at rest on an edge, its far edge EDGE_HEIGHT up, at Δt = 0.01 s. The far corners
    # strike the ground at ~0.15 m/s (pivoting on the edge; above the 0.1 m/s threshold, so a
    # bounce with ε = 0.3 follows), the next landing is below the threshold: the box must end
    # flat on a face and at rest. (The edge freeze: the impacts' path sank through the edge,
    # the separation's lift took the step's energy, and the energy guard zeroed the velocity
    # every step: tilted, at rest, the solve capped every step.) Bounds: corners of the face
    # at most 1e-12 m up (the rounding of the separation's lift, as at large steps below),
    # velocities 1e-12 (rest is the exact solution of a step, as for the resting bodies),
    # no solve capped and no impact once at rest (a face at rest needs one sweep), and each
    # step ends with no more KE + PE than it started with (relative 1e-12: rounding).
    dt = 0.01
    box = sim.Body.box(HALF, 1.0)
    scene = sim.Scene(box, dt, gravity=DOWN, ground=sim.Ground(0.3, 0.5))
    faces = [np.zeros(3), np.array([np.pi / 2, 0, 0]), np.array([0, np.pi / 2, 0])]
    orientation = []
    for face in faces:
        q = quat_exp(face)
        extent = np.ptp(quat_rotate(q, box.shape.vertices), axis=0)  # the face's sides
        for axis, side in ((0, 1), (1, 0)):  # tilted about world x (y side rises), about y
            tilt = np.zeros(3)
            tilt[axis] = np.arcsin(EDGE_HEIGHT / extent[side])
            orientation.append(quat_multiply(quat_exp(tilt), q))
    orientation = np.array(orientation)
    low = -np.min(quat_rotate(orientation[:, None, :], box.shape.vertices)[..., 2], axis=-1)
    position = np.zeros((len(orientation), 1, 3))
    position[:, 0, 2] = low
    state = scene.initial_state(position=position, orientation=orientation[:, None, :])
    e = scene.energy(state)
    steps, settled = 100, 50  # 1 s; the toppling takes a few steps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sim.ContactSolverWarning)
        for k in range(steps):
            state = scene.step(state)
            e_new = scene.energy(state)
            assert np.all(e_new <= e + 1e-12 * np.maximum(np.abs(e), np.abs(e_new)))
            e = e_new
            report = scene.report["contacts"]
            if k >= settled:
                assert (report.capped, report.impacts) == (0, 0), k
    corners = state.position + quat_rotate(state.orientation, box.shape.vertices)
    face = np.sort(corners[..., 2], axis=-1)[:, :4]
    assert np.all(np.abs(face) <= 1e-12), face
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-12)


# --- settings and report -------------------------------------------------------------------------


def test_solver_settings_are_validated_and_a_cap_is_reported():
    for kwargs, name in (
        ({"max_iterations": 0}, "max_iterations"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"tolerance": 0.0}, "tolerance"),
        ({"tolerance": "x"}, "tolerance"),
        ({"max_impacts": -1}, "max_impacts"),
        ({"start": "zero"}, "start"),
    ):
        with pytest.raises(ValueError, match=name):
            sim.SolverSettings(**kwargs)
    box = sim.Body.box(HALF, 1.0)
    with pytest.raises(ValueError, match="contact_solver"):
        sim.Scene(box, 0.01, gravity=DOWN, ground=sim.Ground(), contact_solver=5)

    def incline(solver):
        scene = sim.Scene(
            box,
            1 / 240,
            gravity=(G * np.sin(0.3), 0, -G * np.cos(0.3)),
            ground=sim.Ground(0.0, 0.5),
            contact_solver=solver,
        )
        return scene, scene.initial_state(position=(0, 0, 0.2))

    # The incline needs a probe sweep and a polishing sweep (bench/contact_solve.py): with a
    # cap of one sweep and Gauss–Seidel alone it stops unconverged, and says so.
    scene, state = incline(sim.SolverSettings(max_iterations=1, start="particle"))
    with pytest.warns(sim.ContactSolverWarning):
        scene.step(state)
    report = scene.report["contacts"]
    assert report.capped == 1 and not report.converged and report.iterations >= 1
    scene, state = incline(None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", sim.ContactSolverWarning)
        scene.step(state)
    assert scene.report["contacts"].converged and scene.report["contacts"].engaged == 1


def test_the_warm_start_starts_a_calls_later_steps_from_the_previous_impulses():
    # A box stuck on an incline needs the active-set start every step when cold (the particle
    # start has no friction). Warm, only the first step from a state without impulses does:
    # the later ones start from the previous step's impulses, which are the answer (the box
    # is at rest), and the report counts the element as warm-started (the most of any one
    # step: 1). The result is rest either way (the static-friction test above), within the
    # same tolerance.
    theta = 0.3
    for warm in (False, True):
        scene = sim.Scene(
            sim.Body.box((0.2, 0.2, 0.1), 1.0),
            1 / 240,
            gravity=(G * np.sin(theta), 0.0, -G * np.cos(theta)),
            ground=sim.Ground(0.0, 0.5),
            contact_solver=sim.SolverSettings(warm_start=warm),
        )
        start = scene.initial_state(position=(0, 0, 0.1))
        result = scene.step(start, steps=CHUNK)
        report = scene.report["contacts"]
        assert (report.engaged, report.warm_started, report.capped) == (1, int(warm), 0)
        # The next call's first step starts from the impulses the state carries (warm); a
        # state built from the arrays alone carries none and starts cold.
        assert scene.step(result).report["contacts"].warm_started == int(warm)
        assert scene.step(sim.State(*result.arrays())).report["contacts"].warm_started == 0
        for field in ("linear_velocity", "angular_velocity"):
            np.testing.assert_allclose(getattr(result, field), 0.0, rtol=0, atol=1e-9)


def test_warm_start_setting_is_validated():
    with pytest.raises(ValueError, match="warm_start"):
        sim.SolverSettings(warm_start="yes")
    with pytest.raises(ValueError, match="warm_start"):
        sim.SolverSettings(warm_start=1)
    assert sim.SolverSettings(warm_start=np.bool_(True)).warm_start is True
