"""Per-element model parameters (``Scene.parameters``, ``rigid_env.sim.parameters``).

The law: batch element e stepped with row e of the parameters is, bit for bit, the same state
stepped on a scene built with row e's bodies and ground. Every such scene is pinned by the rest
of the suite (closed forms, conservation laws), so equality carries those laws over to every
row; a wrong row (an index off by one, a row that kept the scene's mass in one kernel's data)
breaks the equality. A closed form on top: the stopping distance of a box sliding on the
ground follows each element's own friction.
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.rotation import quat_exp

GRAVITY = (0.0, 0.0, -9.81)
BOX = sim.Body.box((0.1, 0.15, 0.2), 1.0)
# A body whose inertia is not diagonal: its principal frame is its own per row.
TILTED = sim.Body(2.0, [[2.0, 0.1, 0.0], [0.1, 2.5, 0.2], [0.0, 0.2, 3.0]])


def landing(body=BOX, friction=0.5, restitution=0.3, backend="compiled", dt=0.01):
    return sim.Scene(
        body,
        dt,
        gravity=GRAVITY,
        ground=sim.Ground(restitution=restitution, friction=friction),
        backend=backend,
    )


def drawn(rng, rows, body=BOX):
    """Random masses (×0.5-2), inertias (mass × inertia scale), friction and restitution."""
    mass = rng.uniform(0.5, 2.0, (rows, 1)) * body.mass
    scale = rng.uniform(0.5, 2.0, (rows, 1, 1, 1))
    return dict(
        mass=mass,
        inertia=body.inertia[None, None] * scale * (mass / body.mass)[..., None, None],
        friction=rng.uniform(0.0, 1.0, rows),
        restitution=rng.uniform(0.0, 0.9, rows),
    )


def thrown(scene, rng, rows):
    return scene.initial_state(
        position=(0.0, 0.0, 0.4),
        orientation=quat_exp(rng.uniform(-0.5, 0.5, (rows, 1, 3))),
        linear_velocity=rng.uniform(-1.0, 1.0, (rows, 1, 3)),
        angular_velocity=rng.uniform(-3.0, 3.0, (rows, 1, 3)),
        batch_shape=(rows,),
    )


def same(a: sim.State, b: sim.State, e: int) -> bool:
    return all(np.array_equal(x[e : e + 1], y) for x, y in zip(a.arrays(), b.arrays(), strict=True))


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
@pytest.mark.parametrize("steps", [1, 4])
def test_each_landing_element_is_its_own_scene_bit_for_bit(steps):
    """Thrown boxes through flight, impacts and rest, with torque; one call of ``steps``."""
    rng = np.random.default_rng(0)
    rows = 6
    values = drawn(rng, rows)
    scene = landing()
    params = scene.parameters(**values)
    start = thrown(scene, rng, rows)
    torque = rng.uniform(-0.5, 0.5, (rows, 1, 3))
    state = start
    for _ in range(60 // steps):
        state = scene.step(state, body_torque=torque, steps=steps, parameters=params)
    for e in range(rows):
        body = sim.Body(values["mass"][e, 0], values["inertia"][e, 0], BOX.shape)
        own = landing(body, values["friction"][e], values["restitution"][e])
        alone = start[e : e + 1]
        for _ in range(60 // steps):
            alone = own.step(alone, body_torque=torque[e : e + 1], steps=steps)
        assert same(state, alone, e), e


@pytest.mark.parametrize("integrator", ["splitting", "rk4", "exact", "implicit"])
def test_each_free_body_element_is_its_own_scene_bit_for_bit(integrator):
    """A body with a non-diagonal inertia, under damping and a spring: the integrator's body
    table (principal frame, moments), the damping's and the spring's data, per row."""
    rng = np.random.default_rng(1)
    rows = 4
    spring = sim.Spring(0, (0.0, 0.0, 1.0), 20.0, 0.5, attach=(0.1, 0.0, 0.0))

    def make(body):
        return sim.Scene(
            body,
            0.01,
            integrator=integrator,
            gravity=GRAVITY,
            springs=[spring],
            linear_damping=0.1,
            angular_damping=0.2,
            backend="compiled",
        )

    scene = make(TILTED)
    mass = rng.uniform(0.5, 2.0, (rows, 1)) * TILTED.mass
    turn = sim.rotation.quat_to_matrix(quat_exp(rng.uniform(-1, 1, (rows, 1, 3))))
    inertia = (
        turn @ TILTED.inertia @ np.swapaxes(turn, -1, -2) * rng.uniform(0.5, 2, (rows, 1, 1, 1))
    )
    params = scene.parameters(mass=mass, inertia=inertia)
    start = scene.initial_state(angular_velocity=rng.normal(size=(rows, 1, 3)), batch_shape=(rows,))
    state = scene.step(start, steps=50, parameters=params)
    for e in range(rows):
        own = make(sim.Body(mass[e, 0], inertia[e, 0]))
        assert same(state, own.step(start[e : e + 1], steps=50), e), e


def test_one_row_serves_every_element():
    rng = np.random.default_rng(2)
    values = drawn(rng, 1)
    scene = landing()
    start = thrown(scene, rng, 5)
    body = sim.Body(values["mass"][0, 0], values["inertia"][0, 0], BOX.shape)
    own = landing(body, values["friction"][0], values["restitution"][0])
    got = scene.step(start, steps=30, parameters=scene.parameters(**values))
    want = own.step(start, steps=30)
    assert all(np.array_equal(a, b) for a, b in zip(got.arrays(), want.arrays(), strict=True))


def test_one_row_updated_between_steps_steps_with_its_new_values():
    """The driver takes a one-row parameter set's row once and keeps it: an update between two
    steps must reach the next step (the row is views of the arrays ``update`` writes into)."""
    rng = np.random.default_rng(3)
    values, other = drawn(rng, 1), drawn(rng, 1)
    scene = landing()
    start = thrown(scene, rng, 3)
    params = scene.parameters(**values)
    scene.step(start, steps=2, parameters=params)  # the row is taken here
    params.update(np.array([0]), **other)
    body = sim.Body(other["mass"][0, 0], other["inertia"][0, 0], BOX.shape)
    own = landing(body, other["friction"][0], other["restitution"][0])
    got = scene.step(start, steps=30, parameters=params)
    want = own.step(start, steps=30)
    assert all(np.array_equal(a, b) for a, b in zip(got.arrays(), want.arrays(), strict=True))


def test_over_threads_the_bits_of_the_serial_step():
    rng = np.random.default_rng(3)
    rows = 7
    values = drawn(rng, rows)
    serial = landing()
    threads = landing(backend="compiled-threads")
    start = thrown(serial, rng, rows)
    a = serial.step(start, steps=20, parameters=serial.parameters(**values))
    b = threads.step(start, steps=20, parameters=threads.parameters(**values))
    assert all(np.array_equal(x, y) for x, y in zip(a.arrays(), b.arrays(), strict=True))


def test_each_element_slides_its_own_friction_distance():
    """A box resting flat, sent sliding at v0: Coulomb friction μ m g decelerates it, so it
    stops after d = v0² / (2 μ g). The semi-implicit step with the contact solve stores step
    means; the discrete stop differs from the closed form by at most one step's travel,
    v0 Δt, so that is the tolerance. (μ below 0.5, the half width over the half height of
    the face it rests on: above it the friction tips the box over.)"""
    friction = np.array([0.1, 0.25, 0.45])
    v0, dt, g = 1.0, 0.005, 9.81
    scene = landing(friction=0.5, restitution=0.0, dt=dt)
    params = scene.parameters(friction=friction)
    half = BOX.shape.half_extents[2]
    start = scene.initial_state(
        position=(0.0, 0.0, half), linear_velocity=(v0, 0.0, 0.0), batch_shape=(3,)
    )
    state = scene.step(start, steps=int(1.5 / dt), parameters=params)
    distance = state.position[:, 0, 0]
    assert np.allclose(distance, v0**2 / (2 * friction * g), rtol=0, atol=v0 * dt)
    assert np.all(np.abs(state.linear_velocity[:, 0, :2]) < 1e-9)  # stopped, each of them


def test_update_sets_rows_as_a_fresh_build_would():
    rng = np.random.default_rng(4)
    rows = 4
    values = drawn(rng, rows)
    other = drawn(rng, 2)
    scene = landing()
    params = scene.parameters(**values)
    params.update(np.array([3, 1]), **other)
    for name in other:
        values[name][[3, 1]] = other[name]
    fresh = scene.parameters(**values)
    for name in values:
        assert np.array_equal(getattr(params, name), values[name])
    start = thrown(scene, rng, rows)
    a = scene.step(start, steps=30, parameters=params)
    b = scene.step(start, steps=30, parameters=fresh)
    assert all(np.array_equal(x, y) for x, y in zip(a.arrays(), b.arrays(), strict=True))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(mass=np.ones((3, 1, 1))), "mass must have shape"),
        (dict(mass=np.ones((3, 2))), "mass must have shape"),
        (dict(inertia=np.ones((2, 1, 3))), "inertia must have shape"),
        (dict(mass=np.ones((3, 1)), friction=np.ones(2)), "row counts differ"),
        (dict(mass=np.array([[1.0], [-1.0]])), "row 1: mass"),
        (dict(mass=np.array([[1.0], [np.nan]])), "row 1: mass"),
        (dict(inertia=np.tile(np.diag([1.0, 1.0, 3.0]), (1, 1, 1, 1))), "row 0: inertia"),
        (dict(friction=np.array([-0.1])), "row 0: friction"),
        (dict(restitution=np.array([0.5, 1.5])), "row 1: restitution"),
        (dict(friction=0.3), "friction must have a leading axis"),
        (dict(mass=np.ones((0, 1))), "at least one row"),
        (dict(mass="heavy"), "mass"),
    ],
)
def test_bad_parameters_are_refused_naming_the_array(kwargs, match):
    with pytest.raises(ValueError, match=match):
        landing().parameters(**kwargs)


def test_a_step_refuses_parameters_it_cannot_take_and_then_steps():
    scene = landing()
    start = thrown(scene, np.random.default_rng(5), 3)
    copy = [a.copy() for a in start.arrays()]
    with pytest.raises(ValueError, match="3 elements"):
        scene.step(start, parameters=scene.parameters(mass=np.ones((2, 1))))
    with pytest.raises(ValueError, match="this scene's parameters"):
        scene.step(start, parameters=landing().parameters(mass=np.ones((3, 1))))
    with pytest.raises(ValueError, match="parameters must come"):
        scene.step(start, parameters={"mass": np.ones((3, 1))})
    with pytest.raises(ValueError, match="no ground"):
        sim.Scene(BOX, 0.01, backend="compiled").parameters(friction=np.ones(1))
    assert all(np.array_equal(a, b) for a, b in zip(start.arrays(), copy, strict=True))
    scene.step(start, parameters=scene.parameters(mass=np.ones((3, 1))))  # the next call works


def test_a_bad_update_changes_nothing():
    rng = np.random.default_rng(6)
    values = drawn(rng, 3)
    scene = landing()
    params = scene.parameters(**values)
    data = [a.copy() for a in _leaves(params.data)]
    with pytest.raises(ValueError, match="row 2: mass"):
        params.update(np.array([0, 2]), mass=np.array([[1.0], [0.0]]))
    with pytest.raises(ValueError, match="index out of range"):
        params.update(np.array([3]), mass=np.ones((1, 1)))
    with pytest.raises(ValueError, match="mass must have shape"):
        params.update(np.array([0]), mass=np.ones((2, 1)))
    assert all(np.array_equal(a, b) for a, b in zip(_leaves(params.data), data, strict=True))
    assert np.array_equal(params.mass, values["mass"])
    params.update(np.array([2]), mass=np.array([[1.5]]))  # and the next valid update works
    assert params.mass[2, 0] == 1.5


def _leaves(data):
    if isinstance(data, tuple):
        return [leaf for d in data for leaf in _leaves(d)]
    return [] if data is None else [data]


def test_a_one_body_scene_takes_masses_and_inertias_without_the_body_axis():
    scene = landing()
    rng = np.random.default_rng(7)
    values = drawn(rng, 3)
    flat = scene.parameters(mass=values["mass"][:, 0], inertia=values["inertia"][:, 0])
    full = scene.parameters(mass=values["mass"], inertia=values["inertia"])
    assert np.array_equal(flat.mass, full.mass) and np.array_equal(flat.inertia, full.inertia)
    two = sim.Scene([BOX, BOX], 0.01, backend="compiled")  # two bodies: the axis is needed
    with pytest.raises(ValueError, match="mass must have shape"):
        two.parameters(mass=np.ones(3))
