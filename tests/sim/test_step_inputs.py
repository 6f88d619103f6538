"""What ``Scene.step`` guarantees about the arrays it takes and returns, on both backends.

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
