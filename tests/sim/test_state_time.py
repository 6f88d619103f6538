"""The state carries its time (``State.time``): whole steps of Δt since its origin."""

import pickle

import numpy as np

from rigid_env import sim

BOX = sim.Body.box((0.1, 0.15, 0.2), 1.0)


def test_the_time_is_the_steps_taken_times_dt_exactly():
    dt = 0.01  # not a binary fraction: a running sum of Δt would drift off k Δt
    scene = sim.Scene(BOX, dt)
    state = scene.initial_state(angular_velocity=(1.0, 2.0, 3.0), batch_shape=(2, 3))
    assert np.array_equal(state.time, np.zeros((2, 3)))
    for _ in range(700):
        state = scene.step(state)
    state = scene.step(state, steps=300)
    assert np.array_equal(state.time, np.full((2, 3), 1000 * dt))
    running = 0.0
    for _ in range(1000):
        running += dt
    assert running != 1000 * dt  # (the sum the exact count avoids)
    assert state[1].time.shape == (3,) and np.all(state[1].time == 1000 * dt)
    assert np.array_equal(pickle.loads(pickle.dumps(state)).time, state.time)
    assert np.array_equal(sim.State(*state.arrays()).time, np.zeros((2, 3)))  # built: 0


def test_a_reset_element_restarts_at_zero_and_keeps_counting_exactly():
    dt = 0.01
    scene = sim.Scene(BOX, dt)
    state = scene.step(scene.initial_state(batch_shape=(3,)), steps=100)
    state = state.edited(np.array([1]), position=state.position + 1.0)
    assert np.array_equal(state.time, [100 * dt, 0.0, 100 * dt])
    state = scene.step(state, steps=7)
    assert np.array_equal(state.time, [107 * dt, 7 * dt, 107 * dt])
    assert np.array_equal(state[1:].time, [7 * dt, 107 * dt])


def test_another_dt_continues_from_the_time_reached():
    a, b = sim.Scene(BOX, 0.01), sim.Scene(BOX, 0.004)
    state = a.step(a.initial_state(batch_shape=(2,)), steps=10)
    state = b.step(state, steps=25)
    assert np.allclose(state.time, 10 * 0.01 + 25 * 0.004, rtol=1e-15, atol=0)
