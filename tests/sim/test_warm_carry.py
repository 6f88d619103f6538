"""The state carries the contact solve's warm start across calls (``SolverSettings.warm_start``).

With ``warm_start=True`` each step starts its solve from the impulses the previous step ended
with. The state a step returns carries them, so k calls of one step are bit for bit one call of
k steps (a call of its own used to start cold), and the second call's first solve is warm.
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.scenes import landing_scene

WARM = sim.SolverSettings(warm_start=True)


def resting(rows=3, settings=WARM):
    scene, initial = landing_scene(dt=0.01, contact_solver=settings)
    state = initial(batch_shape=(rows,), rng=np.random.default_rng(0))
    return scene, state


def equal(a, b):
    return all(np.array_equal(x, y) for x, y in zip(a.arrays(), b.arrays(), strict=True))


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_k_calls_of_a_warm_started_step_are_one_call_of_k_steps():
    scene, start = resting()
    one = scene.step(start, steps=120)
    many = start
    warmed = 0
    for _ in range(120):
        many = scene.step(many)
        warmed += many.report["contacts"].warm_started
    assert equal(one, many)
    assert np.array_equal(one.contact_impulses, many.contact_impulses)
    assert warmed > 0  # single calls did start warm: from the impulses their state carried


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_the_carried_impulses_hold_the_box_up_and_follow_indexing():
    """At rest on the ground the normal impulses per step carry the weight: Σ λ_n = m g Δt."""
    scene, start = resting()
    state = scene.step(start, steps=200)  # boxes thrown from 1 m come to rest
    lam = state.contact_impulses
    assert lam.shape == (3, scene._c, 3)
    weight = scene.model.mass[0] * 9.81 * scene.dt
    np.testing.assert_allclose(lam[..., 0].sum(axis=-1), weight, rtol=1e-6)
    part = state[1:]
    assert np.array_equal(part.contact_impulses, lam[1:])
    assert equal(scene.step(part), scene.step(state)[1:])  # the slice warm-starts as before


def test_a_state_without_impulses_starts_cold_and_a_cold_scene_carries_none():
    scene, start = resting()
    assert start.contact_impulses is None
    first = scene.step(start)
    assert first.report["contacts"].warm_started == 0
    cold, start = resting(settings=sim.SolverSettings())
    assert cold.step(start).contact_impulses is None
    assert scene.step(sim.State(*first.arrays())).report["contacts"].warm_started == 0


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_an_edited_state_keeps_the_other_elements_impulses_and_its_own_start_cold():
    scene, start = resting()
    state = scene.step(start, steps=200)
    moved = np.array(state.position)
    moved[1, 0, 2] += 1.0  # element 1 is put back in the air (a reset)
    edited = state.edited(np.array([1]), position=moved)
    lam = state.contact_impulses
    assert np.array_equal(edited.contact_impulses[[0, 2]], lam[[0, 2]])
    assert not edited.contact_impulses[1].any() and lam[1].any()
    assert np.array_equal(edited.position, moved)
    assert np.array_equal(edited.linear_velocity, state.linear_velocity)
    # Element 1 then steps as a state of its own, cold; the others as if not edited.
    stepped = scene.step(edited)
    assert equal(stepped[1:2], scene.step(sim.State(*edited[1:2].arrays())))
    assert equal(stepped[0:1], scene.step(state)[0:1])
    with pytest.raises(ValueError, match="unknown state field"):
        state.edited(np.array([0]), speed=moved)
    with pytest.raises(ValueError, match="must keep the shape"):
        state.edited(np.array([0]), position=moved[:2])


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_a_strided_slice_and_a_batch_of_two_axes_carry_their_impulses():
    scene, start = resting(rows=6)
    state = scene.step(start, steps=150)
    every_other = state[::2]  # its impulses are a strided view
    assert equal(scene.step(every_other), scene.step(state)[::2])
    grid = scene.step(scene.step(start.copy(), steps=150))  # reference, flat
    square = sim.State(*(a.reshape(2, 3, *a.shape[1:]) for a in start.arrays()))
    square = scene.step(scene.step(square, steps=150))
    assert np.array_equal(square.position.reshape(grid.position.shape), grid.position)
    assert square.contact_impulses.shape == (2, 3, scene._c, 3)
