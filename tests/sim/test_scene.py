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

    monkeypatch.setattr(forces.ForceTerm, "__init__", tripwire)
    for cls in (contacts.GroundContacts, contacts.PairContacts, contacts.Layout):
        monkeypatch.setattr(cls, "__init__", tripwire)
    for name in sim.INTEGRATORS:
        scene = sim.Scene([box(), box()], 0.01, integrator=name)
        scene.step(scene.initial_state(angular_velocity=(1, 2, 3)), torque=(0.1, 0, 0))
        assert scene.stages == sim.INTEGRATOR_RECORDS[name].parts
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


# --- input integrity while the step is rebuilt (issue 10, item 4) --------------------------------


def hand_built(scene, batch=(), **fields):
    """A State built directly (not by initial_state), fields overridden as given."""
    base = scene.initial_state(angular_velocity=(1.0, -2.0, 0.5), batch_shape=batch)
    arrays = dict(zip(sim.scene.STATE_FIELDS, base.arrays(), strict=True))
    arrays.update({k: np.asarray(v) for k, v in fields.items()})
    return sim.State(**arrays)


@pytest.mark.parametrize(
    "q",
    [(0.0, 0.0, 0.0, 2.0), (0.1, 0.2, 0.3, 0.4), (0.0, 0.0, 0.0, 0.0), (1e200, 0, 0, 1e200)],
    ids=["twice", "short", "zero", "overflowing"],
)
def test_hand_built_non_unit_quaternion_is_rejected_naming_orientation(q):
    """Rejected, not renormalised: |q| ≠ 1 beyond ORIENTATION_TOLERANCE is a ValueError naming
    ``orientation`` in the step and in every read-out (a zero or overflowing |q|² too, where
    normalising would give NaN or zeros); the state is unchanged and the next step works."""
    scene = sim.Scene(box(), 0.01)
    bad = hand_built(scene, orientation=np.array([q]))
    before = snapshot(bad)
    for call in (scene.step, scene.kinetic_energy, scene.angular_momentum, scene.energy):
        with pytest.raises(ValueError, match="orientation"):
            call(bad)
    for a, b in zip(before, bad.arrays(), strict=True):
        assert np.array_equal(a, b)
    good = scene.step(scene.initial_state(orientation=np.array(q[:3] + (q[3] or 1.0,))))
    assert np.allclose(np.linalg.norm(good.orientation, axis=-1), 1.0, atol=1e-15)


def test_quaternion_within_tolerance_is_renormalised_by_the_step():
    """A float32 round trip leaves |q| − 1 ~ 6e-8 (float32's ε/2): accepted, and the step's
    output is unit to float64 rounding (a few ε over one product of unit quaternions)."""
    scene = sim.Scene(box(), 0.01, integrator="implicit")
    q = sim.rotation.quat_from_axis_angle(np.array([1.0, 2.0, 3.0]), 1.0).astype(np.float32)
    state = hand_built(scene, orientation=q[None])
    assert abs(np.linalg.norm(state.orientation.astype(float)) - 1) > 1e-9
    out = scene.step(state)
    assert abs(np.linalg.norm(out.orientation) - 1) < 4 * np.finfo(float).eps


def test_overflowing_initial_orientation_is_normalised_not_zeroed():
    scene = sim.Scene(box(), 0.01)
    state = scene.initial_state(orientation=(1e200, 0.0, 0.0, 1e200))
    assert np.allclose(state.orientation, [[np.sqrt(0.5), 0, 0, np.sqrt(0.5)]], rtol=1e-15)
    tiny = scene.initial_state(orientation=(0.0, 3e-320, 0.0, 0.0))  # subnormal, non-zero
    assert np.array_equal(tiny.orientation, [[0.0, 1.0, 0.0, 0.0]])


