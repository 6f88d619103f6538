"""The compiled step's machinery: ground detection, determinism, backend selection, the
driver's choice of step and kernels, kernel data and types, the packed layouts."""

import importlib

import numba
import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.compiled import backend as compiled_backend
from rigid_env.sim.compiled import ground as compiled_ground
from rigid_env.sim.compiled import layout
from rigid_env.sim.contacts import GroundContacts
from rigid_env.sim.rotation import quat_rotate, random_quaternions
from rigid_env.sim.scenes import landing_scene


def lopsided_body():
    """A body whose axes are not principal: exercises the principal-frame rotations."""
    inertia = np.array([[0.2, 0.01, 0.02], [0.01, 0.3, 0.0], [0.02, 0.0, 0.4]])
    return sim.Body(2.0, inertia)


def spring():
    return sim.Spring(0, (0.0, 0.0, 1.0), 10.0, 0.5, 0.3, (0.1, 0.0, 0.0))


ALL_FORCES = dict(
    gravity=(0.0, 0.0, -9.81), linear_damping=0.1, angular_damping=0.2, springs=[spring()]
)


def random_state(scene, batch, seed=0):
    rng = np.random.default_rng(seed)
    n = scene.n_bodies
    return scene.initial_state(
        position=rng.normal(0, 0.3, (batch, n, 3)),
        orientation=random_quaternions(rng, (batch, n)),
        linear_velocity=rng.normal(0, 1, (batch, n, 3)),
        angular_velocity=rng.normal(0, 3, (batch, n, 3)),
    )


def hexagonal_prism():
    """12 vertices: more than the 8 a polyhedron offers the ground, so the kernel selects."""
    angles = np.arange(6) * np.pi / 3
    ring = np.stack((0.2 * np.cos(angles), 0.2 * np.sin(angles)), axis=-1)
    vertices = np.concatenate((np.c_[ring, np.full(6, -0.1)], np.c_[ring, np.full(6, 0.1)]), axis=0)
    faces = [tuple(range(5, -1, -1)), tuple(range(6, 12))]
    faces += [(i, (i + 1) % 6, (i + 1) % 6 + 6, i + 6) for i in range(6)]
    return sim.Body.polyhedron(vertices, faces, 1000.0)


def test_ground_detection_takes_each_bodys_k_lowest_points():
    """Boxes, spheres and a 12-vertex polyhedron at random poses: each body's K lowest
    candidate points (arms and gaps), against the points rotated here one by one (one
    rotation, c ≈ 10 ulp); in ascending vertex order, ties to the lower index."""
    bodies = [sim.Body.box((0.1, 0.2, 0.3), 1.0), sim.Body.sphere(0.15, 1.0), hexagonal_prism()]
    rng = np.random.default_rng(1)
    batch, n = 16, len(bodies)
    x = rng.normal(0, 0.5, (batch, n, 3))
    q = random_quaternions(rng, (batch, n))
    ground = GroundContacts(bodies)
    data = compiled_ground.ground_data(bodies)
    k = int(data[3][0])
    contact = np.zeros((batch, n * k, layout.CONTACT_WIDTH))
    st = [np.zeros((batch, n, 3)) for _ in range(layout.STEP_TUPLE_SIZE)]
    st[layout.X0], st[layout.Q0], st[layout.CONTACT] = x, q, contact
    st[layout.REPORT] = np.zeros((batch, layout.REPORT_WIDTH))
    st = tuple(st)
    for e in range(batch):
        compiled_ground.detect(e, st, data)
    got_arm = contact[..., layout.ARM : layout.ARM + 3].reshape(batch, n, k, 3)
    got_gap = contact[..., layout.GAP].reshape(batch, n, k)
    assert np.array_equal(contact[..., layout.BODY].reshape(batch, n, k)[0, :, 0], np.arange(n))
    for e in range(batch):
        for g in range(n):
            arm = quat_rotate(q[e, g], ground.points[g]) + ground.foot[g, 0]
            gap = x[e, g, 2] + arm[:, 2]
            lowest = np.sort(np.argsort(gap, kind="stable")[:k])
            np.testing.assert_allclose(got_gap[e, g], gap[lowest], rtol=0, atol=1e-15)
            np.testing.assert_allclose(got_arm[e, g], arm[lowest], rtol=0, atol=1e-15)


