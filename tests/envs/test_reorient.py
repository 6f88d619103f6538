"""RigidEnv/Reorient-v0: API contract, vectorisation, rendering, reward/termination, physics."""

from __future__ import annotations

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest
from env_testing import (
    assert_deterministic,
    assert_frame_ok,
    assert_picklable,
    assert_vector_equals_singles,
    make_vec,
    part,
)

from rigid_env import sim
from rigid_env.envs.reorient import MAX_EPISODE_STEPS, ReorientEnv, ReorientVectorEnv
from rigid_env.sim.rotation import quat_from_axis_angle, quat_rotate, random_quaternions

ID = "RigidEnv/Reorient-v0"
EPS = np.finfo(float).eps


# --- registration and checkers -------------------------------------------------------------------


def test_spaces_and_info_types():
    env = gym.make(ID)
    assert env.observation_space.dtype == np.float32 and env.observation_space.shape == (10,)
    assert env.action_space.dtype == np.float32 and env.action_space.shape == (3,)
    obs, info = env.reset(seed=0)
    for _ in range(5):
        assert obs in env.observation_space
        assert type(info["is_success"]) is bool and type(info["angle_error"]) is float
        assert info["angular_momentum"].shape == (3,)
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert type(reward) is float and type(terminated) is bool and type(truncated) is bool


# --- seeding, vectorisation, autoreset -----------------------------------------------------------


def test_same_seed_same_trajectory_bit_for_bit():
    assert_deterministic(ID, seed=11, steps=60, max_episode_steps=25)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},  # truncation-driven autoreset (max_episode_steps below)
        # Loose thresholds and a short hold: episodes terminate by success within a few steps.
        {"angle_threshold": np.pi, "spin_threshold": 100.0, "hold_time": 0.1},
        {"integrator": "rk4", "frame_skip": 3, "target_orientation": (0, 0, 1, 1)},
        # Randomised: each sub-env's noise and torque limit come from its own generator.
        {
            "observation_noise": {"error_quaternion": 0.01, "angular_velocity": 0.05},
            "torque_scale_range": (0.5, 1.5),
        },
    ],
    ids=["truncation", "termination", "rk4-fixed-target", "noise-torque-limits"],
)
def test_vector_env_equals_single_envs_seeded_s_plus_i(kwargs):
    ends = assert_vector_equals_singles(
        ID, num_envs=4, seed=100, steps=50, max_episode_steps=20, **kwargs
    )
    assert ends >= 4, "the rollout must exercise autoreset"


# --- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("dt", -0.01),
        ("dt", float("nan")),
        ("frame_skip", 0),
        ("frame_skip", 2.5),
        ("integrator", "leapfrog"),
        ("max_torque", -1.0),
        ("max_torque", (1.0, 2.0)),
        ("spin_range", (2.0, 1.0)),
        ("spin_range", (-1.0, 1.0)),
        ("tumble_fraction", 1.5),
        ("tumble_spread", -0.1),
        ("target_orientation", (0, 0, 0, 0)),
        ("target_orientation", (0, 0, 1)),
        ("half_extents", (0.3, -0.2, 0.1)),
        ("mass", 0.0),
        ("inertia", (1.0, 1.0, 5.0)),  # violates I1 + I2 >= I3
        ("angle_threshold", 0.0),
        ("spin_threshold", -1.0),
        ("hold_time", -1.0),
        ("terminate_on_success", "yes"),
        ("angle_weight", -1.0),
        ("spin_weight", float("inf")),
        ("action_weight", -0.1),
        ("success_bonus", -5.0),
        ("spin_scale", 0.0),
        ("render_mode", "ascii"),
    ],
)
def test_bad_arguments_raise_value_error_naming_them(name, value):
    with pytest.raises(ValueError, match=name):
        ReorientEnv(**{name: value})
    with pytest.raises(ValueError, match=name):
        ReorientVectorEnv(2, **{name: value})


