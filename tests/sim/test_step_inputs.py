"""What ``Scene.step`` guarantees about the arrays it takes and returns.

The compiled step passes the caller's arrays to its kernel when they already have the one
memory layout it takes (float64, C-contiguous, aligned, writeable) and checks a state on every
call, also one it returned itself: these tests break the shortcuts that could go wrong.
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.scenes import landing_scene


def scenes():
    """A tumbling free body and a box falling onto the ground, both at batch 1."""
    free = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 2.0), 0.01)
    spinning = free.initial_state(angular_velocity=(0.3, 3.0, 0.6), batch_shape=(1,))
    landing, initial = landing_scene(dt=0.01)
    falling = initial(batch_shape=(1,))
    return [(free, spinning), (landing, falling)]


def overlaps(arrays):
    return [
        (i, j)
        for i, a in enumerate(arrays)
        for j, b in enumerate(arrays)
        if i < j and np.shares_memory(a, b)
    ]


@pytest.mark.parametrize("steps", [1, 3])
def test_outputs_share_memory_with_no_input_and_no_other_output_and_leave_it_alone(steps):
    for scene, state in scenes():
        torque = np.full((1, 1, 3), 0.1)  # the state's own shape: passed through as it is
        before = state.copy()
        out = scene.step(state, torque=torque, steps=steps)
        assert overlaps([*out.arrays(), *state.arrays(), torque]) == []
        for a, b in zip(state.arrays(), before.arrays(), strict=True):
            assert np.array_equal(a, b)  # several steps carry results in copies of the start
        assert all(a.dtype == np.float64 and a.flags.c_contiguous for a in out.arrays())


def test_a_returned_state_is_not_changed_by_later_steps():
    """Outputs are fresh per call: stepping on (and again from the same start) leaves an
    earlier result as it was."""
    for scene, state in scenes():
        first = scene.step(state)
        kept = first.copy()
        later = first
        for _ in range(5):
            later = scene.step(later)
        again = scene.step(state)
        for a, b, c in zip(first.arrays(), kept.arrays(), again.arrays(), strict=True):
            assert np.array_equal(a, b)
            assert np.array_equal(a, c)


def test_a_state_the_scene_returned_is_checked_again_after_an_edit():
    """A state the scene produced, then edited in place, gets the full check: a quaternion off
    unit length or a reshaped array is a ValueError naming the field, the state is left as it
    was, and the next valid call works."""
    for scene, state in scenes():
        out = scene.step(scene.step(state))
        out.orientation[0, 0] = (0.0, 0.0, 0.0, 2.0)
        edited = out.copy()
        with pytest.raises(ValueError, match="orientation"):
            scene.step(out)
        for a, b in zip(out.arrays(), edited.arrays(), strict=True):
            assert np.array_equal(a, b)
        out.orientation[0, 0] = (0.0, 0.0, 0.0, 1.0)
        out.position.shape = (3,)  # in place: the same array object, another shape
        with pytest.raises(ValueError, match="position"):
            scene.step(out)
        out.position.shape = (1, 1, 3)
        assert np.all(np.isfinite(scene.step(out).position))


def _layouts(a: np.ndarray):
    """``a``'s values in memory layouts the compiled step must copy, not pass through."""
    strided = np.empty(a.shape + (2,))[..., 0]
    strided[...] = a
    readonly = a.copy()
    readonly.flags.writeable = False
    raw = np.zeros(a.nbytes + 1, np.uint8)
    unaligned = np.frombuffer(raw.data, np.float64, a.size, offset=1).reshape(a.shape)
    unaligned.flags.writeable = True
    unaligned[...] = a
    assert not unaligned.flags.aligned
    return {"strided": strided, "readonly": readonly, "unaligned": unaligned}


def test_any_memory_layout_steps_as_a_contiguous_state_does():
    for scene, state in scenes():
        want = scene.step(scene.step(state))
        for kind in ("strided", "readonly", "unaligned"):
            arrays = [_layouts(a)[kind] for a in state.arrays()]
            given = sim.State(*arrays)
            saved = [a.copy() for a in arrays]
            got = scene.step(scene.step(given))
            for g, w in zip(got.arrays(), want.arrays(), strict=True):
                assert np.array_equal(g, w), kind
            for a, s in zip(arrays, saved, strict=True):
                assert np.array_equal(a, s), kind


# --- read-outs and constructors refuse what step refuses (issue 29) -----------------------------

READ_OUTS = ("kinetic_energy", "potential_energy", "energy", "linear_momentum", "angular_momentum")


@pytest.mark.parametrize(
    "field", ["position", "orientation", "linear_velocity", "angular_velocity"]
)
def test_read_outs_raise_what_step_raises_for_a_non_finite_state(field):
    """A state ``step`` rejects gives the same ValueError from every read-out, not NaN; the
    finite batch it was made from reads as finite figures."""
    scene = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 2.0), 0.01, gravity=(0, 0, -9.8))
    good = scene.initial_state(
        position=(0.1, 0.2, 0.3), linear_velocity=(1.0, 0.0, 0.0),
        angular_velocity=(0.3, 3.0, 0.6), batch_shape=(2,),
    )  # fmt: skip
    for value in (np.nan, np.inf):
        arrays = dict(zip(sim.scene.STATE_FIELDS, (a.copy() for a in good.arrays()), strict=True))
        arrays[field][1, 0, 0] = value
        bad = sim.State(**arrays)
        with pytest.raises(ValueError) as stepped:
            scene.step(bad)
        assert field in str(stepped.value)
        for name in READ_OUTS:
            with pytest.raises(ValueError) as read:
                getattr(scene, name)(bad)
            assert str(read.value) == str(stepped.value), name
            assert np.all(np.isfinite(getattr(scene, name)(good))), name


@pytest.mark.parametrize(
    "center, message",
    [
        ((np.nan, 0.0, 0.0), "center_of_mass must be finite"),
        ((0.0, np.inf, 0.0), "center_of_mass must be finite"),
        ((1.0, 2.0), "center_of_mass must have trailing shape"),
        ([[1.0, 2.0, 3.0]], "center_of_mass must be a 3-vector"),
        ("middle", "center_of_mass must be a numeric array"),
    ],
)
def test_body_refuses_a_centre_of_mass_that_is_not_a_finite_3_vector(center, message):
    with pytest.raises(ValueError, match=message):
        sim.Body(1.0, np.eye(3), None, center)
    body = sim.Body(1.0, np.eye(3), None, [0.1, 0.2, 0.3])
    assert body.center_of_mass.shape == (3,) and not body.center_of_mass.flags.writeable


@pytest.mark.parametrize("batch_shape", [(2.5,), (2.0,), 2.5, (2, "3"), [[2, 3]], ("2",)])
def test_initial_state_refuses_a_batch_shape_that_is_not_integers(batch_shape):
    scene = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 2.0), 0.01)
    with pytest.raises(ValueError, match="batch_shape"):
        scene.initial_state(batch_shape=batch_shape)


@pytest.mark.parametrize(
    "batch_shape", [(), (3,), (2, 3), 4, [2, 3], (np.int64(2),), np.array([2])]
)
def test_initial_state_takes_integer_batch_shapes(batch_shape):
    scene = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 2.0), 0.01)
    want = tuple(np.atleast_1d(batch_shape).tolist()) if np.size(batch_shape) else ()
    assert scene.initial_state(batch_shape=batch_shape).position.shape == (*want, 1, 3)
