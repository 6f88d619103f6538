"""``python -m rigid_env.bench.landing_episode``: the whole-episode landing workload.

Timings are machine noise and never asserted. What is: the workload is BoxLanding's (its Δt,
its calls of ``frame_skip`` steps, one episode), the phases partition the element-steps and
match free fall where it is closed form, and the records are what the speed bench's targets read.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigid_env.bench import landing_episode, peers, speed
from rigid_env.envs.box_landing import MAX_EPISODE_STEPS, BoxLandingConfig
from rigid_env.sim.scenes import LANDING_HALF_EXTENTS

GRAVITY = 9.81
DROP = 1.0  # m, the landing scene's start height


def test_the_workload_is_one_boxlanding_episode():
    assert BoxLandingConfig().dt == landing_episode.DT
    assert BoxLandingConfig().frame_skip == landing_episode.FRAME_SKIP
    assert MAX_EPISODE_STEPS * BoxLandingConfig().frame_skip == landing_episode.STEPS
    scene, state = landing_episode.starts(3)
    assert scene.dt == landing_episode.DT
    np.testing.assert_array_equal(state.position[:, 0, 2], DROP)
    assert len({tuple(q) for q in state.orientation[:, 0]}) == 3  # a different tilt each


def test_no_box_touches_before_free_fall_can_reach_the_ground():
    """The lowest corner starts at least 1 m − |half diagonal| up, so a box falls freely for at
    least t = √(2 (1 − |h|) / g) ≈ 0.386 s, 92 steps of 1/240 s: all flight before that."""
    reach = DROP - math.hypot(*LANDING_HALF_EXTENTS)
    free_steps = int(math.sqrt(2 * reach / GRAVITY) / landing_episode.DT)
    scene, state = landing_episode.starts(4)
    mix = landing_episode.phases(scene, state, free_steps)
    assert mix == {"flight": 1.0, "impact or sliding": 0.0, "rest": 0.0}


def test_over_two_seconds_the_boxes_land_and_come_to_rest():
    """Over 2 s the flight share is at least the free fall's (the bounces add flight), the
    shares add up to one, and the boxes end at rest (restitution 0.3, friction 0.5)."""
    steps = 480
    reach = DROP - math.hypot(*LANDING_HALF_EXTENTS)
    fall = math.sqrt(2 * reach / GRAVITY) / landing_episode.DT
    scene, state = landing_episode.starts(4)
    mix = landing_episode.phases(scene, state, steps)
    assert set(mix) == set(landing_episode.PHASES)
    assert math.isclose(sum(mix.values()), 1.0, rel_tol=1e-12)
    assert mix["flight"] >= int(fall) / steps
    assert mix["impact or sliding"] > 0.0 and mix["rest"] > 0.0


def test_measure_records_feed_the_speed_target_row():
    result = landing_episode.measure(batch=2, actions=2, repeats=1)
    assert result["steps"] == 2 * landing_episode.FRAME_SKIP
    engines = [r["engine"] for r in result["records"]]
    assert engines == (["rigid_env", "mujoco"] if peers.available() else ["rigid_env"])
    ours = result["records"][0]
    assert ours["scene"] == landing_episode.SCENE and ours["batch"] == 2
    assert ours["body_steps_per_s"] == pytest.approx(2 / ours["s_per_step"])
    row = next(t for t in speed.TARGETS if t[1] == landing_episode.SCENE)
    assert (row[2], row[3]) == (ours["integrator"], landing_episode.MUJOCO_INTEGRATOR)
    text = landing_episode.table(result)
    assert "µs per body-step" in text and "flight" in text
