"""``width``, ``height`` and ``default_camera_config`` as in MuJoCo's v5 envs; headless quiet."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from env_testing import assert_frame_ok, make_vec

ROOT = Path(__file__).resolve().parents[2]
REORIENT, LANDING = "RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0"
ENVS = (REORIENT, LANDING)


def box_fraction(frame: np.ndarray) -> float:
    """The share of pixels in the body's colour (214, 178, 92) at any shade: red above green
    well above blue. The ground and shadow are grey, the sky blue, the axes and ghost apart."""
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    return float(np.mean((r > 1.6 * b) & (g > 1.4 * b) & (r > g)))


@pytest.mark.parametrize("env_id", ENVS)
def test_width_and_height_set_the_frame_size(env_id):
    env = gym.make(env_id, render_mode="rgb_array", width=320, height=200)
    env.reset(seed=0)
    assert_frame_ok(env.render(), (200, 320, 3))
    vec = make_vec(env_id, 2, render_mode="rgb_array", width=64, height=48)
    vec.reset(seed=0)
    assert [f.shape for f in vec.render()] == [(48, 64, 3)] * 2


@pytest.mark.parametrize("env_id", ENVS)
def test_camera_config_moves_the_camera_and_keeps_the_rest(env_id):
    frames = {}
    for name, config in {
        "default": None,
        "far": {"distance": 12.0},
        "side": {"azimuth": 0.0, "elevation": -5.0},
        "fixed": {"lookat": (0.0, 0.0, 0.0), "distance": 6.0},
    }.items():
        env = gym.make(env_id, render_mode="rgb_array", default_camera_config=config)
        env.reset(seed=0)
        frames[name] = env.render()
        if config:
            camera = env.unwrapped._display.camera
            for key, value in config.items():
                assert getattr(camera, key) == pytest.approx(value)
    default = box_fraction(frames["default"])
    assert box_fraction(frames["far"]) < 0.5 * default, "farther away, the body looks smaller"
    assert not np.array_equal(frames["side"], frames["default"])
    assert not np.array_equal(frames["fixed"], frames["default"])


def test_box_landing_default_camera_frames_the_box():
    # The camera follows the box: in the first frame of every episode the box covers at least
    # 3 % of the pixels (the earlier camera, framing the whole throw: 1.5 %), and lies wholly
    # inside the frame.
    env = gym.make(LANDING, render_mode="rgb_array")
    for seed in range(6):
        env.reset(seed=seed)
        frame = env.render()
        mask = (frame[..., 0] > 1.6 * frame[..., 2]) & (frame[..., 1] > 1.4 * frame[..., 2])
        assert box_fraction(frame) > 0.03, seed
        assert not (mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())


BAD = [
    (dict(width=0), "width"),
    (dict(width=1.5), "width"),
    (dict(height=True), "height"),
    (dict(height=10_000), "height"),
    (dict(default_camera_config={"distance": 0.0}), r"default_camera_config\['distance'\]"),
    (dict(default_camera_config={"distance": 1e9}), r"default_camera_config\['distance'\]"),
    (dict(default_camera_config={"elevation": 90}), r"default_camera_config\['elevation'\]"),
    (dict(default_camera_config={"azimuth": "north"}), r"default_camera_config\['azimuth'\]"),
    (dict(default_camera_config={"lookat": (0, 0)}), r"default_camera_config\['lookat'\]"),
    (dict(default_camera_config={"trackbodyid": 1}), "unknown key 'trackbodyid'"),
    (dict(default_camera_config=[("distance", 3)]), "default_camera_config must be a dict"),
]


@pytest.mark.parametrize(("kwargs", "match"), BAD, ids=[m for _, m in BAD])
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_render_options_raise_naming_them(env_id, kwargs, match):
    # Checked when the env is made, whatever its render mode.
    for render_mode in (None, "rgb_array"):
        with pytest.raises(ValueError, match=match):
            gym.make(env_id, render_mode=render_mode, **kwargs)
        with pytest.raises(ValueError, match=match):
            make_vec(env_id, 2, render_mode=render_mode, **kwargs)


HEADLESS = """
import gymnasium as gym, numpy as np, rigid_env
for mode in ("human", "rgb_array"):
    for env_id in ("RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0"):
        env = gym.make(env_id, render_mode=mode, height_range=(0.3, 0.4)) if "Box" in env_id \\
            else gym.make(env_id, render_mode=mode)
        env.reset(seed=0)
        env.step(np.zeros(3, np.float32))
        env.render()
        env.close()
"""


def test_headless_rendering_prints_nothing():
    # No display and no SDL_VIDEODRIVER: SDL used to print an XDG_RUNTIME_DIR error per display
    # driver it tried before settling on its offscreen one; pygame its greeting.
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER", "PYGAME_HIDE_SUPPORT_PROMPT")
    }
    env["PYTHONPATH"] = str(ROOT)
    result = subprocess.run(
        [sys.executable, "-c", HEADLESS],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout == "" and result.stderr == "", result.stdout + result.stderr
