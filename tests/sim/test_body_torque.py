"""A torque fixed in the body frame (``Scene.step(..., body_torque=)``) and several steps per
call (``steps=``), on the compiled step (``conftest``).

The body torque turns with the body: every integrator evaluates R(q) τ_body at the orientation
of each of its load evaluations. Tested against closed forms (spin-up about a principal axis),
the world torque where the two must coincide, an independent DOP853 reference for each
integrator's order, and k steps in one call against k calls, bit for bit.
"""

import functools

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rigid_env import sim
from rigid_env.sim.rotation import (
    quat_angle,
    quat_from_axis_angle,
    quat_multiply,
    quat_rotate,
    random_quaternions,
)

EPS = np.finfo(float).eps
ORDER = {name: record.order for name, record in sim.INTEGRATOR_RECORDS.items()}
MOMENTS = np.array([0.2, 0.4, 0.52])  # the Reorient satellite's principal moments, kg m²
# Methods whose kicks sit around a rotation that is exact for a spin about a principal axis.
EXACT_ON_AN_AXIS = ("splitting", "splitting4", "exact", "exact4")
# Semi-implicit methods update the velocities from the loads at the start of the step only.
START_LOADS = tuple(n for n, r in sim.INTEGRATOR_RECORDS.items() if r.semi_implicit)


def principal_body():
    return sim.Body(1.0, np.diag(MOMENTS))


def lopsided_body():
    """Body axes that are not principal: the body frame is not the principal frame."""
    return sim.Body(2.0, np.array([[0.2, 0.01, 0.02], [0.01, 0.3, 0.0], [0.02, 0.0, 0.4]]))


def same(a: sim.State, b: sim.State) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a.arrays(), b.arrays(), strict=True))


