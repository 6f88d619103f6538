"""``reset(seed=..., options=...)``: documented start keys, refused others, Gymnasium's seeding."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from env_testing import make_vec, part

from rigid_env.sim.rotation import quat_from_axis_angle

REORIENT, LANDING = "RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0"
ENVS = (REORIENT, LANDING)
# A start for each env: every key its reset takes.
TILT = quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.5)
STARTS = {
    REORIENT: dict(orientation=TILT, angular_velocity=(0.0, 0.0, 0.25), target=(0, 0, 0, 1)),
    LANDING: dict(
        position=(0.3, -0.2, 0.8),
        orientation=TILT,
        linear_velocity=(0.5, 0.0, -1.0),
        angular_velocity=(0.0, 0.0, 0.25),
        target_face="+x",
    ),
}


@pytest.mark.parametrize("env_id", ENVS)
def test_start_options_set_the_start_state(env_id):
    env = gym.make(env_id)
    obs, info = env.reset(seed=0, options=STARTS[env_id])
    task = env.unwrapped.task
    np.testing.assert_allclose(task.state.orientation[0, 0], TILT, atol=1e-15)
    np.testing.assert_array_equal(task.state.angular_velocity[0, 0], (0.0, 0.0, 0.25))
    if env_id == LANDING:
        np.testing.assert_array_equal(task.state.position[0, 0], (0.3, -0.2, 0.8))
        np.testing.assert_array_equal(task.state.linear_velocity[0, 0], (0.5, 0.0, -1.0))
        assert info["target_face"] == 0 and info["height"] == 0.8
        np.testing.assert_array_equal(part(env, obs, "target_normal"), (1, 0, 0))
    else:
        assert info["angle_error"] == pytest.approx(0.5, abs=1e-12)  # the tilt from the target


@pytest.mark.parametrize("env_id", ENVS)
def test_options_do_not_change_the_generator_stream(env_id):
    # The reset draws its random start all the same; the options replace parts of it. So a
    # later reset (no options) starts where it would have without them.
    a, b = gym.make(env_id), gym.make(env_id)
    a.reset(seed=5, options=STARTS[env_id])
    b.reset(seed=5)
    assert np.array_equal(a.reset()[0], b.reset()[0])


@pytest.mark.parametrize("env_id", ENVS)
def test_a_partial_start_keeps_the_drawn_rest(env_id):
    a, b = gym.make(env_id), gym.make(env_id)
    a.reset(seed=3, options={"angular_velocity": (0.0, 0.0, 0.0)})
    b.reset(seed=3)
    sa, sb = a.unwrapped.task.state, b.unwrapped.task.state
    assert np.array_equal(sa.orientation, sb.orientation)
    assert np.all(sa.angular_velocity == 0) and np.any(sb.angular_velocity != 0)


BAD_OPTIONS = {
    "not a dict": ([1], "options must be a dict"),
    "unknown key": ({"orientaton": (0, 0, 0, 1)}, "orientaton"),
    "zero quaternion": ({"orientation": (0, 0, 0, 0)}, r"options\['orientation'\]"),
    "nan spin": ({"angular_velocity": (0, np.nan, 0)}, r"options\['angular_velocity'\]"),
    "short spin": ({"angular_velocity": (0, 1)}, r"options\['angular_velocity'\]"),
}


@pytest.mark.parametrize("case", BAD_OPTIONS)
@pytest.mark.parametrize("env_id", ENVS)
def test_bad_options_raise_naming_the_key_and_change_nothing(env_id, case):
    options, match = BAD_OPTIONS[case]
    env, twin = gym.make(env_id), gym.make(env_id)
    env.reset(seed=1)
    twin.reset(seed=1)
    action = np.full(3, 0.3, np.float32)
    env.step(action)
    twin.step(action)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=9, options=options)
    # Nothing changed, the generator included: the next steps and reset match the twin's.
    assert np.array_equal(env.step(action)[0], twin.step(action)[0])
    assert np.array_equal(env.reset()[0], twin.reset()[0])


def test_box_landing_refuses_a_start_in_the_ground():
    env = gym.make(LANDING)
    reach = env.unwrapped.task.reach  # 0.269 m for the default box
    with pytest.raises(ValueError, match=r"options\['position'\].*reach"):
        env.reset(seed=0, options={"position": (0, 0, 0.2)})  # with a drawn orientation
    with pytest.raises(ValueError, match="deep in the ground"):
        env.reset(seed=0, options={"position": (0, 0, 0.1), "orientation": (0, 0, 0, 1)})
    with pytest.raises(ValueError, match=r"options\['target_face'\]"):
        env.reset(seed=0, options={"target_face": "top"})
    # Resting on the -z face (the box's half height 0.2 m) is fine, and so is the reach.
    env.reset(seed=0, options={"position": (0, 0, 0.2), "orientation": (0, 0, 0, 1)})
    env.reset(seed=0, options={"position": (0, 0, reach)})
    # set_state holds the same rule.
    with pytest.raises(ValueError, match="deep in the ground"):
        env.unwrapped.set_state(position=(0, 0, 0.05), orientation=(0, 0, 0, 1))


# --- the vector env ---------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_vector_options_broadcast_over_the_reset_sub_envs(env_id):
    env = make_vec(env_id, 3)
    env.reset(seed=0)
    moved = env.step(np.full((3, 3), 0.5, np.float32))[0]
    spins = np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.3]])
    mask = np.array([True, False, True])
    obs, _ = env.reset(options={"reset_mask": mask, "angular_velocity": spins})
    w = env.unwrapped.task.state.angular_velocity[:, 0]
    assert np.array_equal(w[mask], spins)
    assert np.array_equal(obs[1], moved[1]), "sub-env 1 was not reset"
    # One value for all reset sub-envs, and a mismatched batch refused, naming the key.
    env.reset(options={"orientation": TILT})
    assert np.allclose(env.unwrapped.task.state.orientation[:, 0], TILT)
    with pytest.raises(ValueError, match=r"options\['angular_velocity'\]"):
        env.reset(options={"angular_velocity": np.zeros((2, 3))})
    with pytest.raises(ValueError, match="unknown key 'bogus'"):
        env.reset(options={"bogus": 1})
    with pytest.raises(ValueError, match="options must be a dict"):
        env.reset(options=[1])


@pytest.mark.parametrize("env_id", ENVS)
def test_vector_seed_lists_follow_gymnasium(env_id):
    # A list gives one seed per sub-env; None in it draws a random seed for that one.
    ref, _ = make_vec(env_id, 3).reset(seed=[4, 5, 6])
    obs, _ = make_vec(env_id, 3).reset(seed=np.array([4, 5, 6]))
    assert np.array_equal(obs, ref)
    obs, _ = make_vec(env_id, 3).reset(seed=[4, None, 6])
    assert np.array_equal(obs[[0, 2]], ref[[0, 2]]) and not np.array_equal(obs[1], ref[1])


@pytest.mark.parametrize("env_id", ENVS)
def test_a_seeded_partial_reset_reseeds_only_the_reset_sub_envs(env_id):
    # As Gymnasium's sync vector env: sub-envs outside the mask keep their generators.
    env, twin = make_vec(env_id, 2, max_episode_steps=2), make_vec(env_id, 2, max_episode_steps=2)
    env.reset(seed=1)
    twin.reset(seed=1)
    env.reset(seed=[7, 8], options={"reset_mask": np.array([True, False])})
    alone = make_vec(env_id, 2).reset(seed=7)[0]
    assert np.array_equal(env.unwrapped.task.observation()[0], alone[0])
    # Sub-env 1 ends its episode and autoresets from its own, untouched generator.
    zero = np.zeros((2, 3), np.float32)
    for _ in range(3):
        a, b = env.step(zero), twin.step(zero)
    assert np.array_equal(a[0][1], b[0][1])
