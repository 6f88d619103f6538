"""Scene composition, state helpers, and every bad input of the core contract."""

import numpy as np
import pytest

from rigid_env import sim


def box():
    return sim.Body.box((0.1, 0.2, 0.3), 2.0)


# --- composition: a scene runs only the stages it was given ------------------------------------


def test_free_body_runs_only_the_integrator():
    assert sim.Scene(box(), 0.01).stages == ("integrate",)
    # A zero gravity vector is no gravity: nothing to compute.
    assert sim.Scene(box(), 0.01, gravity=(0, 0, 0)).stages == ("integrate",)
    # A semi-implicit integrator contributes its two parts, nothing else.
    scene = sim.Scene(box(), 0.01, integrator="implicit_gyro")
    assert scene.stages == ("integrate_velocity", "integrate_position")


def test_stages_follow_the_terms_given():
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=10.0)
    scene = sim.Scene(box(), 0.01, gravity=(0, 0, -9.81), springs=[spring], linear_damping=0.1)
    assert scene.stages == ("gravity", "damping", "springs", "integrate")
    assert scene.stages == tuple(stage.name for stage in scene.pipeline)
    assert all(isinstance(stage, sim.pipeline.Stage) for stage in scene.pipeline)


def test_contacts_sit_between_the_velocity_and_position_updates():
    scene = sim.Scene(box(), 0.01, gravity=(0, 0, -9.81), ground=sim.Ground())
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


def test_free_body_pays_nothing_for_forces_or_contacts(monkeypatch):
    """The free-body step builds and calls no force term and no contact code (tripwires)."""
    from rigid_env.sim import contacts, forces

    def tripwire(*args, **kwargs):
        raise AssertionError("force or contact code ran for a free body")

    for cls in (forces.Gravity, forces.Damping, forces.Springs):
        for method in ("__init__", "__call__", "wrench"):
            monkeypatch.setattr(cls, method, tripwire)
    for cls in (contacts.GroundContacts, contacts.PairContacts, contacts.Layout):
        monkeypatch.setattr(cls, "__init__", tripwire)
    for name in sim.INTEGRATORS:
        scene = sim.Scene([box(), box()], 0.01, integrator=name)
        scene.step(scene.initial_state(angular_velocity=(1, 2, 3)), torque=(0.1, 0, 0))
    # The tripwires are live: a scene with gravity trips them.
    with pytest.raises(AssertionError, match="free body"):
        sim.Scene(box(), 0.01, gravity=(0, 0, -9.81))


# --- states ---------------------------------------------------------------------------------------


def test_initial_state_defaults_and_batching():
    scene = sim.Scene([box(), box()], 0.01)
    state = scene.initial_state(batch_shape=(4, 3))
    assert state.position.shape == (4, 3, 2, 3)
    assert state.orientation.shape == (4, 3, 2, 4)
    assert np.all(state.orientation[..., 3] == 1)
    # Arrays with their own batch axes set the batch shape.
    state = scene.initial_state(angular_velocity=np.ones((5, 2, 3)))
    assert state.batch_shape == (5,)
    # Orientations are normalised.
    state = scene.initial_state(orientation=(0, 0, 2.0, 0))
    assert np.allclose(state.orientation, [0, 0, 1, 0])


def test_read_outs_match_their_definitions():
    body = box()
    scene = sim.Scene(body, 0.01, gravity=(0, 0, -9.81))
    q = sim.rotation.quat_from_axis_angle(np.array([1.0, 2.0, 0.5]), 0.7)
    state = scene.initial_state(
        position=(1, 2, 3), orientation=q, linear_velocity=(0.5, -1, 2), angular_velocity=(3, 1, -2)
    )
    rot = sim.rotation.quat_to_matrix(q)
    inertia_world = rot @ body.inertia @ rot.T  # notes: M = R M0 Rᵀ
    w, v = np.array([3.0, 1, -2]), np.array([0.5, -1, 2])
    expected_energy = 0.5 * 2.0 * v @ v + 0.5 * w @ inertia_world @ w
    assert np.isclose(scene.kinetic_energy(state)[()], expected_energy, rtol=1e-14)
    assert np.allclose(scene.linear_momentum(state), 2.0 * v, rtol=1e-14)
    about = np.array([1.0, 0, 0])
    expected_l = inertia_world @ w + np.cross(np.array([1.0, 2, 3]) - about, 2.0 * v)
    assert np.allclose(scene.angular_momentum(state, about=about), expected_l, rtol=1e-13)
    assert np.isclose(scene.potential_energy(state)[()], 2.0 * 9.81 * 3, rtol=1e-14)
    assert np.allclose(state.body_angular_velocity[0], rot.T @ w, rtol=1e-13)
    r = np.array([0.1, -0.2, 0.3])
    assert np.allclose(state.point_position(r)[0], [1, 2, 3] + rot @ r, rtol=1e-14)
    assert np.allclose(state.point_velocity(r)[0], v + np.cross(w, rot @ r), rtol=1e-14)


def test_polyhedron_body_simulates_like_the_equivalent_box():
    corners = np.array([[x, y, z] for x in (0, 0.2) for y in (0, 0.4) for z in (0, 0.6)])
    # Faces of the cuboid by corner index (bit 2: x, bit 1: y, bit 0: z), counter-clockwise
    # from outside.
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    poly = sim.Body.polyhedron(corners, faces, density=2.0 / 0.048)
    assert np.allclose(poly.center_of_mass, [0.1, 0.2, 0.3])
    assert np.isclose(poly.mass, 2.0)
    assert np.allclose(poly.inertia, box().inertia, rtol=1e-12)


# --- bad input: ValueError naming the parameter; nothing lost -------------------------------------


