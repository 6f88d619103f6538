"""The compiled ground-contact stages against the numpy reference (``rigid_env.sim.contacts``).

Step by step from the same state. Each step is taken by both backends from the numpy
trajectory's state, so differences cannot be amplified by the dynamics from step to step (a
tumbling box on its edge doubles a perturbation every few steps). Within one step the two
backends run the same algorithm and the same operations on the same data, with sums in another
order in places (numpy's einsum/matmul/BLAS dot products, LAPACK's ``eigh`` against one Jacobi
rotation for the 2×2 tangent blocks, ``solve`` against L⁻¹ Rᵀ for the scaled velocities): a
few roundings, ~64 ε S for velocities of scale S (ε = 2.2e-16). One more source is not
rounding but starts from it: Gauss–Seidel stops at the first sweep that changes no contact
velocity by more than ``tol · S``, and what is left of the iteration then is that change times
ρ/(1 − ρ), ρ its contraction per sweep. A solve that needed N sweeps to fall from S to tol · S
has ρ^N ≈ tol, so 1/(1 − ρ) ≈ N / ln(1/tol); the two backends may stop a sweep apart, at most
2 tol S (1 + N / ln(1/tol)) apart in velocity. Positions move by Δt times that (Δt < 1). S is
at most 10 m/s in these scenes (a 1 m drop is 4.4 m/s, a 3 rad/s spin moves a corner 0.8 m/s).
"""

import warnings

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench.contact_solve import l_prism, tetrahedron
from rigid_env.sim.compiled import backend as compiled_backend
from rigid_env.sim.rotation import quat_exp, quat_multiply
from rigid_env.sim.scenes import landing_scene

pytestmark = pytest.mark.skipif(
    not compiled_backend.numba_available(), reason="numba is not installed"
)
G = 9.81
DT = 1 / 240
SPEED = 10.0  # m/s: the largest contact velocity in these scenes (module docstring)
STEPS = 240
TOLERANCE = sim.SolverSettings().tolerance


def step_bound(tolerance, sweeps):
    """The module docstring's bound on one step's difference (velocities; positions less)."""
    tail = 2 * tolerance * SPEED * (1 + sweeps / np.log(1 / tolerance))
    return tail + 64 * np.finfo(float).eps * SPEED


# A Newton polish (``SolverSettings.newton_steps``) ends at a point of the solution set that
# the backends' dense linear algebra (LAPACK against a pivoted Cholesky) reach differently where
# that set is degenerate (a face's redundant corners): measured up to 1e-8 m/s (rad/s) in 3 of
# the 8-box landing's 240 steps, where the same steps without the polish agree to 1e-13. Such
# steps may exceed ``step_bound`` (at most 2 % of them), and never this.
POLISHED = 1e-6
POLISHED_SHARE = 0.02


def check_fields(out, ref, a, b, bound) -> bool:
    """Every state field of the two steps within ``bound``, or, in a step where either backend
    polished by Newton, within ``POLISHED``; returns whether the looser bound was needed."""
    polished = a.newton > 0 or b.newton > 0
    loose = False
    for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
        diff = np.max(np.abs(getattr(out, field) - getattr(ref, field)))
        if polished and diff > bound:
            loose = True
            assert diff <= POLISHED, (field, diff, a, b)
        else:
            assert diff <= bound, (field, diff, bound, a, b)
    return loose


def impacts_bound(settings, impacts):
    """What a step's impacts add to ``step_bound``: each event is a Gauss–Seidel solve of its
    own (the struck contacts with the loaded supports held), stopped by the same rule, whose
    sweeps the report does not give: at most ``max_iterations`` each."""
    return impacts * step_bound(settings.tolerance, settings.max_iterations)


def scenes(backend, settings):
    """name → (scene, start state): every ground case the issue names."""
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)
    down = (0.0, 0.0, -G)

    def make(body, gravity=down, ground=None):
        ground = sim.Ground(0.3, 0.5) if ground is None else ground
        return sim.Scene(
            body, DT, gravity=gravity, ground=ground, contact_solver=settings, backend=backend
        )

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


SETTINGS = {
    "active_set": sim.SolverSettings(),
    "particle": sim.SolverSettings(start="particle", max_iterations=2000),
}


