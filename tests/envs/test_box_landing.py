"""RigidEnv/BoxLanding-v0: API contract, vectorisation, rendering, reward/termination, physics.

Physics steps in contact are the expensive part (a few ms each at batch 1), so most tests use
short drops, a smaller ``frame_skip`` or one vector env for many hand-built cases.
"""

from __future__ import annotations

import pickle

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
from rigid_env.envs.box_landing import (
    CONTACT_SOLVER,
    FACE_NORMALS,
    FACES,
    GRAVITY,
    BoxLandingEnv,
    BoxLandingVectorEnv,
)
from rigid_env.sim.rotation import quat_from_axis_angle

ID = "RigidEnv/BoxLanding-v0"
EPS = np.finfo(float).eps
HALF = np.array([0.1, 0.15, 0.2])  # the default box
# Short drops that land within a few steps: cheap episodes with contact.
LOW = dict(height_range=(0.3, 0.5), frame_skip=4)
# Nearly upright flat drops with loose thresholds: episodes end by success (termination).
SETTLING = dict(
    height_range=(0.28, 0.3),
    tilt_range=(0.0, 0.05),
    spin_range=(0.0, 0.1),
    horizontal_speed_range=(0.0, 0.0),
    vertical_velocity_range=(0.0, 0.0),
    speed_threshold=0.5,
    spin_threshold=2.0,
    hold_time=0.05,
    frame_skip=4,
)


