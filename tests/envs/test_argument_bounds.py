"""Finite but absurd arguments are refused at their documented bounds, naming the argument."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from rigid_env.envs.box_landing import BoxLandingConfig
from rigid_env.envs.reorient import ReorientConfig

# (argument, a value at its bound (accepted), one past it (refused)), per config.
SHARED = [
    ("dt", 1.0, 1.01),
    ("frame_skip", 10_000, 10_001),
    ("max_torque", 1e4, 1.01e4),
    ("max_torque", (1.0, 1e4, 1.0), (1.0, 1e300, 1.0)),
    ("spin_range", (0.0, 1e3), (0.0, 1.1e3)),
    ("hold_time", 1e4, 1.1e4),
    ("spin_weight", 1e6, 1.1e6),
    ("action_weight", 1e6, 1e300),
    ("success_bonus", 1e6, 1e300),
    ("spin_scale", 1e3, 1.1e3),
    ("mass", 1e6, 1.1e6),
]
REORIENT = [
    *SHARED,
    # (BoxLanding's box must also start below its 10 m altimeter range: a smaller bound.)
    ("half_extents", (0.1, 100.0, 0.2), (0.1, 101.0, 0.2)),
    ("tumble_spread", 10.0, 10.5),
    ("angle_threshold", math.pi, 3.2),
    ("spin_threshold", 1e3, 1.1e3),
    ("angle_weight", 1e6, 1.1e6),
]
LANDING = [
    *SHARED,
    ("friction", 10.0, 10.5),
    ("height_range", (1.0, 10.0), (1.0, 10.5)),
    ("vertical_velocity_range", (-100.0, 100.0), (-101.0, 1.0)),
    ("horizontal_speed_range", (0.0, 100.0), (0.0, 101.0)),
    ("face_threshold", math.pi, 3.2),
    ("speed_threshold", 100.0, 101.0),
    ("spin_threshold", 1e3, 1.1e3),
    ("contact_tolerance", 1.0, 1.5),
    ("face_weight", 1e6, 1.1e6),
    ("bounce_weight", 1e6, 1.1e6),
]


@pytest.mark.parametrize(("name", "ok", "bad"), REORIENT, ids=lambda v: str(v))
def test_reorient_bounds(name, ok, bad):
    ReorientConfig(**{name: ok})
    with pytest.raises(ValueError, match=name):
        ReorientConfig(**{name: bad})


@pytest.mark.parametrize(("name", "ok", "bad"), LANDING, ids=lambda v: str(v))
def test_box_landing_bounds(name, ok, bad):
    BoxLandingConfig(**{name: ok})
    with pytest.raises(ValueError, match=name):
        BoxLandingConfig(**{name: bad})


def test_the_issue_case_a_huge_torque_is_refused_not_minus_infinity():
    # max_torque=1e300 used to run, with rewards of -inf once the spin overflowed.
    with pytest.raises(ValueError, match="max_torque must be at most 10000"):
        gym.make("RigidEnv/Reorient-v0", max_torque=1e300)
    env = gym.make("RigidEnv/Reorient-v0", max_torque=1e4)  # the bound itself runs finite
    env.reset(seed=0)
    for _ in range(200):
        _, reward, terminated, truncated, _ = env.step(np.ones(3, np.float32))
        assert np.isfinite(reward)