# --- closed forms ---------------------------------------------------------------------------


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_spin_up_about_a_principal_axis(name, axis):
    """Spinning at ω₀ about principal axis i with a body torque τ about the same axis: Ω stays
    on the axis (no gyroscopic term), so ω(t) = ω₀ + τ t / I_i and the body turns about that
    axis by θ(t) = ω₀ t + τ t² / (2 I_i): q(t) = q₀ ∘ exp(θ e_i)."""
    body, omega0, tau, t_end = principal_body(), 1.5, 0.3, 2.0
    q0 = random_quaternions(np.random.default_rng(axis))
    e = np.eye(3)[axis]
    rate = omega0 + tau * t_end / MOMENTS[axis]
    theta = omega0 * t_end + tau * t_end**2 / (2 * MOMENTS[axis])
    q_exact = quat_multiply(q0, quat_from_axis_angle(e, theta))
    errors = []
    for dt in (0.02, 0.01):
        scene = sim.Scene(body, dt, integrator=name)
        state = scene.initial_state(orientation=q0, angular_velocity=quat_rotate(q0, omega0 * e))
        state = scene.step(state, body_torque=tau * e, steps=round(t_end / dt))
        # ω is linear in t, which every method integrates exactly: rounding only, ~ε |ω| per
        # step over ≤ 200 steps of |ω| ≤ 4.5 rad/s: 2e-13; 1e-12 allows the body-to-world turns.
        # (R(q) e_i = R(q₀) e_i throughout: the world axis of the spin never moves.)
        omega = state.angular_velocity[0]
        assert np.allclose(omega, quat_rotate(q0, rate * e), rtol=0, atol=1e-12)
        errors.append(quat_angle(state.orientation[0], q_exact))
    if name in EXACT_ON_AN_AXIS:
        # Half kicks around a rotation exact about a principal axis: exact but for rounding.
        # Each free flow errs by ≤ 64 ε (1 + |ω| Δt) and storing q, ω by 4 ε (the bound of
        # tests/sim/test_exact.py), 1 or 3 flows a step (the triple jump), over 200 steps.
        # About the intermediate axis (unstable) a rounding-size tilt grows like e^(σ θ),
        # σ = √((I₂ − I₁)(I₃ − I₂) / (I₁ I₃)) = 0.48, θ = 4.5 rad here: a factor 8.7.
        flows = 3 if name.endswith("4") else 1
        growth = np.exp(0.48 * theta) if axis == 1 else 1.0
        bound = 200 * (flows * 64 * EPS * (1 + rate * 0.02) + 4 * EPS) * growth
        assert max(errors) < bound, (errors, bound)
    else:
        observed = np.log2(errors[0] / errors[1])
        assert abs(observed - ORDER[name]) < 0.3, (errors, observed)


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_a_zero_body_torque_steps_as_a_zero_world_torque(name):
    """The torque-free limit: R(q) 0 = 0 adds nothing, bit for bit (signed zeros aside)."""
    scene = sim.Scene(lopsided_body(), 0.02, integrator=name, gravity=(0, 0, -9.81))
    rng = np.random.default_rng(4)
    state = scene.initial_state(
        orientation=random_quaternions(rng, (3, 1)),
        angular_velocity=rng.normal(0, 2, (3, 1, 3)),
    )
    body = scene.step(state, body_torque=np.zeros(3), steps=10)
    world = scene.step(state, torque=np.zeros(3), steps=10)
    assert same(body, world)


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_body_and_world_torque_agree_while_the_torque_keeps_its_world_direction(name):
    """From rest, a torque about a principal axis turns the body about that axis only, so
    R(q) τ_body stays R(q₀) τ_body: the two loads are the same function of time, and the two
    runs differ only in how R(q) τ is rounded. Per load evaluation that is ≤ 64 ε relative (a
    generous count of the operations it passes through), ≤ 6 evaluations a step (the triple
    jump's kicks), 100 steps, about the stable axis of largest moment (no growth of a tilt)."""
    body = principal_body()
    q0 = random_quaternions(np.random.default_rng(6))
    tau = np.array([0.0, 0.0, 0.2])
    scene = sim.Scene(body, 0.02, integrator=name)
    state = scene.initial_state(orientation=q0)
    turned = scene.step(state, body_torque=tau, steps=100)
    held = scene.step(state, torque=quat_rotate(q0, tau), steps=100)
    bound = 100 * 6 * 64 * EPS
    omega = 0.2 * 2.0 / MOMENTS[2]  # the final spin, rad/s
    assert quat_angle(turned.orientation[0], held.orientation[0]) < bound
    assert np.abs(turned.angular_velocity - held.angular_velocity).max() < bound * omega
    assert np.abs(turned.angular_velocity[0]).max() > 0.5 * omega  # it did spin up


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_where_each_integrator_evaluates_the_body_torque(name):
    """One step of a spinning lopsided body under a generic body torque. Semi-implicit methods
    take the loads at the start of the step only, so they equal the world torque R(q₀) τ to
    rounding (≲ 10 ε of |ω|); the others evaluate it again later in the step, at orientations
    that have turned by ~|Ω| Δt = 0.06 rad, which changes ω by ~ Δt · 0.06 |τ| / I ≈ 1e-3."""
    scene = sim.Scene(lopsided_body(), 0.02, integrator=name)
    q0 = random_quaternions(np.random.default_rng(8))
    state = scene.initial_state(orientation=q0, angular_velocity=(1.0, -2.0, 2.0))
    tau = np.array([0.4, 0.3, -0.5])
    turned = scene.step(state, body_torque=tau)
    held = scene.step(state, torque=quat_rotate(q0, tau))
    gap = np.abs(turned.angular_velocity - held.angular_velocity).max()
    if name in START_LOADS:
        assert gap < 10 * EPS * 3
    else:
        assert gap > 1e-5


# --- order of accuracy ----------------------------------------------------------------------