@pytest.mark.parametrize("backend", ["compiled", "compiled-threads"])
def test_batch_equals_single_bitwise(backend):
    """Each element of a batch steps exactly as it does alone (and threads change no bit)."""
    scene = sim.Scene(
        [lopsided_body(), sim.Body.box((0.1, 0.2, 0.3), 1.0)],
        0.01,
        integrator="rk4",
        backend=backend,
        **ALL_FORCES,
    )
    state = random_state(scene, 7, seed=3)
    torque = np.random.default_rng(4).normal(0, 0.5, (7, 2, 3))
    batched = state
    for _ in range(10):
        batched = scene.step(batched, torque=torque)
    for i in range(7):
        single = state[i]
        for _ in range(10):
            single = scene.step(single, torque=torque[i])
        for got, want in zip(single.arrays(), batched[i].arrays(), strict=True):
            assert np.array_equal(got, want)


def test_the_compiled_step_leaves_its_input_alone_and_shares_no_memory():
    scene = sim.Scene(lopsided_body(), 0.01, backend="compiled", **ALL_FORCES)
    state = random_state(scene, 3)
    before = state.copy()
    new = scene.step(state)
    for a, b, c in zip(state.arrays(), before.arrays(), new.arrays(), strict=True):
        assert np.array_equal(a, b)
        assert not np.shares_memory(a, c)


def test_backend_selection(monkeypatch):
    """``compiled`` by default; the numpy step and ``auto`` are gone, and say so."""
    body = sim.Body.box((0.1, 0.2, 0.3), 1.0)
    monkeypatch.delenv("RIGID_ENV_BACKEND", raising=False)
    assert sim.Scene(body, 0.01).backend == "compiled"
    assert sim.Scene(body, 0.01, backend="compiled-threads").backend == "compiled"
    for removed in ("numpy", "auto"):
        with pytest.raises(ValueError, match="numpy step was removed"):
            sim.Scene(body, 0.01, backend=removed)
    monkeypatch.setenv("RIGID_ENV_BACKEND", "fast")
    with pytest.raises(ValueError, match="RIGID_ENV_BACKEND"):
        sim.Scene(body, 0.01)
    with pytest.raises(ValueError, match="backend"):
        sim.Scene(body, 0.01, backend="fortran")


def test_body_body_scenes_without_a_ground_step_compiled():
    """Every scene the Scene accepts has kernels: two spheres in space, without a ground."""
    balls = [sim.Body.sphere(0.1, 1.0), sim.Body.sphere(0.1, 1.0)]
    assert sim.Scene(balls, 0.01, contacts=sim.Material()).backend == "compiled"


def test_composition_picks_the_step_the_integrator_and_the_force_slots():
    """The driver picks ``free_step`` or ``contact_step`` from the composition; the scene's
    integrator tag names its kernels; the force data holds each term the scene has and None
    for the others (which compile away); equal compositions share one compiled overload."""
    from rigid_env.sim.compiled import forces, registry, steps

    a = sim.Scene(lopsided_body(), 0.01, integrator="euler", backend="compiled", **ALL_FORCES)
    b = sim.Scene(lopsided_body(), 0.02, integrator="euler", backend="compiled", **ALL_FORCES)
    free = sim.Scene(lopsided_body(), 0.01, integrator="euler", backend="compiled")
    landing, _ = landing_scene(dt=0.01)
    assert a._driver.step is free._driver.step is steps.free_step
    assert landing._driver.step is steps.contact_step
    euler = registry.INTEGRATORS["euler"]
    assert type(a._driver.integrator) is euler.tag
    assert [k.name for k in a._driver.kernels] == ["euler_velocity", "euler_position"]
    assert [fd is None for fd in a._driver.data[0][1]] == [False, False, False]
    assert free._driver.data[0][1] == (None, None, None)
    gravity_only = landing._driver.data[0][1]
    assert forces.TERMS[0] == "gravity" and [fd is None for fd in gravity_only] == [
        False,
        True,
        True,
    ]
    # Nothing is called by address in a free body's step: it takes no addresses at all.
    assert free._driver.addresses is None and not free._driver._callees
    for scene in (a, b, free):
        scene.step(scene.initial_state(angular_velocity=(1.0, 2.0, 3.0)))
    assert a._driver.signature == b._driver.signature != free._driver.signature
    entry = a._driver._entries[False]
    assert entry is not None and entry == b._driver._entries[False]


