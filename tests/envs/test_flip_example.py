"""The docs' worked example (docs/examples/flip_task.py, included in docs/custom-task.md) works:
it registers an env that passes the checkers, starts where it says, and can be solved."""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from env_testing import assert_checkers_pass, assert_vector_equals_singles

from rigid_env.envs.box_landing import FACES

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"
sys.path.insert(0, str(EXAMPLES))
import flip_task  # noqa: E402  (registers MyTasks/Flip-v0)

ID = "MyTasks/Flip-v0"


def test_the_example_is_about_sixty_lines():
    lines = (EXAMPLES / "flip_task.py").read_text().splitlines()
    assert len(lines) <= 80


def test_registered_and_passes_the_checkers():
    assert gym.spec(ID).max_episode_steps == flip_task.MAX_EPISODE_STEPS
    assert_checkers_pass(ID)


def test_starts_at_rest_on_another_face_than_the_target():
    env = gym.make(ID)
    starts, targets = set(), set()
    for seed in range(40):
        _, info = env.reset(seed=seed)
        assert info["contact_count"] == 4 and info["speed"] == 0.0 and info["spin"] == 0.0
        assert info["down_face"] != info["target_face"], seed
        assert info["angle_error"] >= np.pi / 2 - 1e-9  # a neighbouring face or the opposite
        starts.add(info["down_face"])
        targets.add(info["target_face"])
    assert starts == targets == set(range(6))
    fixed = gym.make(ID, target_face="+z")
    for seed in range(10):
        _, info = fixed.reset(seed=seed)
        assert info["target_face"] == FACES.index("+z") != info["down_face"]


def test_a_short_push_about_y_tips_the_box_onto_its_plus_x_face():
    # R_y(+90°) takes body +x to world -z: a positive torque about body y, for four actions,
    # tips the box standing on -z over its edge onto +x, where it settles and succeeds.
    env = gym.make(ID)
    start = {"position": (0, 0, 0.2), "orientation": (0, 0, 0, 1), "target_face": "+x"}
    env.reset(seed=0, options=start)
    for t in range(100):
        action = np.array([0.0, 1.0 if t < 4 else 0.0, 0.0], np.float32)
        _, reward, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert terminated and info["is_success"] and FACES[info["down_face"]] == "+x"
    assert reward > 9.0  # the success bonus


@pytest.mark.filterwarnings("ignore::rigid_env.envs.contact_caps.ContactCapWarning")
def test_vector_env_equals_single_envs_seeded_s_plus_i():
    ends = assert_vector_equals_singles(ID, num_envs=3, seed=5, steps=20, max_episode_steps=8)
    assert ends >= 3
