"""The compiled contact step's guarantees beyond the laws (``test_contacts``,
``test_contact_laws``): a batch steps as its elements alone and on threads bit for bit, a
capped solve is reported per element and warned at the caller, a body without a shape moves
as if no contact existed, and the ground detection keeps each box's K lowest corners where
corners tie.
"""

import warnings

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench.contact_solve import l_prism, tetrahedron
from rigid_env.sim.rotation import quat_exp, quat_multiply, quat_rotate
from rigid_env.sim.scenes import landing_scene

G = 9.81
DT = 1 / 240
STEPS = 240


def scenes(settings):
    """name → (scene, start state): every ground case the issue names."""
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    down = (0.0, 0.0, -G)

    def make(body, gravity=down, ground=None):
        ground = sim.Ground(0.3, 0.5) if ground is None else ground
        return sim.Scene(body, DT, gravity=gravity, ground=ground, contact_solver=settings)

    def resting(body):
        scene = make(body)
        return scene, scene.initial_state(position=(0, 0, -np.min(body.shape.vertices[:, 2])))

    tilt = 0.3  # tan 0.3 < μ = 0.5: sticks
    incline = make(box, (G * np.sin(tilt), 0.0, -G * np.cos(tilt)), sim.Ground(0.0, 0.5))
    slide = make(box, ground=sim.Ground(0.0, 0.5))
    ball = make(sim.Body.sphere(0.1, 1.0), ground=sim.Ground(0.8, 0.5))
    land, init = landing_scene()
    tumble = make(land.model.bodies)
    batch = init((8,), np.random.default_rng(0))
    yaw = quat_exp(np.array([0.0, 0.0, 0.4]))
    return {
        "resting box": resting(box),
        "resting L-prism": resting(l_prism()),
        "resting tetrahedron": resting(tetrahedron()),
        "box on incline": (incline, incline.initial_state(position=(0, 0, 0.2))),
        "yawed box sliding": (
            slide,
            slide.initial_state(position=(0, 0, 0.2), orientation=yaw, linear_velocity=(1.5, 1, 0)),
        ),
        "bouncing sphere": (ball, ball.initial_state(position=(0, 0, 1.0))),
        "tumbling landing": (tumble, init()),
        "8 tumbling boxes": (tumble, batch),
    }


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_batched_compiled_step_equals_elements_alone_bit_for_bit():
    scene, state = scenes(sim.SolverSettings())["8 tumbling boxes"]
    fields = ("position", "orientation", "linear_velocity", "angular_velocity")
    touched_any = False
    for _ in range(150):
        new = scene.step(state)
        touched = scene.report["contacts"].touched
        touched_any |= touched.any()
        for i in range(8):
            alone = scene.step(sim.State(*(getattr(state, f)[i] for f in fields)))
            for f in fields:
                assert np.array_equal(getattr(alone, f), getattr(new, f)[i])
            assert scene.report["contacts"].touched[0] == touched[i]
        state = new
    assert touched_any


def test_every_contact_scene_compiles():
    box = sim.Body.box((0.1, 0.1, 0.1), 1.0)
    ground = sim.Ground(0.5, 0.5)
    for body in (box, sim.Body.sphere(0.1, 1.0), tetrahedron()):
        scene = sim.Scene([body, body], DT, gravity=(0, 0, -G), ground=ground)
        assert scene.backend == "compiled"
    pair = sim.Scene([box, box], DT, ground=ground, contacts=sim.Material())
    assert pair.backend == "compiled"
    space = sim.Scene([box, box], DT, contacts=sim.Material())
    assert space.backend == "compiled"


@pytest.mark.parametrize(
    "settings", [sim.SolverSettings(max_iterations=1), sim.SolverSettings(max_impacts=1)]
)
def test_a_capped_solve_is_reported_per_element_and_warned_at_the_caller(settings):
    """One sweep, or one impact per step, is not enough for the tumbling landing: the steps
    that stop at the cap say so in ``capped`` (the count), ``capped_mask`` (per element, what
    an env counts per sub-env) and ``converged``, with one ``ContactSolverWarning``
    attributed to this file; the steps that do not, warn nothing."""
    scene, state = scenes(settings)["8 tumbling boxes"]
    capped_steps = 0
    for _ in range(STEPS):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            state = scene.step(state)
        report = state.report["contacts"]
        assert report.capped_mask.shape == (8,)
        assert int(report.capped_mask.sum()) == report.capped
        assert report.converged == (report.capped == 0)
        kinds = [w.category for w in caught]
        if report.capped:
            assert kinds == [sim.ContactSolverWarning]
            assert caught[0].filename == __file__  # attributed to the caller
        else:
            assert kinds == []
        capped_steps += report.capped > 0
    assert capped_steps > 0


CONTACT_INTEGRATORS = [name for name in sim.INTEGRATORS if name in sim.CONTACT_CAPABLE]


# Every contact integrator under gravity, and one without any force stage (its own stage
# tuple: the contact stages with nothing but the integrator around them). Each pair compiles a
# contact driver (~15 s), so the force-free tuple is not repeated per integrator: the force
# terms' composition is integrator-independent and test_compiled.py covers it for all of them.
SHAPELESS_CASES = [(name, (0.0, 0.0, -G)) for name in CONTACT_INTEGRATORS]
SHAPELESS_CASES.append((sim.CONTACT_INTEGRATOR, None))