def test_arguments_reach_the_env_through_make():
    with pytest.raises(ValueError, match="max_torque"):
        gym.make(ID, max_torque=0.0)
    with pytest.raises(ValueError, match="dt"):
        make_vec(ID, 2, dt=0.0)
    task = make_vec(ID, 2, dt=0.01, frame_skip=5, max_torque=2.0).unwrapped.task
    assert (task.dt, task.frame_skip, task.max_torque.tolist()) == (0.01, 5, [2.0] * 3)


def test_bad_vector_arguments():
    with pytest.raises(ValueError, match="num_envs"):
        make_vec(ID, 0)
    with pytest.raises(ValueError, match="max_episode_steps"):
        make_vec(ID, 2, max_episode_steps=0)
    with pytest.raises(ValueError, match="body"):
        gym.make(ID, body=sim.Body.sphere(0.2, 1.0), mass=3.0)


# --- pickling, rendering -------------------------------------------------------------------------


def test_pickled_env_continues_the_same_trajectory():
    assert_picklable(ID)
    assert_picklable(ID, body=sim.Body.sphere(0.3, 2.0), inertia=(0.1, 0.2, 0.25))


def test_rgb_frame_has_content_and_follows_the_orientation():
    env = gym.make(ID, render_mode="rgb_array")
    assert_frame_ok(env.unwrapped.render(), (480, 480, 3))  # before any reset: the initial pose
    env.reset(seed=0)
    u = env.unwrapped
    u.set_state(orientation=(0, 0, 0, 1), angular_velocity=(0, 0, 0), target=(0, 0, 0, 1))
    aligned = env.render()
    assert_frame_ok(aligned)
    u.set_state(orientation=quat_from_axis_angle(np.array([1.0, 0, 0]), 1.0))
    turned = env.render()
    changed = np.any(aligned != turned, axis=-1).mean()
    assert changed > 0.02, f"turning the body by 1 rad changed only {changed:.1%} of the pixels"
    env.close()


def test_other_shapes_render():
    tetra = sim.Body.polyhedron(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
        [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)],
        1.0,
    )
    for body in (sim.Body.sphere(0.2, 1.0), tetra):
        env = gym.make(ID, body=body, render_mode="rgb_array")
        env.reset(seed=0)
        assert_frame_ok(env.render())


def test_vector_render_returns_one_frame_per_env():
    env = make_vec(ID, 2, render_mode="rgb_array")
    env.reset(seed=0)
    frames = env.render()
    assert len(frames) == 2
    for frame in frames:
        assert_frame_ok(frame, (480, 480, 3))
    assert not np.array_equal(frames[0], frames[1])
    env.close()


def test_human_mode_opens_and_close_releases_the_window():
    import pygame

    env = gym.make(ID, render_mode="human")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert pygame.display.get_init() and pygame.display.get_surface() is not None
    env.close()
    assert not pygame.display.get_init()


def test_episode_clip_as_gif(tmp_path):
    env = gym.make(ID, render_mode="rgb_array")
    env.reset(seed=2)
    frames = [env.render()]
    for _ in range(8):
        env.step(env.action_space.sample())
        frames.append(env.render())
    path = tmp_path / "clip.gif"
    imageio.mimsave(path, frames, duration=1 / env.metadata["render_fps"])
    clip = imageio.mimread(path)
    assert len(clip) == 9 and clip[0].shape[:2] == (480, 480)


# --- starting state ------------------------------------------------------------------------------


def test_starting_state_follows_its_arguments():
    env = make_vec(ID, 400, spin_range=(0.5, 1.0), tumble_fraction=1.0, tumble_spread=0.02)
    _, info = env.reset(seed=0)
    task = env.unwrapped.task
    assert np.all((info["spin"] >= 0.5 - 1e-12) & (info["spin"] <= 1.0 + 1e-12))
    # Every spin axis lies near body ±y, the default box's intermediate axis (moments .2, .4, .52).
    assert np.allclose(np.abs(task.intermediate_axis), [0, 1, 0])
    cos = np.abs(task._omega[:, 1]) / info["spin"]
    assert cos.min() > np.cos(0.1)
    # Isotropic directions otherwise: about a third of |Ω̂_y| below 1/3 (uniform |cos| on a sphere).
    env = make_vec(ID, 400, tumble_fraction=0.0, target_orientation=(0, 0, 1, 0))
    env.reset(seed=0)
    task = env.unwrapped.task
    share = np.mean(np.abs(task._omega[:, 1]) / task._spin < 1 / 3)
    assert 0.25 < share < 0.42
    assert np.array_equal(task.target, np.tile([0.0, 0, 1, 0], (400, 1)))


