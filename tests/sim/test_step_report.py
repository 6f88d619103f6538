"""A step returns its report with the state (``State.report``).

The report belongs to the step that made the state, not to the scene: a state read after other
steps of its scene, or stepped beside them on other threads, still reports its own step.
"""

import pickle
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rigid_env.sim.scenes import landing_scene


def fields(report):
    return {k: np.array(v) for k, v in vars(report["contacts"]).items()}


def same_fields(a, b):
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_a_states_report_is_its_own_steps_read_at_once_or_much_later():
    scene, initial = landing_scene(dt=0.01)
    state = initial(batch_shape=(3,), rng=np.random.default_rng(0))
    states, at_once = [], []
    for _ in range(80):  # flight, impacts, rest
        state = scene.step(state)
        assert state.report is scene.report  # until the next step, the scene's too
        states.append(state)
        at_once.append(fields(scene.report))
    for state, want in zip(states, at_once, strict=True):  # read after 80 steps more
        assert same_fields(fields(state.report), want)
    engaged = [int(f["engaged"]) for f in at_once]
    assert engaged[0] == 0 and max(engaged) > 0  # the reports differ: the test can fail


@pytest.mark.filterwarnings("ignore::rigid_env.sim.ContactSolverWarning")
def test_steps_of_one_scene_on_threads_each_return_their_own_report():
    scene, initial = landing_scene(dt=0.01)
    rng = np.random.default_rng(1)
    starts = {size: initial(batch_shape=(size,), rng=rng) for size in (2, 5)}
    for size, start in starts.items():  # pre-roll to contact, the same on every thread
        starts[size] = scene.step(start, steps=40)
    alone = {size: fields(scene.step(start).report) for size, start in starts.items()}

    def step(size):
        return size, fields(scene.step(starts[size]).report)

    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(step, [2, 5] * 20))
    for size, got in results:
        assert len(got["touched"]) == size
        assert same_fields(got, alone[size])


def test_a_state_no_step_returned_reports_nothing():
    scene, initial = landing_scene(dt=0.01)
    assert initial().report == {}
    state = scene.step(initial(batch_shape=(2,)), steps=3)
    assert "contacts" in state.report
    assert state[0].report == {} and state.copy().report == {}
    twin = pickle.loads(pickle.dumps(state))  # a compiled report refers to the driver
    assert twin.report == {}
    assert all(np.array_equal(a, b) for a, b in zip(twin.arrays(), state.arrays(), strict=True))