# (scene, start, steps): every scene with the default start; the particle start (slow on the
# incline and the prism, which is what the active-set start is for) on three, fewer steps.
CASES = [(name, "active_set", STEPS) for name in scenes("numpy", sim.SolverSettings())]
CASES += [
    ("resting L-prism", "particle", 60),
    ("box on incline", "particle", 60),
    ("tumbling landing", "particle", STEPS),
]


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
@pytest.mark.parametrize(("name", "start", "steps"), CASES)
def test_compiled_contacts_match_numpy_step_by_step(name, start, steps):
    settings = SETTINGS[start]
    numpy_scene, state = scenes("numpy", settings)[name]
    compiled_scene, _ = scenes("compiled", settings)[name]
    assert compiled_scene.backend == "compiled"
    engaged = same_sweeps = split_caps = loose = 0
    for _ in range(steps):
        ref = numpy_scene.step(state)
        out = compiled_scene.step(state)
        a, b = numpy_scene.report["contacts"], compiled_scene.report["contacts"]
        assert (b.engaged, b.impacts) == (a.engaged, a.impacts)
        np.testing.assert_array_equal(b.touched, a.touched)
        assert b.tolerance == a.tolerance
        # Whether a solve that crawls reaches the tolerance before the cap is itself decided by
        # roundings: after a Newton polish the two backends' iterates differ by a few ulp, and
        # one may converge in the next sweeps while the other crawls to the cap (seen once on
        # the 8-box landing: 12 sweeps against 501). Such a split may happen, rarely; a
        # systematic difference in the solve would split far more steps.
        split_caps += b.capped != a.capped
        # A step stopped at the cap holds an iterate, not a solution: no bound applies (numpy
        # itself moves by 2e-7 m/s when the state moves by one ulp in such a step of the 8-box
        # landing, measured; converged, the backends agree to 5e-14).
        bound = (
            np.inf
            if a.capped or b.capped
            else step_bound(settings.tolerance, max(a.iterations, b.iterations))
            + impacts_bound(settings, a.impacts)
        )
        loose += check_fields(out, ref, a, b, bound)
        engaged += a.engaged > 0
        same_sweeps += a.iterations == b.iterations
        state = ref
    assert engaged > 0
    assert split_caps <= 0.01 * steps
    assert loose <= POLISHED_SHARE * steps
    # The sweep count is the first sweep under the tolerance: a rounding can move it by one in
    # a slowly converging solve. In all but a few steps it is the same.
    assert same_sweeps >= 0.95 * steps


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_batched_compiled_step_equals_elements_alone_bit_for_bit():
    scene, state = scenes("compiled", sim.SolverSettings())["8 tumbling boxes"]
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
        scene = sim.Scene([body, body], DT, gravity=(0, 0, -G), ground=ground, backend="auto")
        assert scene.backend == "compiled"
    pair = sim.Scene([box, box], DT, ground=ground, contacts=sim.Material(), backend="auto")
    assert pair.backend == "compiled"
    space = sim.Scene([box, box], DT, contacts=sim.Material(), backend="auto")
    assert space.backend == "compiled"


@pytest.mark.parametrize(
    "settings", [sim.SolverSettings(max_iterations=1), sim.SolverSettings(max_impacts=1)]
)
def test_compiled_cap_is_reported_and_warned_as_numpy_does(settings):
    numpy_scene, state = scenes("numpy", settings)["tumbling landing"]
    compiled_scene, _ = scenes("compiled", settings)["tumbling landing"]
    capped_steps = 0
    for _ in range(STEPS):
        with warnings.catch_warnings(record=True) as ref_warnings:
            warnings.simplefilter("always")
            ref = numpy_scene.step(state)
        with warnings.catch_warnings(record=True) as out_warnings:
            warnings.simplefilter("always")
            compiled_scene.step(state)
        a, b = numpy_scene.report["contacts"], compiled_scene.report["contacts"]
        assert b.capped == a.capped
        assert b.converged == a.converged
        # Per element, which solves stopped (an env counts them per sub-env): the same on both.
        np.testing.assert_array_equal(b.capped_mask, a.capped_mask)
        assert a.capped_mask.shape == (int(np.prod(state.position.shape[:-2])),)
        assert int(a.capped_mask.sum()) == a.capped
        kinds = [w.category for w in out_warnings]
        assert kinds == [w.category for w in ref_warnings]
        if b.capped:
            assert kinds == [sim.ContactSolverWarning]
            assert out_warnings[0].filename == __file__  # attributed to the caller
        capped_steps += b.capped > 0
        state = ref
    assert capped_steps > 0


CONTACT_INTEGRATORS = [name for name in sim.INTEGRATORS if name in sim.CONTACT_CAPABLE]


# Every contact integrator under gravity, and one without any force stage (its own stage
# tuple: the contact stages with nothing but the integrator around them). Each pair compiles a
# contact driver (~15 s), so the force-free tuple is not repeated per integrator: the force
# terms' composition is integrator-independent and test_compiled.py covers it for all of them.
SHAPELESS_CASES = [(name, (0.0, 0.0, -G)) for name in CONTACT_INTEGRATORS]
SHAPELESS_CASES.append((sim.CONTACT_INTEGRATOR, None))