@functools.cache
def dop853_reference(t_end):
    """q(t_end) of Euler's equations with a body-fixed torque, DOP853 at rtol 1e-13 (its
    error here is ~1e-12, three orders below the smallest error the order test measures)."""

    def rhs(_t, y):
        q, pi = y[:4] / np.linalg.norm(y[:4]), y[4:]
        om = pi / MOMENTS
        dq = 0.5 * quat_multiply(q, np.append(om, 0.0))
        return np.concatenate((dq, np.cross(pi, om) + ORDER_TORQUE))

    y0 = np.concatenate((ORDER_Q0, MOMENTS * ORDER_OMEGA0))
    sol = solve_ivp(rhs, (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-14)
    return sol.y[:4, -1] / np.linalg.norm(sol.y[:4, -1])


ORDER_Q0 = np.array([0.1, -0.3, 0.2, 0.9]) / np.linalg.norm([0.1, -0.3, 0.2, 0.9])
ORDER_OMEGA0 = np.array([0.3, 1.5, -0.4])  # body axes, near the intermediate axis
ORDER_TORQUE = np.array([0.2, -0.3, 0.25])  # body axes
# The coarsest step per order, in the asymptotic regime of every method of that order.
ORDER_STEP = {1: 0.02, 2: 0.1, 4: 0.4}


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_order_with_a_body_torque_matches_the_record(name):
    """Global error at Δt, Δt/2, Δt/4 over 2 s against DOP853 with the torque in body axes.

    e(h) = a hᵖ (1 + c h + …) gives an observed order log2(e(h)/e(h/2)) = p + O(h), the
    deviation halving with h: on the finer pair it must be within 0.1 of the record's p and
    no farther from p than on the coarser pair. A torque held in the world over each step
    (the env's former load model) is a first-order error and fails this for every method of
    order 2 and 4.
    """
    t_end, p = 2.0, ORDER[name]
    q_ref = dop853_reference(t_end)
    errors = []
    for dt in ORDER_STEP[p] / np.array([1, 2, 4]):
        scene = sim.Scene(principal_body(), dt, integrator=name)
        state = scene.initial_state(
            orientation=ORDER_Q0, angular_velocity=quat_rotate(ORDER_Q0, ORDER_OMEGA0)
        )
        state = scene.step(state, body_torque=ORDER_TORQUE, steps=round(t_end / dt))
        errors.append(quat_angle(state.orientation[0], q_ref))
    errors = np.array(errors)
    assert errors.min() > 1e3 * 1e-12, errors  # far above the reference's own error
    coarse, fine = np.log2(errors[:-1] / errors[1:])
    assert abs(fine - p) < 0.1, (errors, coarse, fine)
    assert abs(fine - p) <= abs(coarse - p) + 0.01, (errors, coarse, fine)


# --- validation and broadcasting --------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"body_torque": np.full((4, 1, 3), np.nan)}, "body_torque"),
        ({"body_torque": np.array([0.0, np.inf, 0.0])}, "body_torque"),
        ({"body_torque": np.zeros((4, 2, 3))}, "body_torque"),
        ({"body_torque": np.zeros(2)}, "body_torque"),
        ({"body_torque": "spin"}, "body_torque"),
        ({"steps": 0}, "steps"),
        ({"steps": -2}, "steps"),
        ({"steps": 1.5}, "steps"),
        ({"steps": 2.0}, "steps"),
        ({"steps": True}, "steps"),
        ({"steps": "3"}, "steps"),
        ({"steps": None}, "steps"),
    ],
)
@pytest.mark.parametrize("name", ["splitting", "exact", "rk4", "implicit_gyro"])
def test_rejected_step_names_the_parameter_and_leaves_the_state_alone(kwargs, word, name):
    scene = sim.Scene(principal_body(), 0.01, integrator=name, gravity=(0, 0, -9.81))
    state = scene.initial_state(angular_velocity=(1, 2, 3), batch_shape=(4,))
    before = [a.copy() for a in state.arrays()]
    with pytest.raises(ValueError, match=word):
        scene.step(state, **kwargs)
    for a, b in zip(before, state.arrays(), strict=True):
        assert np.array_equal(a, b)
    after = scene.step(state, body_torque=np.ones((4, 1, 3)), steps=np.int64(2))
    assert np.all(np.isfinite(after.angular_velocity))


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_a_broadcast_body_torque_acts_as_its_full_copy(name):
    scene = sim.Scene([principal_body(), lopsided_body()], 0.02, integrator=name)
    rng = np.random.default_rng(1)
    state = scene.initial_state(
        orientation=random_quaternions(rng, (2, 2)), angular_velocity=rng.normal(0, 1, (2, 2, 3))
    )
    for shape in [(3,), (2, 3), (2, 1, 3)]:
        tau = np.arange(1.0, 1.0 + np.prod(shape)).reshape(shape) / 10
        full = np.broadcast_to(tau, (2, 2, 3)).copy()
        assert same(scene.step(state, body_torque=tau), scene.step(state, body_torque=full))


# --- several steps per call -------------------------------------------------------------------


@pytest.mark.parametrize("name", sim.INTEGRATORS)
def test_k_steps_in_one_call_equal_k_calls_bit_for_bit(name):
    """Every load at once (world and body torques, force, gravity, damping, a spring), a batch
    of shape (2, 3) of two bodies: the result of steps=k is the k-th single call's, bit for bit
    (the compiled driver carries each step's result into the next inside its kernel)."""
    spring = sim.Spring(0, (0.0, 0.0, 1.0), 10.0, 0.5, 0.3, (0.1, 0.0, 0.0))
    scene = sim.Scene(
        [principal_body(), lopsided_body()],
        0.01,
        integrator=name,
        gravity=(0, 0, -9.81),
        linear_damping=0.1,
        angular_damping=0.2,
        springs=[spring],
    )
    rng = np.random.default_rng(2)
    state = scene.initial_state(
        position=rng.normal(0, 0.3, (2, 3, 2, 3)),
        orientation=random_quaternions(rng, (2, 3, 2)),
        linear_velocity=rng.normal(0, 1, (2, 3, 2, 3)),
        angular_velocity=rng.normal(0, 3, (2, 3, 2, 3)),
    )
    loads = dict(
        torque=(0.1, -0.2, 0.05),
        force=rng.normal(0, 1, (2, 3, 2, 3)),
        body_torque=rng.normal(0, 0.5, (3, 2, 3)),
    )
    single = state
    for _ in range(7):
        single = scene.step(single, **loads)
    assert same(scene.step(state, steps=7, **loads), single)
    assert same(scene.step(state, steps=1, **loads), scene.step(state, **loads))