def test_non_diagonal_inertia_has_the_right_intermediate_axis():
    axes = quat_rotate(
        np.array([0.1, 0.2, 0.3, 0.9]) / np.linalg.norm([0.1, 0.2, 0.3, 0.9]), np.eye(3)
    )
    tensor = axes.T @ np.diag([1.0, 2.0, 2.5]) @ axes  # principal axes = rows of `axes`
    env = gym.make(ID, inertia=tensor)
    mid = env.unwrapped.task.intermediate_axis
    assert abs(abs(mid @ axes[1]) - 1) < 1e-12


# --- reward and termination on hand-built states ---------------------------------------------------


def _at(env, orientation, omega=(0.0, 0.0, 0.0), target=(0.0, 0.0, 0.0, 1.0)):
    env.reset(seed=0)
    return env.unwrapped.set_state(orientation=orientation, angular_velocity=omega, target=target)


def test_body_at_target_at_rest_succeeds_after_the_hold_time():
    env = gym.make(ID)  # hold 1 s at 0.05 s per step: success on step 20
    target = random_quaternions(np.random.default_rng(0))
    _, info = _at(env, target, target=target)
    assert info["angle_error"] == pytest.approx(0.0, abs=1e-7) and not info["is_success"]
    zero = np.zeros(3, np.float32)
    for step in range(1, 21):
        _, reward, terminated, truncated, info = env.step(zero)
        assert terminated == info["is_success"] == (step == 20), step
        assert not truncated
    assert reward == pytest.approx(10.0, abs=1e-6)  # the bonus, and no penalty at rest on target


def test_spinning_or_misaligned_body_does_not_succeed():
    env = gym.make(ID, terminate_on_success=False)
    zero = np.zeros(3, np.float32)
    slightly = quat_from_axis_angle(np.array([0.0, 0, 1]), 0.12)  # just outside 0.1 rad
    for orientation, omega in [((0, 0, 0, 1), (0.0, 0.06, 0.0)), (slightly, (0.0, 0.0, 0.0))]:
        _at(env, orientation, omega)
        assert not any(env.step(zero)[4]["is_success"] for _ in range(40))


def test_success_persists_without_termination_and_bonus_is_paid_each_step():
    env = gym.make(ID, terminate_on_success=False, hold_time=0.1, success_bonus=2.0)
    _at(env, (0, 0, 0, 1))
    zero = np.zeros(3, np.float32)
    results = [env.step(zero) for _ in range(5)]
    assert [r[4]["is_success"] for r in results] == [False, True, True, True, True]
    assert [r[2] for r in results] == [False] * 5
    assert [r[1] for r in results] == pytest.approx([0.0, 2.0, 2.0, 2.0, 2.0], abs=1e-9)


def test_reward_is_the_documented_sum_of_terms():
    kw = dict(
        angle_weight=0.7, spin_weight=0.3, action_weight=0.2, spin_scale=1.5, success_bonus=0.0
    )
    env = gym.make(ID, **kw)
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    for _ in range(30):
        a = rng.uniform(-1, 1, 3).astype(np.float32)
        _, reward, _, _, info = env.step(a)
        expected = (
            -0.7 * info["angle_error"] / np.pi
            - 0.3 * info["spin"] / 1.5
            - 0.2 * np.sum(a.astype(float) ** 2) / 3
        )
        assert reward == pytest.approx(expected, rel=1e-12)


def test_angle_error_of_a_known_rotation():
    env = gym.make(ID)
    q = quat_from_axis_angle(np.array([1.0, 2.0, -1.0]), 2.5)
    obs, info = _at(env, q)
    assert info["angle_error"] == pytest.approx(2.5, abs=1e-12)
    w = part(env, obs, "error_quaternion")[3]
    assert w == pytest.approx(np.cos(1.25), abs=1e-7) and w >= 0
    obs, info = _at(env, -q)  # the same rotation: same observation (w >= 0 convention)
    assert part(env, obs, "error_quaternion")[3] == pytest.approx(np.cos(1.25), abs=1e-7)