@pytest.mark.parametrize(("integrator", "gravity"), SHAPELESS_CASES)
def test_every_contact_integrator_with_a_shapeless_body_matches_numpy(integrator, gravity):
    """Three bodies, the first without a shape (no contact slots, but the energy guard and
    the impacts' path move it too), thrown at the ground: the bound of the module docstring."""
    free = sim.Body(2.0, np.diag([0.1, 0.2, 0.3]))
    bodies = [free, sim.Body.box((0.1, 0.15, 0.2), 1.0), sim.Body.sphere(0.1, 1.0)]

    def make(backend):
        ground = sim.Ground(0.5, 0.4)
        return sim.Scene(
            bodies, DT, integrator=integrator, gravity=gravity, ground=ground, backend=backend
        )

    numpy_scene, compiled_scene = make("numpy"), make("compiled")
    state = numpy_scene.initial_state(
        position=[(0, 0, 2.0), (0, 0, 0.5), (0.5, 0, 0.3)],
        linear_velocity=[(0, 0, -1), (0.5, 0, -3), (0, 0.3, -2)],
        angular_velocity=[(1, 2, 3), (2, 1, 0), (0, 0, 1)],
    )
    impacts = 0
    for _ in range(120):
        ref, out = numpy_scene.step(state), compiled_scene.step(state)
        a, b = numpy_scene.report["contacts"], compiled_scene.report["contacts"]
        assert (b.engaged, b.impacts, b.capped) == (a.engaged, a.impacts, a.capped)
        bound = step_bound(TOLERANCE, max(a.iterations, b.iterations))
        for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
            assert np.max(np.abs(getattr(out, field) - getattr(ref, field))) <= bound
        impacts += a.impacts
        state = ref
    assert impacts > 0


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_threaded_contact_step_equals_serial_bit_for_bit():
    serial, state = scenes("compiled", sim.SolverSettings())["8 tumbling boxes"]
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


WARM_CALL = 4  # steps per call in the warm-start comparison


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
@pytest.mark.parametrize("name", list(scenes("numpy", sim.SolverSettings())))
def test_compiled_warm_start_matches_numpy_call_by_call(name):
    # SolverSettings(warm_start=True): a call's steps after its first start their solve from
    # the previous step's impulses, on both backends (contact slot i is the same vertex).
    # Each call of WARM_CALL steps starts from numpy's state. Within it each step adds at most
    # step_bound (both solves converge to the tolerance from starts that differ by what the
    # earlier steps left), and the dynamics at most double a difference over WARM_CALL steps
    # (the tumbling box's doubling takes a few steps, module docstring): 2 WARM_CALL
    # step_bound, with the sweeps of the call's slowest step.
    settings = sim.SolverSettings(warm_start=True)
    numpy_scene, state = scenes("numpy", settings)[name]
    compiled_scene, _ = scenes("compiled", settings)[name]
    assert compiled_scene.backend == "compiled"
    engaged = split_caps = loose = 0
    for _ in range(STEPS // WARM_CALL):
        ref = numpy_scene.step(state, steps=WARM_CALL)
        out = compiled_scene.step(state, steps=WARM_CALL)
        a, b = numpy_scene.report["contacts"], compiled_scene.report["contacts"]
        assert (b.engaged, b.impacts, b.warm_started) == (a.engaged, a.impacts, a.warm_started)
        split_caps += b.capped != a.capped  # as in the step-by-step test
        sweeps = max(a.iterations, b.iterations)
        bound = (
            np.inf
            if a.capped or b.capped
            else 2
            * WARM_CALL
            * (step_bound(settings.tolerance, sweeps) + impacts_bound(settings, a.impacts))
        )
        loose += check_fields(out, ref, a, b, bound)
        engaged += a.engaged > 0
        state = ref
    assert engaged > 0
    # A call splits, or needs the looser bound, when one of its steps does: the share per step.
    assert split_caps <= 0.01 * STEPS
    assert loose <= POLISHED_SHARE * STEPS


def test_compiled_detection_keeps_numpy_contacts():
    """The compiled detection orders a box's corners by R's third row (no per-element scratch)
    where numpy orders its rotated corners' heights: the same K lowest, in vertex order, with
    numpy's arms and gaps to rounding (4 ε of the box's size), for generic orientations and for
    those where corners tie (faces and edges level: every multiple of 45° about x, then y)."""
    from numba import njit

    from rigid_env.sim.compiled import layout
    from rigid_env.sim.compiled.ground import detect, ground_data
    from rigid_env.sim.contacts.ground import GroundContacts

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
    arm, gap = GroundContacts([body]).detect(x0, q0)
    size = 4 * np.finfo(float).eps * 0.5
    np.testing.assert_allclose(contact[:, :, layout.ARM : layout.ARM + 3], arm[:, 0], atol=size)
    np.testing.assert_allclose(contact[:, :, layout.GAP], gap[:, 0], atol=size)