def _scenes_of_every_kind():
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=20.0, damping=0.3, attach=(0.1, 0, 0))
    # Every force term, as test_compiled.py's ALL_FORCES: the same stage tuples, compiled once.
    forces = dict(gravity=(0, 0, -9.81), linear_damping=0.1, angular_damping=0.2, springs=[spring])
    for name in sim.INTEGRATORS:
        yield name, sim.Scene(box(), 0.01, integrator=name, **forces)
        yield f"{name}-free", sim.Scene(box(), 0.01, integrator=name)
    for name in sim.CONTACT_CAPABLE:
        yield f"{name}-ground", sim.Scene(box(), 0.01, integrator=name, ground=sim.Ground())


def test_output_never_shares_memory_with_input():
    # A resting free body (nothing changes) is the case where a step could hand back its input.
    for label, scene in _scenes_of_every_kind():
        for state in (
            scene.initial_state(position=(0, 0, 0.3), batch_shape=(2,)),
            scene.initial_state(position=(0, 0, 0.3), angular_velocity=(1, 2, 3)),
        ):
            out = scene.step(state)
            for a in out.arrays():
                for b in state.arrays():
                    assert not np.shares_memory(a, b), label


@pytest.mark.parametrize("dtype", [np.float32, np.int64, np.float16])
def test_output_is_float64_whatever_the_input_dtype(dtype):
    for label, scene in _scenes_of_every_kind():
        base = scene.initial_state(position=(0, 0, 1), batch_shape=(2,))
        # Integer-valued fields so every dtype represents them exactly; q = (0, 0, 0, 1).
        state = sim.State(*(a.astype(dtype) for a in base.arrays()))
        out = scene.step(state, torque=np.ones(3, dtype=dtype))
        assert all(a.dtype == np.float64 for a in out.arrays()), label
        expected = scene.step(base, torque=np.ones(3))
        for a, b in zip(out.arrays(), expected.arrays(), strict=True):
            assert np.array_equal(a, b), label


def test_read_outs_reject_a_state_with_the_wrong_number_of_bodies():
    two = sim.Scene([box(), box()], 0.01, gravity=(0, 0, -9.81))
    state = sim.Scene(box(), 0.01).initial_state(batch_shape=(3,))
    for read_out in (
        two.kinetic_energy,
        two.potential_energy,
        two.energy,
        two.linear_momentum,
        two.angular_momentum,
        two.step,
    ):
        with pytest.raises(ValueError, match="2 bodies"):
            read_out(state)


def test_finiteness_check_does_not_overflow_on_large_finite_values():
    """|x| near the largest double: a sum over the array would overflow to infinity (and call
    this a divergence); the step is exact here (x + Δt·0) and must return it."""
    scene = sim.Scene([box(), box()], 0.01)
    big = 0.9 * np.finfo(float).max
    state = scene.initial_state(position=[(big, big, 0.0), (big, -big, big)])
    out = scene.step(state)
    assert np.array_equal(out.position, state.position)