def test_a_step_with_an_unknown_sequence_of_kernels_is_refused():
    """The two steps run fixed sequences: kernels in another order are a ``ValueError`` when
    the driver is built, never a step that silently skips or reorders a stage."""
    from rigid_env.sim.compiled.driver import Driver

    landing, _ = landing_scene(dt=0.01)
    kernels, forces = landing._driver.kernels, landing._driver.forces
    swapped = (kernels[0], kernels[2], kernels[1], *kernels[3:])
    with pytest.raises(ValueError, match="contact step runs"):
        Driver(swapped, forces)
    with pytest.raises(ValueError, match="semi-implicit"):
        Driver(kernels[1:], forces)


def test_compiled_kernels_call_lapack_only_if_scipy_is_a_core_dependency():
    """numba's np.linalg calls LAPACK through scipy: a compiled kernel using it fails to compile
    ("scipy 0.16+ is required for linear algebra") on an install without scipy, which the rl
    extra (the README's first command) does not bring. The kernels call none today
    (``compiled.min_norm`` replaced ``pinv``), so scipy is no core dependency; adding an
    np.linalg call to a kernel must bring it back."""
    from importlib import metadata
    from pathlib import Path

    sources = Path(compiled_backend.__file__).parent.glob("*.py")
    calls_lapack = [p.name for p in sources if "np.linalg" in p.read_text()]
    core = [r for r in metadata.requires("rigid-env") or [] if "extra ==" not in r]
    scipy_core = any(r.replace(" ", "").lower().startswith("scipy") for r in core)
    assert scipy_core or not calls_lapack, (calls_lapack, core)


def test_landing_kernels_get_their_data_from_one_shared_copy(monkeypatch):
    """The landing step takes three data tuples: the integrator's (with the force data), the
    ground detection's and the contact data every other contact kernel was built with; each
    kernel gets its own, passed once (numba unboxes every array of an argument per call)."""
    monkeypatch.setenv("RIGID_ENV_BACKEND", "compiled")
    scene, _ = landing_scene(dt=0.01)
    drv = scene._driver
    idata, ground, shared = drv.data

    def same(a, b):  # the same nesting, dtypes, shapes and bits (-0.0 is not 0.0)
        if isinstance(a, tuple) or a is None:
            return type(a) is type(b) and (a is None or len(a) == len(b) and all(map(same, a, b)))
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()

    for kernel in drv.kernels:
        if kernel.tag is not None:  # the integrator's halves: equal data, built twice
            assert same(kernel.data, idata[0])
        else:
            assert same(kernel.data, ground if kernel.name == "detect" else shared)
    assert not same(ground, shared)
    assert same(idata[1], (*(f.data for f in drv.forces), None, None))