def resting_pose(face: str) -> tuple[np.ndarray, np.ndarray]:
    """Quaternion and centre of mass of the default box resting on ``face``."""
    x, y = np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    q = {
        "-z": np.array([0.0, 0, 0, 1]),
        "+z": quat_from_axis_angle(x, np.pi),
        "+x": quat_from_axis_angle(y, np.pi / 2),  # R_y(90°) takes body +x to world −z
        "-x": quat_from_axis_angle(y, -np.pi / 2),
        "+y": quat_from_axis_angle(x, -np.pi / 2),
        "-y": quat_from_axis_angle(x, np.pi / 2),
    }[face]
    return q, np.array([0.0, 0.0, HALF[FACES.index(face) // 2]])


ZERO = np.zeros(3, np.float32)


# --- registration and checkers -------------------------------------------------------------------


def test_spaces_and_info_types():
    env = gym.make(ID, **LOW)
    assert env.observation_space.dtype == np.float32 and env.observation_space.shape == (25,)
    assert env.action_space.dtype == np.float32 and env.action_space.shape == (3,)
    obs, info = env.reset(seed=0)
    for _ in range(12):  # through the touchdown
        assert obs in env.observation_space
        assert type(info["is_success"]) is bool and type(info["angle_error"]) is float
        assert type(info["contact_count"]) is int and type(info["bounces"]) is int
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert type(reward) is float and type(terminated) is bool and type(truncated) is bool
    assert info["touchdowns"] >= 1


# --- seeding, vectorisation, autoreset -----------------------------------------------------------


def test_same_seed_same_trajectory_bit_for_bit():
    assert_deterministic(ID, seed=11, steps=30, max_episode_steps=12, **LOW)


@pytest.mark.parametrize(
    "kwargs",
    [
        LOW,  # truncation-driven autoreset, with touchdowns in some sub-envs and not others
        SETTLING,
        dict(LOW, integrator="euler", target_face="random", restitution=0.8, friction=0.2),
        # Randomised: each sub-env's noise and torque limit come from its own generator.
        dict(
            LOW,
            observation_noise={"height": 0.02, "up": 0.01, "angular_velocity": 0.05},
            torque_scale_range=(0.5, 1.5),
        ),
    ],
    ids=["truncation", "termination", "euler-random-face-bouncy", "noise-torque-limits"],
)
def test_vector_env_equals_single_envs_seeded_s_plus_i(kwargs):
    ends = assert_vector_equals_singles(
        ID, num_envs=4, seed=100, steps=30, max_episode_steps=12, **kwargs
    )
    assert ends >= 4, "the rollout must exercise autoreset"


def test_termination_case_really_terminates():
    env = make_vec(ID, 4, **SETTLING)
    env.reset(seed=100)
    terminated = np.zeros(4, bool)
    for _ in range(20):
        terminated |= env.step(np.zeros((4, 3), np.float32))[2]
    assert terminated.all()


# --- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("dt", 0.0),
        ("frame_skip", 0),
        ("integrator", "rk4"),  # not semi-implicit: cannot carry contacts
        ("integrator", "leapfrog"),
        ("restitution", 1.5),
        ("friction", -0.1),
        ("max_torque", 0.0),
        ("max_torque", (1.0, 2.0)),
        ("height_range", (0.2, 1.0)),  # below the box's reach (0.27 m): starts in the ground
        ("height_range", (2.0, 1.0)),
        ("vertical_velocity_range", (1.0, float("nan"))),
        ("horizontal_speed_range", (-1.0, 1.0)),
        ("spin_range", (3.0, 1.0)),
        ("tilt_range", (0.0, 4.0)),
        ("target_face", "top"),
        ("target_face", 7),
        ("half_extents", (0.1, 0.0, 0.2)),
        ("mass", -1.0),
        ("inertia", (0.01, 0.01, 0.05)),  # violates I1 + I2 >= I3
        ("face_threshold", 0.0),
        ("speed_threshold", -1.0),
        ("spin_threshold", float("inf")),
        ("hold_time", -0.5),
        ("contact_tolerance", 0.0),
        ("terminate_on_success", 1),
        ("face_weight", -1.0),
        ("spin_weight", -1.0),
        ("bounce_weight", float("nan")),
        ("action_weight", -0.1),
        ("success_bonus", -5.0),
        ("spin_scale", 0.0),
        ("contact_solver", {"warm_start": True}),
        ("body", sim.Body.sphere(0.2, 1.0)),  # a face to land on needs a box
        ("render_mode", "ascii"),
    ],
)
def test_bad_arguments_raise_value_error_naming_them(name, value):
    with pytest.raises(ValueError, match=name):
        BoxLandingEnv(**{name: value})
    with pytest.raises(ValueError, match=name):
        BoxLandingVectorEnv(2, **{name: value})


def test_arguments_reach_the_env_through_make():
    with pytest.raises(ValueError, match="restitution"):
        gym.make(ID, restitution=-1.0)
    with pytest.raises(ValueError, match="num_envs"):
        make_vec(ID, 0)
    task = make_vec(
        ID, 2, dt=0.002, frame_skip=5, max_torque=0.5, restitution=0.7, friction=0.9
    ).unwrapped.task
    assert (task.dt, task.frame_skip, task.max_torque.tolist()) == (0.002, 5, [0.5] * 3)
    assert task.scene.model.ground.restitution == 0.7 and task.scene.model.ground.friction == 0.9
    assert task.scene.integrator == sim.CONTACT_INTEGRATOR
    body = sim.Body.box((0.2, 0.2, 0.1), 3.0)
    assert gym.make(ID, body=body).unwrapped.task.body is body
    for solver in (sim.SolverSettings(), CONTACT_SOLVER):  # reaches the scene's solve stage
        task = make_vec(ID, 2, contact_solver=solver).unwrapped.task
        (solve,) = [s for s in task.scene.pipeline if s.name == "solve_contacts"]
        assert solve.settings is solver
    assert CONTACT_SOLVER.warm_start and gym.make(ID).unwrapped.task.config.contact_solver is (
        CONTACT_SOLVER
    )


# --- pickling, rendering -------------------------------------------------------------------------


def test_pickled_envs_continue_the_same_trajectory():
    assert_picklable(ID, **LOW)
    env = make_vec(ID, 3, max_episode_steps=4, **LOW)
    env.reset(seed=8)
    copy = pickle.loads(pickle.dumps(env))
    action = 0.4 * np.ones((3, 3), np.float32)
    for _ in range(6):  # across an autoreset
        a, b = env.step(action), copy.step(action)
        assert all(np.array_equal(x, y) for x, y in zip(a[:4], b[:4], strict=True))


def test_rgb_frame_shows_box_ghost_ground_and_shadow():
    env = gym.make(ID, render_mode="rgb_array")
    assert_frame_ok(env.unwrapped.render(), (480, 480, 3))  # before any reset
    env.reset(seed=0)
    u = env.unwrapped
    q, x = resting_pose("-z")
    # 0.3 m up: the camera follows the box, and the shadow below it is in view.
    u.set_state(position=x + [0, 0, 0.3], orientation=q, linear_velocity=(0, 0, 0))
    high = env.render()
    assert_frame_ok(high)
    shadow = np.all(high == (60, 60, 58), axis=-1).sum()  # the renderer's shadow colour
    assert shadow > 200, "a box above the ground casts a shadow"
    # The ghost's white wireframe (anti-aliased): near-white pixels below the text lines; the
    # ground (at most 150), the box (blue 92) and the shadow are all darker.
    assert np.all(high[70:] > 200, axis=-1).sum() > 50, "the ghost's white wireframe"
    u.set_state(orientation=resting_pose("+x")[0])
    turned = env.render()
    changed = np.any(high != turned, axis=-1).mean()
    assert changed > 0.01, f"turning the box changed only {changed:.1%} of the pixels"
    env.close()


def test_vector_render_and_clip(tmp_path):
    env = make_vec(ID, 2, render_mode="rgb_array")
    env.reset(seed=0)
    frames = env.render()
    assert len(frames) == 2 and not np.array_equal(frames[0], frames[1])
    clip = [frames[0]]
    for _ in range(5):
        env.step(np.zeros((2, 3), np.float32))
        clip.append(env.render()[0])
    path = tmp_path / "clip.gif"
    imageio.mimsave(path, clip, duration=1 / env.metadata["render_fps"])
    read = imageio.mimread(path)
    assert len(read) == 6 and read[0].shape[:2] == (480, 480)
    assert env.metadata["render_fps"] == pytest.approx(30.0)


def test_human_mode_opens_and_close_releases_the_window():
    import pygame

    env = gym.make(ID, render_mode="human")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert pygame.display.get_init() and pygame.display.get_surface() is not None
    env.close()
    assert not pygame.display.get_init()


# --- starting state ------------------------------------------------------------------------------


def test_starting_state_follows_its_arguments():
    kw = dict(
        height_range=(1.2, 1.5),
        vertical_velocity_range=(-1.0, -0.5),
        horizontal_speed_range=(0.2, 0.4),
        spin_range=(1.0, 2.0),
        target_face="random",
    )
    env = make_vec(ID, 600, **kw)
    obs, info = env.reset(seed=0)
    task = env.unwrapped.task
    v = task.state.linear_velocity[:, 0]
    assert np.all((info["height"] >= 1.2) & (info["height"] <= 1.5))
    assert np.all((v[:, 2] >= -1.0) & (v[:, 2] <= -0.5))
    horizontal = np.hypot(v[:, 0], v[:, 1])
    assert np.all((horizontal >= 0.2 - 1e-12) & (horizontal <= 0.4 + 1e-12))
    assert np.all((info["spin"] >= 1.0 - 1e-12) & (info["spin"] <= 2.0 + 1e-12))
    assert not info["contact_count"].any() and not info["touchdowns"].any()
    # Uniform orientations: body +z lies within 60° of world up in (1 − cos 60°)/2 = 1/4 of them
    # (binomial sd for 600: 0.018); each of the six faces is drawn 1/6 of the time (sd 0.015).
    up_z = part(env, obs, "up")[:, 2]
    assert 0.19 < np.mean(up_z > 0.5) < 0.31
    counts = np.bincount(info["target_face"], minlength=6) / 600
    assert np.all((counts > 0.11) & (counts < 0.22))
    normal = part(env, obs, "target_normal")
    assert np.array_equal(normal, FACE_NORMALS[info["target_face"]].astype(np.float32))
    # A tilt range of (0, 0.3) keeps body +z within 0.3 rad of up.
    env = make_vec(ID, 200, tilt_range=(0.0, 0.3))
    obs, _ = env.reset(seed=1)
    assert np.all(part(env, obs, "up")[:, 2] >= np.cos(0.3) - 1e-6)


# --- reward and termination on hand-built states ---------------------------------------------------


def _place(env, face, target, **state):
    env.reset(seed=0)
    q, x = resting_pose(face)
    kw = dict(position=x, orientation=q, linear_velocity=(0, 0, 0), angular_velocity=(0, 0, 0))
    return env.unwrapped.set_state(**{**kw, **state}, target_face=target)


def test_box_resting_on_the_target_face_succeeds_after_the_hold_time():
    env = gym.make(ID)  # hold 0.5 s at 1/30 s per step: success on step 15
    obs, info = _place(env, "-z", "-z")
    assert info["angle_error"] == 0.0 and info["contact_count"] == 4 and not info["is_success"]
    assert np.array_equal(
        part(env, obs, "corner_contacts"), [1, 0, 1, 0, 1, 0, 1, 0]
    )  # the four corners with z = −h
    for step in range(1, 16):
        _, reward, terminated, truncated, info = env.step(ZERO)
        assert terminated == info["is_success"] == (step == 15), step
        assert not truncated and info["touchdowns"] == 0
    # The bonus, less the spin penalty of the resting contact's residual jitter (< 0.1 rad/s).
    assert 10.0 - 0.05 * 0.1 / 3.0 < reward <= 10.0


def test_only_the_target_face_succeeds_for_every_face():
    """36 sub-envs: the box resting on each face with each target; success iff they agree."""
    env = make_vec(ID, 36, terminate_on_success=False, hold_time=0.2)
    env.reset(seed=0)
    for k in range(36):
        face, target = FACES[k // 6], FACES[k % 6]
        q, x = resting_pose(face)
        env.unwrapped.set_state(
            k, position=x, orientation=q, linear_velocity=(0, 0, 0), angular_velocity=(0, 0, 0)
        )
        env.unwrapped.set_state(k, target_face=target)
    agree = np.array([k // 6 == k % 6 for k in range(36)])
    success = np.zeros(36, bool)
    for _ in range(10):
        _, reward, terminated, _, info = env.step(np.zeros((36, 3), np.float32))
        success |= info["is_success"]
        assert not terminated.any()
    assert np.array_equal(success, agree)
    assert np.array_equal(info["down_face"], np.repeat(np.arange(6), 6))
    # Off target the face term is −θ/π: θ = π/2 for a neighbouring face, π for the opposite one.
    theta = np.where(agree, 0.0, np.pi / 2)
    theta[[k for k in range(36) if k // 6 != k % 6 and k // 12 == (k % 6) // 2]] = np.pi
    assert info["angle_error"] == pytest.approx(theta, abs=1e-9)
    assert reward[~agree] == pytest.approx(-theta[~agree] / np.pi, abs=2e-3)  # + tiny spin term


def test_box_on_the_wrong_face_does_not_end_the_episode():
    env = gym.make(ID, max_episode_steps=20)
    _place(env, "+x", "-z")
    for _ in range(20):
        _, reward, terminated, truncated, info = env.step(ZERO)
        assert not terminated and not info["is_success"] and info["down_face"] == 0
        assert reward == pytest.approx(-0.5, abs=2e-3)  # θ = π/2
    assert truncated


def test_success_needs_ground_contact_rest_and_the_face():
    """Each case fails, and its twin with only the one threshold relaxed succeeds."""

    def one_step_success(state, **kw):
        # Hold 0: a single step within the goal succeeds; one physics step per action.
        env = gym.make(ID, hold_time=0.0, terminate_on_success=False, frame_skip=1, **kw)
        _place(env, "-z", "-z", **state)
        return env.step(ZERO)[4]

    # Mid-air with the target face down, at rest: no contact, whatever the speed threshold.
    info = one_step_success(dict(position=(0, 0, 1.0)), speed_threshold=10.0)
    assert info["contact_count"] == 0 and not info["is_success"]
    # On the target face, sliding at 0.2 m/s (friction takes μ g dt = 0.02 m/s off per step).
    sliding = dict(linear_velocity=(0.2, 0, 0))
    assert not one_step_success(sliding)["is_success"]
    assert one_step_success(sliding, speed_threshold=0.5)["is_success"]
    # Spinning about the vertical at 0.5 rad/s on the target face.
    spinning = dict(angular_velocity=(0, 0, 0.5))
    assert not one_step_success(spinning)["is_success"]
    assert one_step_success(spinning, spin_threshold=1.0)["is_success"]
    # Tipped by 0.25 rad about x, its lowest edge 1 mm above the ground: in contact, at rest
    # to within one step of gravity (g dt = 0.04 m/s), but beyond face_threshold (0.2 rad).
    q = quat_from_axis_angle(np.array([1.0, 0, 0]), 0.25)
    reach = HALF[1] * np.sin(0.25) + HALF[2] * np.cos(0.25)
    tipped = dict(orientation=q, position=(0, 0, reach + 1e-3))
    info = one_step_success(tipped)
    assert info["contact_count"] == 2 and not info["is_success"]
    assert info["angle_error"] == pytest.approx(0.25, abs=0.01)
    assert one_step_success(tipped, face_threshold=0.3)["is_success"]


def test_reward_is_the_documented_sum_of_terms_and_bounces_are_counted():
    kw = dict(
        face_weight=0.7,
        spin_weight=0.3,
        bounce_weight=0.4,
        action_weight=0.2,
        success_bonus=0.0,
        spin_scale=1.5,
        restitution=0.8,
    )
    env = gym.make(ID, **kw)
    env.reset(seed=4)
    # Flat drop of 0.3 m with ε = 0.8: rebounds to 0.8² · 0.3 = 0.19 m, 0.12 m, ...
    _place(env, "-z", "-z", position=(0, 0, 0.5))
    rng = np.random.default_rng(4)
    touchdowns = []
    for _ in range(40):
        # Small actions (the action term is still exercised): 0.2 of the torque limit tilted
        # the "flat" drop by ~0.1 rad before touchdown, and an edge-first landing bounces low
        # (the contact solve resolves the edges' impacts in order).
        a = 0.02 * rng.uniform(-1, 1, 3).astype(np.float32)
        before = env.unwrapped.task.touchdowns[0]
        _, reward, _, _, info = env.step(a)
        bounce = info["touchdowns"] > before and before > 0
        touchdowns.append(info["touchdowns"])
        expected = (
            -0.7 * info["angle_error"] / np.pi
            - 0.3 * info["spin"] / 1.5
            - 0.4 * bounce
            - 0.2 * np.sum(a.astype(float) ** 2) / 3
        )
        assert reward == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert touchdowns[-1] >= 3 and info["bounces"] == touchdowns[-1] - 1
    assert np.all(np.diff(touchdowns) >= 0)
    # No restitution: the same drop touches down once and stays.
    env = gym.make(ID, restitution=0.0)
    _place(env, "-z", "-z", position=(0, 0, 0.5))
    for _ in range(30):
        info = env.step(ZERO)[4]
    assert info["touchdowns"] == 1 and info["bounces"] == 0


# --- physics inside the env ------------------------------------------------------------------------


def test_free_fall_matches_semi_implicit_euler_closed_form():
    # The contact integrators are semi-implicit: v_{k+1} = v_k − g dt, x_{k+1} = x_k + dt v_{k+1},
    # so after n steps z = z0 + n dt v0 − g dt² n(n+1)/2 and E = E0 − n m g² dt² / 2 exactly
    # (the scheme's energy drift under constant gravity). Rounding: each step adds a few ulp of
    # the largest term (|z| ≤ 1.6, |E| ≤ 20 J); 32 ulp per step bounds the accumulation.
    env = gym.make(ID, frame_skip=1, max_episode_steps=1000)
    v0 = np.array([0.3, -0.2, 0.5])
    _, info = _place(env, "-z", "-z", position=(0, 0, 1.5), linear_velocity=v0)
    e0, dt, g = info["energy"], 1 / 240, GRAVITY
    for n in range(1, 61):  # 0.25 s: z goes 1.5 → ~1.4, far from the ground
        _, _, _, _, info = env.step(ZERO)
        z = 1.5 + n * dt * v0[2] - g * dt**2 * n * (n + 1) / 2
        assert abs(info["height"] - z) < 32 * n * EPS * 1.6
        assert abs(info["energy"] - (e0 - n * g**2 * dt**2 / 2)) < 32 * n * EPS * 20
    assert info["contact_count"] == 0 and info["touchdowns"] == 0


def test_torque_acts_about_body_axes():
    # From rest in the air, a torque about a principal body axis spins the box about that axis
    # only (ω × Iω = 0), so after n steps Ω = n dt τ / I along it and the box has turned by
    # dt² (τ/I) n(n+1)/2 (semi-implicit: the angle uses the updated Ω). About body x with the
    # target −z, that angle is the face error θ.
    max_torque = (0.5, 1.0, 2.0)
    env = gym.make(ID, frame_skip=1, max_torque=max_torque)
    inertia = np.diag(env.unwrapped.task.inertia)
    dt = 1 / 240
    for axis in range(3):
        _place(env, "-z", "-z", position=(0, 0, 1.5))
        a = np.zeros(3, np.float32)
        a[axis] = 0.5
        for _ in range(12):
            obs, _, _, _, info = env.step(a)
        alpha = 0.5 * max_torque[axis] / inertia[axis]
        omega = part(env, obs, "angular_velocity") * env.unwrapped.task.spin_scale
        assert omega[axis] == pytest.approx(12 * dt * alpha, rel=1e-6)  # float32 observation
        assert np.abs(np.delete(omega, axis)).max() < 1e-6
        if axis < 2:
            assert info["angle_error"] == pytest.approx(dt**2 * alpha * 78, rel=1e-9)
        else:  # spinning about the vertical axis leaves the face down
            assert info["angle_error"] < 1e-12


def test_zero_torque_never_gains_energy():
    # Flight loses exactly n m g² dt²/2 (semi-implicit Euler, above); contacts with ε ≤ 1 and
    # friction only dissipate. So E (kinetic + m g z) must not rise beyond rounding (a few ulp
    # of the largest energy, ~30 J), through throws, impacts, bounces, sliding and rest.
    env = make_vec(ID, 32, terminate_on_success=False, max_episode_steps=1000, restitution=0.6)
    _, info = env.reset(seed=3)
    energy = info["energy"]
    touched = np.zeros(32, bool)
    for _ in range(45):
        _, _, _, _, info = env.step(np.zeros((32, 3), np.float32))
        assert np.all(info["energy"] <= energy + 1e-12)
        energy = info["energy"]
        touched |= info["touchdowns"] > 1
    assert touched.mean() > 0.5, "the run must include bounces"