@pytest.mark.parametrize(
    ("build", "word"),
    [
        (lambda: sim.Body.box((0.1, 0.2, 0.3), 0.0), "mass"),
        (lambda: sim.Body.box((0.1, 0.2, 0.3), -1.0), "mass"),
        (lambda: sim.Body.sphere(-0.1, 1.0), "radius"),
        (lambda: sim.Body(1.0, -np.eye(3)), "inertia"),
        (lambda: sim.Body(1.0, np.diag([1.0, 1.0, 5.0])), "inertia"),  # I1 + I2 < I3
        (lambda: sim.Body(1.0, np.ones((2, 2))), "inertia"),
        (lambda: sim.Body(1.0, [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), "inertia"),  # asymmetric
        (lambda: sim.Body(np.nan, np.eye(3)), "mass"),
        (lambda: sim.Scene(box(), 0.0), "dt"),
        (lambda: sim.Scene(box(), -0.01), "dt"),
        (lambda: sim.Scene(box(), float("inf")), "dt"),
        (lambda: sim.Scene(box(), 0.01, integrator="verlet"), "integrator"),
        (lambda: sim.Scene([], 0.01), "bodies"),
        (lambda: sim.Scene(box(), 0.01, gravity=(0, 0)), "gravity"),
        (lambda: sim.Scene(box(), 0.01, gravity=(0, 0, np.nan)), "gravity"),
        (lambda: sim.Scene(box(), 0.01, ground="floor"), "ground"),
        (lambda: sim.Scene(box(), 0.01, linear_damping=-1), "linear_damping"),
        (lambda: sim.Ground(restitution=1.5), "restitution"),
        (lambda: sim.Ground(restitution=-0.1), "restitution"),
        (lambda: sim.Ground(friction=-0.2), "friction"),
        (lambda: sim.Spring(0, (0, 0, 0), stiffness=-1.0), "stiffness"),
        (lambda: sim.Spring(0, (0, 0, 0), stiffness=1.0, damping=-1.0), "damping"),
        (lambda: sim.Spring(0, (0, 0), stiffness=1.0), "anchor"),
        (lambda: sim.Scene(box(), 0.01, springs=[sim.Spring(3, (0, 0, 0), 1.0)]), "springs"),
        (lambda: sim.Body.polyhedron(np.eye(3), [(0, 1, 2)], 1.0), "vertices"),
    ],
)
def test_bad_construction_raises_value_error_naming_the_parameter(build, word):
    with pytest.raises(ValueError, match=word):
        build()


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"position": (0, 0)}, "position"),
        ({"orientation": (0, 0, 0, 0)}, "orientation"),
        ({"orientation": (0, 0, 1)}, "orientation"),
        ({"angular_velocity": (np.nan, 0, 0)}, "angular_velocity"),
        ({"linear_velocity": (np.inf, 0, 0)}, "linear_velocity"),
        ({"position": np.zeros((3, 2, 3))}, "broadcast"),
        ({"batch_shape": (-1,)}, "batch_shape"),
    ],
)
def test_bad_initial_state(kwargs, word):
    with pytest.raises(ValueError, match=word):
        sim.Scene(box(), 0.01).initial_state(**kwargs)


def snapshot(state):
    return [a.copy() for a in state.arrays()]


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"torque": np.full((4, 1, 3), np.nan)}, "torque"),
        ({"torque": np.full((4, 1, 3), np.inf)}, "torque"),
        ({"force": np.array([[0, 0, np.nan]])}, "force"),
        ({"torque": np.zeros((4, 2, 3))}, "torque"),
        ({"torque": np.zeros(2)}, "torque"),
        ({"force": "up"}, "force"),
    ],
)
@pytest.mark.parametrize("integrator", sim.INTEGRATORS)
def test_rejected_step_leaves_the_state_alone_and_the_next_step_works(kwargs, word, integrator):
    scene = sim.Scene(box(), 0.01, integrator=integrator, gravity=(0, 0, -9.81))
    state = scene.initial_state(angular_velocity=(1, 2, 3), batch_shape=(4,))
    before = snapshot(state)
    with pytest.raises(ValueError, match=word):
        scene.step(state, **kwargs)
    for a, b in zip(before, state.arrays(), strict=True):
        assert np.array_equal(a, b)
    after = scene.step(state, torque=np.ones((4, 1, 3)))
    assert np.all(np.isfinite(after.angular_velocity))


def test_state_with_nan_is_named():
    scene = sim.Scene(box(), 0.01)
    state = scene.initial_state(batch_shape=(2,))
    bad = sim.State(
        state.position, state.orientation, state.linear_velocity, state.angular_velocity.copy()
    )
    bad.angular_velocity[1, 0, 2] = np.nan
    with pytest.raises(ValueError, match="angular_velocity"):
        scene.step(bad)
    with pytest.raises(ValueError, match="state"):
        scene.step("not a state")
    wrong = sim.State(state.position[..., :2], *state.arrays()[1:])
    with pytest.raises(ValueError, match="position"):
        scene.step(wrong)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy's overflow notes on the way up
def test_divergence_raises_instead_of_returning_nan():
    """Explicit Euler on a spring with ω_n Δt = 1000 grows ~10⁶ per step: it must raise."""
    spring = sim.Spring(0, anchor=(0, 0, 0), stiffness=1e6)
    scene = sim.Scene(sim.Body.sphere(0.1, 1.0), 1.0, integrator="euler", springs=[spring])
    state = scene.initial_state(position=(1, 0, 0))
    with pytest.raises(sim.DivergenceError, match="diverged"):
        for _ in range(200):
            state = scene.step(state)
    assert np.all(np.isfinite(state.position))  # the last state returned was finite