def test_kernels_called_by_address_get_the_types_they_were_compiled_for(monkeypatch):
    """The step calls the contact kernels through their addresses (``calls``), passing the
    step tuple by reference: each was compiled for ``calls.signature(data)``, so the tuple the
    step builds must have the type ``calls.step_tuple_type`` declares (a pointer call with
    other types would read the wrong memory), and each kernel's data the type of its own."""
    from rigid_env.sim.compiled import calls, steps
    from rigid_env.sim.compiled.driver import CONTACT_KERNELS

    monkeypatch.setenv("RIGID_ENV_BACKEND", "compiled")
    scene, initial = landing_scene(dt=0.01)
    scene.step(initial(batch_shape=(2,)))
    drv = scene._driver
    # The step's own typing of ``st`` (a cached overload keeps no type map: compile a copy).
    fresh = numba.njit(steps.contact_step.py_func)
    fresh.compile(drv.signature)
    typemap = fresh.overloads[drv.signature].type_annotation.typemap
    assert typemap["st"] == calls.step_tuple_type()
    assert typemap["ref"] == calls.StepRef(calls.step_tuple_type())
    assert len(drv._callees) == 6 and sorted(CONTACT_KERNELS[k.name] for k, _ in drv._callees) == [
        steps.GROUND,
        steps.ASSEMBLE,
        steps.RESTITUTE,
        steps.SOLVE,
        steps.LIMIT,
        steps.SEPARATE,
    ]
    # Every kernel's address is where the step reads it; no body–body pairs, no address.
    assert drv.addresses[steps.PAIRS] == 0
    assert all(drv.addresses[CONTACT_KERNELS[k.name]] != 0 for k, _ in drv._callees)
    _, ground, shared = drv.data  # what the step passes them
    for kernel, data in drv._callees:
        function = getattr(importlib.import_module(kernel.module), kernel.name)
        assert data is (ground if kernel.name == "detect" else shared)
        assert calls.signature(data) in function.overloads


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_a_report_read_late_is_the_last_steps_report(monkeypatch):
    """The compiled report is built when read, from the last step's columns: a scene read after
    every step and one read only now and then agree at every read, and a read twice is the
    same dict."""
    monkeypatch.setenv("RIGID_ENV_BACKEND", "compiled")
    eager, initial = landing_scene(dt=0.01)
    lazy, _ = landing_scene(dt=0.01)
    assert eager.backend == lazy.backend == "compiled"
    a = b = initial(batch_shape=(3,), rng=np.random.default_rng(2))
    seen = set()
    for k in range(90):
        a, b = eager.step(a), lazy.step(b)
        want = eager.report["contacts"]
        if k % 7 == 3:
            got = lazy.report["contacts"]
            assert lazy.report is lazy.report
            assert vars(got).keys() == vars(want).keys()
            for key, value in vars(want).items():
                assert np.array_equal(getattr(got, key), value), key
            seen.add((want.engaged, want.impacts > 0))
    assert (0, False) in seen and any(engaged for engaged, _ in seen)  # before and on the ground


@pytest.mark.parametrize("integrator", ["splitting", "splitting4"])
def test_splitting_takes_its_damped_template_only_with_velocity_dependent_forces(integrator):
    """Without velocity-dependent forces the plain kernel closes with an explicit half kick
    (and calls nothing that can raise: ``integrators.free_rotation``); with damping the scene
    must get the ``_damped`` one, whose implicit half kick takes the damping matrices."""

    def kernels(**terms):
        scene = sim.Scene(lopsided_body(), 0.01, integrator=integrator, backend="compiled", **terms)
        return [k.name for k in scene._driver.kernels]

    assert kernels(gravity=(0.0, 0.0, -9.81)) == [integrator]
    assert kernels(linear_damping=0.3, angular_damping=0.5) == [integrator + "_damped"]


@pytest.mark.parametrize("fields", ["CONTACT_COLUMNS", "REPORT_COLUMNS"])
def test_each_packed_column_is_where_its_declaration_puts_it(fields):
    """The names bound in ``layout`` are the declared fields, in order, at the derived starts:
    a field inserted or swapped in one place and not the other fails here."""
    declared = getattr(layout, fields)
    starts = layout.columns(declared)
    assert [getattr(layout, name) for name, _ in declared] == list(starts[:-1])
    width = "CONTACT_WIDTH" if fields == "CONTACT_COLUMNS" else "REPORT_WIDTH"
    assert getattr(layout, width) == starts[-1] == sum(w for _, w in declared)
    assert starts[-1] == (75 if fields == "CONTACT_COLUMNS" else 12)
    if fields == "CONTACT_COLUMNS":  # a ground scene's slots stop before the body–body columns
        assert layout.GROUND_WIDTH == layout.NORMAL == 42