def test_k_steps_of_a_contact_scene_equal_k_calls():
    """A box dropped on the ground (contact stages between the velocity and position updates,
    reading the start-of-step state), through its impact: bit for bit."""
    scene = sim.Scene(
        sim.Body.box((0.2, 0.15, 0.1), 1.0), 0.01, gravity=(0, 0, -9.81), ground=sim.Ground()
    )
    rng = np.random.default_rng(3)
    state = scene.initial_state(
        position=(0.0, 0.0, 0.3),
        orientation=random_quaternions(rng, (2, 1)),
        angular_velocity=rng.normal(0, 2, (2, 1, 3)),
    )
    single = state
    for _ in range(30):
        single = scene.step(single, body_torque=(0.0, 0.05, 0.0))
    assert same(scene.step(state, body_torque=(0.0, 0.05, 0.0), steps=30), single)
    assert single.position[..., 2].min() < 0.3  # it fell: the contact stages had work to do


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy's overflow notes on the way up
def test_a_divergence_within_k_steps_raises_as_the_single_call_would():
    """Explicit Euler on a spring with ω_n Δt = 1000 grows ~10⁶ per step: single calls raise
    within 200 steps, and so must one call of 200 steps (instead of returning NaN)."""
    spring = sim.Spring(0, anchor=(0, 0, 0), stiffness=1e6)
    scene = sim.Scene(sim.Body.sphere(0.1, 1.0), 1.0, integrator="euler", springs=[spring])
    state = scene.initial_state(position=(1, 0, 0))
    with pytest.raises(sim.DivergenceError, match="diverged"):
        scene.step(state, steps=200)
    assert np.array_equal(state.position, [[1.0, 0.0, 0.0]])  # the input is untouched


def test_the_timer_counts_every_physics_step():
    scene = sim.Scene(principal_body(), 0.01, timer=sim.StageTimer())
    state = scene.step(scene.initial_state(angular_velocity=(1, 2, 3)), steps=5)
    scene.step(state, body_torque=(0.1, 0, 0), steps=3)
    assert scene.timer.steps == 8
    assert sum(scene.timer.seconds.values()) <= scene.timer.step_seconds


# --- reports of several steps -----------------------------------------------------------------


def test_the_compiled_step_carries_results_and_folds_report_rows():
    """``steps.carry`` and ``steps.fold`` on a hand-made step tuple: the result rows become the
    start rows, contact slots are zeroed but for the warm-start columns (the previous step's
    impulses, ``SolverSettings.warm_start``), and the report is the maximum over the steps."""
    pytest.importorskip("numba")
    from rigid_env.sim.compiled import layout, steps

    rng = np.random.default_rng(0)
    st = [rng.normal(size=(3, 1, 4 if i in (1, 5) else 3)) for i in range(10)]
    st += [np.zeros((3, 1, 3)), rng.normal(size=(3, 2, layout.CONTACT_WIDTH))]
    report = np.zeros((3, layout.REPORT_WIDTH))
    report[1, layout.ITERATIONS], report[1, layout.CAPPED] = 4.0, 1.0
    st += [report, np.zeros((3, 1, 3))]
    st = tuple(st)
    total = np.zeros_like(report)
    steps.carry(1, st, total)
    for start, result in ((layout.X0, layout.X), (layout.Q0, layout.Q), (layout.W0, layout.W)):
        assert np.array_equal(st[start][1], st[result][1])
        assert not np.array_equal(st[start][0], st[result][0])  # other rows untouched
    contact = st[layout.CONTACT]
    assert not contact[1, :, : layout.WARM].any() and contact[0].all()
    assert contact[1, :, layout.WARM : layout.WARM_END].all()  # the next step's warm start
    assert not contact[1, :, layout.WARM_END :].any()  # the body–body columns: zeroed
    assert not report[1].any() and total[1, layout.ITERATIONS] == 4.0
    report[1, layout.ITERATIONS] = 2.0  # the next step used fewer iterations, did not cap
    steps.fold(1, st, total)
    assert report[1, layout.ITERATIONS] == 4.0 and report[1, layout.CAPPED] == 1.0