def test_unused_polyhedron_vertices_take_no_part_in_collisions():
    """A cube given an extra vertex 1 m below it that no face uses: the cube rests on its
    face exactly as without it (the stray point is not a contact candidate)."""
    corners = [[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (-0.1, 0.1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    heights = []
    for stray in ([], [[0.0, 0.0, -1.0]]):
        cube = sim.Body.polyhedron(np.array(corners + stray), faces, 1000.0)
        scene = sim.Scene(cube, 0.01, gravity=(0, 0, -9.81), ground=sim.Ground())
        state = scene.initial_state(position=(0, 0, 0.1))
        for _ in range(50):
            state = scene.step(state)
        heights.append(state.position[0, 2])
    assert heights[1] == heights[0]
    assert abs(heights[0] - 0.1) < 1e-12  # resting on its face: a fixed point of the step


@pytest.mark.parametrize("integrator", sim.INTEGRATORS)
@pytest.mark.parametrize("shape", [(3,), (1, 3), (2, 1, 3), (1, 2, 3)])
def test_broadcastable_torques_work_with_every_integrator(integrator, shape):
    """A torque that broadcasts to (*batch, n, 3) acts exactly as its broadcast copy."""
    spring = sim.Spring(0, anchor=(0, 0, 1), stiffness=20.0, damping=0.3)
    scene = sim.Scene(
        [box(), box()], 0.01, integrator=integrator, gravity=(0, 0, -9.81), springs=[spring]
    )
    state = scene.initial_state(angular_velocity=(1.0, 2.0, 0.5), batch_shape=(2,))
    torque = np.arange(1.0, 1.0 + np.prod(shape)).reshape(shape)
    force = -torque
    full = np.broadcast_to(torque, (2, 2, 3))
    got = scene.step(state, torque=torque, force=force)
    want = scene.step(state, torque=full.copy(), force=-full)
    for a, b in zip(got.arrays(), want.arrays(), strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize(
    ("call", "word"),
    [
        (lambda s, st: sim.Scene(5, 0.01), "bodies"),
        (lambda s, st: sim.Scene(box(), "fast"), "dt"),
        (lambda s, st: sim.Scene(box(), 0.01, integrator=["rk4"]), "integrator"),
        (lambda s, st: sim.Scene(box(), 0.01, springs=5), "springs"),
        (lambda s, st: sim.Scene(box(), 0.01, gravity="down"), "gravity"),
        (lambda s, st: sim.Scene(box(), 0.01, backend=3), "backend"),
        (lambda s, st: sim.Scene(box(), 0.01, timer="yes"), "timer"),
        (lambda s, st: s.initial_state(position="here"), "position"),
        (lambda s, st: s.initial_state(batch_shape="ab"), "batch_shape"),
        (lambda s, st: s.step(st, torque=object()), "torque"),
        (lambda s, st: s.step(st, force={"x": 1}), "force"),
        (lambda s, st: s.step(sim.State("a", "b", "c", "d")), "position"),
        (lambda s, st: s.step(sim.State(*st.arrays()[:3], None)), "angular_velocity"),
        (lambda s, st: s.step(sim.State(st.position, [[0, 0, 1]], *st.arrays()[2:])), "shape"),
        (lambda s, st: s.kinetic_energy(None), "state"),
        (lambda s, st: s.angular_momentum(st, about="origin"), "about"),
    ],
)
def test_wrong_types_raise_value_error(call, word):
    scene = sim.Scene(box(), 0.01)
    state = scene.initial_state()
    with pytest.raises(ValueError, match=word):
        call(scene, state)


def test_backend_is_validated_and_read_from_the_environment(monkeypatch):
    monkeypatch.delenv("RIGID_ENV_BACKEND", raising=False)
    assert sim.Scene(box(), 0.01).backend == "compiled"
    with pytest.raises(ValueError, match="backend"):
        sim.Scene(box(), 0.01, backend="cuda")
    monkeypatch.setenv("RIGID_ENV_BACKEND", "fortran")
    with pytest.raises(ValueError, match="RIGID_ENV_BACKEND"):
        sim.Scene(box(), 0.01)
    monkeypatch.setenv("RIGID_ENV_BACKEND", "compiled-threads")
    assert sim.Scene(box(), 0.01).backend == "compiled"


def test_stage_timer_accumulates_each_part_of_a_step():
    timer = sim.StageTimer()
    scene = sim.Scene(box(), 0.01, gravity=(0, 0, -9.81), ground=sim.Ground(), timer=timer)
    state = scene.initial_state(position=(0, 0, 0.5))
    for _ in range(5):
        state = scene.step(state)
    assert timer.steps == 5
    # A step is one kernel call ("compiled") between its checks.
    assert set(timer.seconds) == {"compiled", "validate", "check"}
    # Disjoint intervals inside each step: the parts cannot add up to more than the steps.
    assert 0 < sum(timer.seconds.values()) <= timer.step_seconds
    scene.timer = None
    scene.step(state)
    assert timer.steps == 5