@pytest.mark.parametrize(("integrator", "gravity"), SHAPELESS_CASES)
def test_a_body_without_a_shape_moves_as_without_contacts(integrator, gravity):
    """Three bodies, the first without a shape (no contact slots, but the energy guard and
    the impacts' path reach it too), the others thrown at the ground: the shapeless body's
    motion is that of the same body alone in the same gravity, through the steps where the
    others strike the ground. An engaged step turns its orientation along the impacts' path
    and back (exp(elapsed ω), then exp((Δt − elapsed) ω)): a few roundings of |q| = 1 and of
    |x|, |v| ≤ 3 per step, 120 steps × 8 ε × 3 ≈ 6e-13, so 1e-12."""
    free = sim.Body(2.0, np.diag([0.1, 0.2, 0.3]))
    bodies = [free, sim.Body.box((0.1, 0.15, 0.2), 1.0), sim.Body.sphere(0.1, 1.0)]
    ground = sim.Ground(0.5, 0.4)
    scene = sim.Scene(bodies, DT, integrator=integrator, gravity=gravity, ground=ground)
    alone = sim.Scene(free, DT, integrator=integrator, gravity=gravity)
    state = scene.initial_state(
        position=[(0, 0, 2.0), (0, 0, 0.5), (0.5, 0, 0.3)],
        linear_velocity=[(0, 0, -1), (0.5, 0, -3), (0, 0.3, -2)],
        angular_velocity=[(1, 2, 3), (2, 1, 0), (0, 0, 1)],
    )
    single = alone.initial_state(
        position=(0, 0, 2.0), linear_velocity=(0, 0, -1), angular_velocity=(1, 2, 3)
    )
    impacts = 0
    for _ in range(120):
        state, single = scene.step(state), alone.step(single)
        impacts += state.report["contacts"].impacts
        for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
            got, want = getattr(state, field)[0], getattr(single, field)[0]
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=field)
    assert impacts > 0


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_threaded_contact_step_equals_serial_bit_for_bit():
    serial, state = scenes(sim.SolverSettings())["8 tumbling boxes"]
    threads = sim.Scene(
        serial.model.bodies,
        DT,
        gravity=(0, 0, -G),
        ground=serial.model.ground,
        backend="compiled-threads",
    )
    fields = ("position", "orientation", "linear_velocity", "angular_velocity")
    for _ in range(150):
        a, b = serial.step(state), threads.step(state)
        assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in fields)
        ra, rb = serial.report["contacts"], threads.report["contacts"]
        assert (ra.engaged, ra.iterations, ra.impacts, ra.capped) == (
            rb.engaged,
            rb.iterations,
            rb.impacts,
            rb.capped,
        )
        assert np.array_equal(ra.touched, rb.touched)
        state = a


def test_the_detection_keeps_a_boxs_four_lowest_corners_where_corners_tie():
    """The detection orders a box's corners by R's third row (no per-element scratch): the
    four lowest of the corners rotated here, in vertex order (ties to the lower index), with
    their arms and gaps to rounding (4 ε of the box's size), for generic orientations and for
    those where corners tie (faces and edges level: every multiple of 45° about x, then y)."""
    from numba import njit

    from rigid_env.sim.compiled import layout
    from rigid_env.sim.compiled.ground import detect, ground_data

    @njit
    def run(st, data):
        for e in range(st[0].shape[0]):
            detect(e, st, data)

    body = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    rng = np.random.default_rng(0)
    generic = quat_exp(rng.normal(size=(500, 3)))
    angles = np.arange(8) * np.pi / 4
    ax, ay = np.meshgrid(angles, angles)
    about_x = quat_exp(np.stack([ax.ravel(), 0 * ax.ravel(), 0 * ax.ravel()], -1))
    about_y = quat_exp(np.stack([0 * ay.ravel(), ay.ravel(), 0 * ay.ravel()], -1))
    level = quat_multiply(about_y, about_x)
    q0 = np.concatenate([generic, level])[:, None, :]
    n = len(q0)
    x0 = np.zeros((n, 1, 3))
    x0[:, 0, 2] = rng.uniform(-0.1, 0.5, n)
    data = ground_data([body])
    slots = len(data[2]) * int(data[3][0])
    contact = np.zeros((n, slots, layout.CONTACT_WIDTH))
    zero = np.zeros((n, 1, 3))
    st = (x0, q0, zero, zero, zero, q0, zero, zero, zero, zero, zero, contact)
    st = st + (np.zeros((n, layout.REPORT_WIDTH)), zero)
    run(st, data)
    corners = body.shape.vertices
    arm = quat_rotate(q0[:, :, None, :], corners)  # (n, 1, 8, 3)
    heights = x0[:, :, None, 2] + arm[..., 2]
    # Ties by the heights R's third row gives (a corner's height up to rounding): the lower
    # vertex index first, as the kernel orders them.
    lowest = np.sort(np.argsort(np.round(heights, 12), axis=-1, kind="stable")[..., :4], -1)
    gap = np.take_along_axis(heights, lowest, -1)
    arm = np.take_along_axis(arm, lowest[..., None], -2)
    size = 4 * np.finfo(float).eps * 0.5
    np.testing.assert_allclose(contact[:, :, layout.ARM : layout.ARM + 3], arm[:, 0], atol=size)
    np.testing.assert_allclose(contact[:, :, layout.GAP], gap[:, 0], atol=size)