# --- physics inside the env ------------------------------------------------------------------------


def test_zero_torque_keeps_world_angular_momentum():
    # The splitting integrator applies exact rotations about principal axes, so world L changes
    # only by rounding. Per physics step about a dozen rounding-level operations touch L (five axis
    # rotations of Π and q, the L = R I0 Rᵀ ω and ω = R I0⁻¹ Rᵀ L conversions, amplified by the
    # inertia ratio 0.52/0.2 = 2.6): ~30 ulp of |L|. Allow 64 ulp per step, accumulating linearly
    # (rounding errors need not cancel) over the 400 physics steps (200 actions × 2).
    # Measured: ~36 ulp per step; a spurious torque of even 1e-9 N m would exceed the bound.
    env = gym.make(ID, spin_range=(1.5, 2.0), tumble_fraction=1.0)
    _, info = env.reset(seed=9)
    start, energy = info["angular_momentum"], info["energy"]
    tol = 400 * 64 * EPS * np.linalg.norm(start)
    zero = np.zeros(3, np.float32)
    for _ in range(MAX_EPISODE_STEPS):
        _, _, _, truncated, info = env.step(zero)
        assert np.abs(info["angular_momentum"] - start).max() < tol
    assert truncated
    # Energy is not exact for the splitting, but its error is O((|ω| dt)²) and bounded (the map
    # is symplectic): (2 rad/s · 0.025 s)² = 2.5e-3 relative at most.
    assert abs(info["energy"] - energy) < 2.5e-3 * energy


def test_torque_acts_about_body_axes():
    # One physics step per action: the splitting's two half kicks add ½ dt · R(q) τ_body each,
    # R taken at the orientation of each kick (the start and the end of the step), since the
    # torque turns with the body; the rotation between them keeps world L. So
    # L_end = L_start + ½ dt (R(q_start) + R(q_end)) τ_body; a torque held in the world over the
    # step (R(q_start) twice) misses this by ~½ dt · |Ω| dt · |τ| ≈ 6e-4 here. Rounding: a few ulp.
    env = gym.make(ID, frame_skip=1, max_torque=(1.0, 2.0, 3.0))
    q = random_quaternions(np.random.default_rng(1))
    _, info = _at(env, q, omega=(0.3, -0.2, 0.5))
    a = np.array([0.5, -0.25, 1.0], np.float32)
    _, _, _, _, after = env.step(a)
    tau = a * np.array([1.0, 2.0, 3.0])
    q_end = env.unwrapped.task.state.orientation[0, 0]
    expected = info["angular_momentum"] + 0.0125 * (quat_rotate(q, tau) + quat_rotate(q_end, tau))
    assert np.abs(after["angular_momentum"] - expected).max() < 64 * EPS * np.linalg.norm(expected)


def test_one_simulator_call_per_action():
    # The frame_skip physics steps of an action run in one Scene.step call (steps=frame_skip),
    # with the torque in the body frame: no per-physics-step round trip through Python.
    env = gym.make(ID, frame_skip=4)
    env.reset(seed=3)
    scene = env.unwrapped.task.scene
    calls = []
    step = scene.step

    def counting(state, *args, **kwargs):
        calls.append(kwargs)
        return step(state, *args, **kwargs)

    scene.step = counting
    env.step(np.array([0.5, -0.5, 0.25], np.float32))
    assert len(calls) == 1
    assert calls[0]["steps"] == 4 and calls[0]["body_torque"].shape == (1, 1, 3)


def test_pickled_vector_env_continues_the_same_trajectory():
    import pickle

    env = make_vec(ID, 3, max_episode_steps=4)
    env.reset(seed=8)
    copy = pickle.loads(pickle.dumps(env))
    action = 0.4 * np.ones((3, 3), np.float32)
    for _ in range(6):  # across an autoreset
        a, b = env.step(action), copy.step(action)
        assert all(np.array_equal(x, y) for x, y in zip(a[:4], b[:4], strict=True))