def test_contact_data_blocks_start_where_the_kernels_read_them():
    """Each block of the contact kernels' data sits where ``offsets`` (the kernels' reader)
    says, holding what the scene gave it."""
    from rigid_env.sim.compiled import contact_assembly as ca
    from rigid_env.sim.contacts.stages import AssembleContacts

    scene = sim.Scene(
        [sim.Body.box((0.1, 0.15, 0.2), 1.0), sim.Body.sphere(0.1, 2.0)],
        0.01,
        gravity=(0.0, 0.0, -9.81),
        ground=sim.Ground(restitution=0.3, friction=0.5),
        springs=[spring()],
        backend="compiled",
    )
    ints, floats, _ = ca.contact_data(scene)
    o = ca.offsets.py_func(ints)
    lay = next(s for s in scene.pipeline if isinstance(s, AssembleContacts)).layout
    c, n, g = len(lay.a), scene.n_bodies, ints[ca.I_GROUND]
    np.testing.assert_array_equal(ints[o[ca.O_OWNER] : o[ca.O_OWNER] + c], lay.a)
    np.testing.assert_array_equal(ints[o[ca.O_SHAPED] : o[ca.O_SHAPED] + g], [0, 1])
    expected = {
        ca.O_MU: lay.mu,
        ca.O_EPS: lay.eps,
        ca.O_THRESHOLD: lay.threshold,
        ca.O_MASS: scene.model.mass,
        ca.O_RIM: lay.root_inv_mass,
        ca.O_L: lay.root_inv_inertia.reshape(-1),
        ca.O_LINV: lay.root_inertia.reshape(-1),
    }
    for block, values in expected.items():
        np.testing.assert_array_equal(floats[o[block] : o[block] + len(values)], values)
    assert o[ca.O_L] - o[ca.O_RIM] == n and o[ca.O_LINV] - o[ca.O_L] == 9 * n
    assert floats[ca.F_DT] == 0.01
    np.testing.assert_array_equal(floats[ca.F_GRAVITY : ca.F_GRAVITY + 3], (0.0, 0.0, -9.81))
    assert o[ca.O_SHAPES] - o[ca.O_SPRINGS] == ca.spring_table(scene.model).size
    np.testing.assert_array_equal(ints[o[ca.O_OWNER_B] : o[ca.O_OWNER_B] + c], lay.b)
    np.testing.assert_array_equal(floats[o[ca.O_SPIN] : o[ca.O_SPIN] + n], lay.spin)
    bounds = [ca.bounding_radius(b.shape) for b in scene.model.bodies]
    np.testing.assert_array_equal(floats[o[ca.O_BOUND] : o[ca.O_BOUND] + n], bounds)
    assert o[ca.O_BOUND] + n == len(floats)  # the last float block


_PAIR_CODE_PROBE = """
import numba, numpy as np
from rigid_env.sim.scenes import landing_scene
from rigid_env.sim.compiled import contact_assembly as ca, contact_energy as ce
from rigid_env.sim.compiled import contact_solve as cs
scene, initial = landing_scene(dt=0.01)
ints, floats, pairs = ca.contact_data(scene)
assert pairs is None
o = ca.offsets(ints)
n, c = int(ints[ca.I_N]), int(ints[ca.I_C])
st = tuple(np.zeros((1, max(n, c), 64)) for _ in range(14))
st = st[:12] + (np.zeros((1, 16)),) + st[13:]
x, q, u = np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 6))
owner = np.zeros(c, np.int64)
fresh = numba.njit  # uncached copies: numba types them (and reaches their callees) here
marker = None if {none} else np.array([1], np.int64)
fresh(ca.assemble_pairs.py_func)(marker, 0, st, ints, floats, o, False)
if {none}:  # (with a marker these would compile the box-box detection: seconds)
    fresh(ce.separated_end_potential.py_func)(marker, st, 0, ints, floats, o, 0.0, 0.0)
    fresh(ce.separate_pairs.py_func)(marker, ints, floats, o, x, q)
fresh(cs.reassemble_pairs.py_func)(marker, 0, st, ints, floats, o, owner, owner - 1, u)
print(len(ca.assemble_pair.signatures), len(ce.separated.signatures))
"""


@pytest.mark.parametrize("none", [True, False])
def test_a_ground_scene_compiles_no_pair_code(none):
    """The contact data's ``pairs`` is None in a scene without body–body contacts, and the pair
    parts of the kernels then reach no pair function: numba drops their branches before
    typing (``contact_assembly.PAIRS``). With a marker, the same call reaches its pair
    function: the check sees callees."""
    import subprocess
    import sys

    if numba.config.DISABLE_JIT:
        pytest.skip("nothing is typed with numba's JIT disabled")
    out = subprocess.run(
        [sys.executable, "-c", _PAIR_CODE_PROBE.replace("{none}", str(none))],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assigned, separated = int(out[-2]), int(out[-1])
    if none:
        assert (assigned, separated) == (0, 0)
    else:
        assert assigned > 0
