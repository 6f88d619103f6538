"""Per-episode torque limits and observation noise: off by default, seeded, in the docs' terms."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from env_testing import assert_checkers_pass, make_vec, part

from rigid_env.envs.box_landing import BoxLandingConfig
from rigid_env.envs.contact_caps import ContactCapWarning
from rigid_env.envs.reorient import ReorientConfig

REORIENT, LANDING = "RigidEnv/Reorient-v0", "RigidEnv/BoxLanding-v0"
ENVS = (REORIENT, LANDING)
FAST = {REORIENT: {}, LANDING: dict(height_range=(0.3, 0.5), frame_skip=4)}
NOISE = {
    REORIENT: {"error_quaternion": 0.01, "angular_velocity": 0.05},
    LANDING: {"height": 0.02, "linear_velocity": 0.05, "up": 0.01, "angular_velocity": 0.05},
}


def rollout(env_id, seed, steps, **kwargs):
    """Observations and infos of a single env under fixed actions, with its resets."""
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        out.append((obs, info))
        if terminated or truncated:
            out.append(env.reset())
    return out


# --- off by default ----------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_off_by_default_no_extra_draws_and_no_extra_info(env_id):
    env = gym.make(env_id)
    task = env.unwrapped.task
    assert task.config.torque_scale_range is None and task.config.observation_noise is None
    assert task.noise_index is None
    rng = np.random.default_rng(0)
    assert len(task.draw(rng)) == len(task.draw_start(rng)), "nothing drawn beyond the start"
    _, info = env.reset(seed=0)
    assert "observation_clean" not in info and "torque_limit" not in info


@pytest.mark.parametrize("env_id", ENVS)
def test_zero_noise_and_a_unit_torque_scale_leave_the_first_episode_bit_for_bit(env_id):
    # Noise of std 0 draws nothing; a range (1, 1) draws its uniform after the start, so the
    # first episode (until the next reset's draws) is the default one bit for bit.
    kwargs = dict(FAST[env_id], max_episode_steps=200)
    names = list(NOISE[env_id])
    base = rollout(env_id, 4, 15, **kwargs)
    zero = rollout(env_id, 4, 15, observation_noise=dict.fromkeys(names, 0.0), **kwargs)
    unit = rollout(env_id, 4, 15, torque_scale_range=(1.0, 1.0), **kwargs)
    for (bo, bi), (zo, zi), (uo, ui) in zip(base, zero, unit, strict=True):
        assert np.array_equal(bo, zo) and np.array_equal(bo, uo)
        assert bi.keys() == zi.keys() == ui.keys() - {"torque_limit"}
        np.testing.assert_array_equal(ui["torque_limit"], (1.0, 1.0, 1.0))


# --- torque limits -----------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_torque_limit_is_drawn_per_episode_in_its_range_and_seeded(env_id):
    env = make_vec(env_id, 64, torque_scale_range=(0.5, 2.0), max_torque=(1.0, 2.0, 0.5))
    _, info = env.reset(seed=0)
    limit = info["torque_limit"]
    scale = limit / np.array([1.0, 2.0, 0.5])
    assert np.allclose(scale, scale[:, :1]), "one scale for the three axes"
    assert scale.min() >= 0.5 and scale.max() <= 2.0 and np.ptp(scale[:, 0]) > 1.0
    again = make_vec(env_id, 64, torque_scale_range=(0.5, 2.0), max_torque=(1.0, 2.0, 0.5))
    assert np.array_equal(again.reset(seed=0)[1]["torque_limit"], limit)
    assert not np.array_equal(env.reset(seed=1)[1]["torque_limit"], limit)


def push_from_rest(env, seed):
    """Reorient reset with ``seed``, put at rest, then action 1 about the principal body x axis
    for one action: returns the reset's info and the body's Ω_x after it, which is
    limit · period / I_x (a body-fixed torque about a principal axis of a body at rest:
    ω × Iω = 0 throughout)."""
    _, info = env.reset(seed=seed)
    env.unwrapped.set_state(orientation=(0, 0, 0, 1), target=(0, 0, 0, 1))
    obs, *_ = env.step(np.array([1.0, 0.0, 0.0], np.float32))
    return info, part(env, obs, "angular_velocity")[0] * env.unwrapped.task.spin_scale


def test_the_drawn_torque_limit_is_the_torque_applied():
    env = gym.make(REORIENT, torque_scale_range=(0.25, 4.0), spin_range=(0.0, 0.0))
    task = env.unwrapped.task
    seen = []
    for seed in range(4):
        info, omega = push_from_rest(env, seed)
        expected = info["torque_limit"][0] * task.config.action_period / task.inertia[0, 0]
        assert omega == pytest.approx(expected, rel=1e-6)  # float32 observation
        seen.append(info["torque_limit"][0])
    assert np.ptp(seen) > 0.5


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ((0.0, 1.0), "start above 0"),
        ((2.0, 1.0), "torque_scale_range"),
        ((1.0, float("nan")), "torque_scale_range"),
        ((1.0, 2e4), "torque_scale_range"),  # max_torque × 2e4 exceeds the 1e4 N m bound
        (1.5, "torque_scale_range"),
    ],
)
def test_bad_torque_scale_range_is_refused(value, match):
    for config in (ReorientConfig, BoxLandingConfig):
        with pytest.raises(ValueError, match=match):
            config(torque_scale_range=value)


# --- observation noise -------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ENVS)
def test_noise_has_the_stated_std_per_part_and_the_clean_observation_is_in_info(env_id):
    stds = NOISE[env_id]
    env = make_vec(env_id, 256, observation_noise=stds, **FAST[env_id])
    quiet = make_vec(env_id, 256, **FAST[env_id])
    obs, info = env.reset(seed=0)
    ref, _ = quiet.reset(seed=0)
    assert np.array_equal(info["observation_clean"], ref), "the clean observation is the env's"
    space = env.single_observation_space
    seen = {name: [] for name in env.unwrapped.observation_structure}
    for _ in range(4):
        assert env.observation_space.contains(obs)
        clean = info["observation_clean"].astype(float)
        for name in seen:
            noise = part(env, obs.astype(float) - clean, name)
            # Clipping to the space narrows the spread near a bound: keep clean values that
            # are 5 standard deviations inside both.
            std = stds.get(name, 0.0)
            inside = (part(env, clean - space.low, name) > 5 * std) & (
                part(env, space.high - clean, name) > 5 * std
            )
            seen[name].append(noise[inside] if std else noise.ravel())
        obs, _, _, _, info = env.step(np.zeros((256, 3), np.float32))
    for name, chunks in seen.items():
        noise = np.concatenate(chunks)
        if name not in stds:
            assert np.all(noise == 0), f"{name} has no noise"
        else:
            assert len(noise) > 1000, name
            assert np.std(noise) == pytest.approx(stds[name], rel=0.08), name
            assert abs(np.mean(noise)) < 0.1 * stds[name], name


@pytest.mark.parametrize("env_id", ENVS)
def test_noisy_episodes_are_reproducible_from_the_seed(env_id):
    kwargs = dict(FAST[env_id], observation_noise=NOISE[env_id], max_episode_steps=8)
    a, b = rollout(env_id, 6, 20, **kwargs), rollout(env_id, 6, 20, **kwargs)
    for (ao, ai), (bo, bi) in zip(a, b, strict=True):
        assert np.array_equal(ao, bo)
        assert np.array_equal(ai["observation_clean"], bi["observation_clean"])
    c = rollout(env_id, 7, 20, **kwargs)
    assert not np.array_equal(a[0][0], c[0][0])


@pytest.mark.parametrize("env_id", ENVS)
def test_partial_reset_keeps_the_other_sub_envs_noisy_observation(env_id):
    env = make_vec(env_id, 3, observation_noise=NOISE[env_id])
    env.reset(seed=0)
    obs = env.step(np.zeros((3, 3), np.float32))[0]
    again, _ = env.reset(options={"reset_mask": np.array([False, True, False])})
    assert np.array_equal(again[[0, 2]], obs[[0, 2]])


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ({"heading": 0.1}, "unknown observation part 'heading'"),
        ({"angular_velocity": -0.1}, r"observation_noise\['angular_velocity'\]"),
        ({"angular_velocity": 1e9}, r"observation_noise\['angular_velocity'\]"),
        (0.1, "observation_noise must be a dict"),
    ],
)
def test_bad_observation_noise_is_refused(value, match):
    for config in (ReorientConfig, BoxLandingConfig):
        with pytest.raises(ValueError, match=match):
            config(observation_noise=value)


@pytest.mark.parametrize("env_id", ENVS)
def test_checkers_pass_with_noise_and_torque_limits(env_id):
    # Gymnasium's checker resets twice with one seed and compares: noise is seeded too.
    assert_checkers_pass(env_id, observation_noise=NOISE[env_id], torque_scale_range=(0.5, 1.5))


# --- physical parameters -----------------------------------------------------------------------

PHYSICAL = {
    REORIENT: dict(mass_scale_range=(0.5, 2.0), inertia_scale_range=(0.8, 1.25)),
    LANDING: dict(
        mass_scale_range=(0.5, 2.0),
        inertia_scale_range=(0.8, 1.25),
        friction_range=(0.2, 1.0),
        restitution_range=(0.0, 0.6),
    ),
}
INFO_KEYS = {
    "mass_scale_range": "mass_scale",
    "inertia_scale_range": "inertia_scale",
    "friction_range": "friction",
    "restitution_range": "restitution",
}


@pytest.mark.parametrize("env_id", ENVS)
def test_physical_parameters_are_drawn_per_episode_in_their_ranges_and_seeded(env_id):
    kwargs = dict(PHYSICAL[env_id], **FAST[env_id])
    env = make_vec(env_id, 64, **kwargs)
    _, info = env.reset(seed=0)
    for name, (low, high) in PHYSICAL[env_id].items():
        values = info[INFO_KEYS[name]]
        assert values.min() >= low and values.max() <= high
        assert np.ptp(values) > 0.5 * (high - low), name
    # Each sub-env steps its own row of the scene's parameters: its body and ground are the
    # drawn ones (that a row steps as a scene of its own is tests/sim/test_parameters.py's).
    params = env.unwrapped.task.parameters
    task = env.unwrapped.task
    for i in (0, 17, 63):
        mass = params.mass[i, 0]
        assert mass == pytest.approx(task.body.mass * info["mass_scale"][i], rel=1e-15)
        scale = info["mass_scale"][i] * info["inertia_scale"][i]
        np.testing.assert_allclose(params.inertia[i, 0], scale * task.inertia, rtol=1e-15)
        if env_id == LANDING:
            assert params.friction[i] == info["friction"][i]
            assert params.restitution[i] == info["restitution"][i]
    again = make_vec(env_id, 64, **kwargs)
    _, same = again.reset(seed=0)
    _, other = env.reset(seed=1)
    for key in map(INFO_KEYS.get, PHYSICAL[env_id]):
        assert np.array_equal(same[key], info[key])
        assert not np.array_equal(other[key], info[key])


@pytest.mark.parametrize("env_id", ENVS)
def test_with_physical_randomisation_sub_env_i_equals_a_single_env_seeded_s_plus_i(env_id):
    kwargs = dict(PHYSICAL[env_id], **FAST[env_id])
    env = make_vec(env_id, 3, **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(3)]
    obs, _ = env.reset(seed=5)
    for i, single in enumerate(singles):
        assert np.array_equal(single.reset(seed=5 + i)[0], obs[i])
    rng = np.random.default_rng(1)
    for _ in range(30):
        action = rng.uniform(-1, 1, (3, 3)).astype(np.float32)
        obs, *_ = env.step(action)
        for i, single in enumerate(singles):
            assert np.array_equal(single.step(action[i])[0], obs[i])


@pytest.mark.parametrize("env_id", ENVS)
def test_a_partial_reset_redraws_only_its_envs_physics(env_id):
    kwargs = dict(PHYSICAL[env_id], **FAST[env_id])
    env = make_vec(env_id, 4, **kwargs)
    env.reset(seed=2)
    params = env.unwrapped.task.parameters
    before = params.values()
    env.reset(options={"reset_mask": np.array([False, True, False, False])})
    after = params.values()
    for name in before:
        assert np.array_equal(np.delete(after[name], 1, 0), np.delete(before[name], 1, 0))
        if name != "inertia" or "inertia_scale_range" in kwargs:
            assert not np.array_equal(after[name][1], before[name][1]), name


@pytest.mark.parametrize("env_id", ENVS)
def test_randomised_physics_survives_pickling(env_id):
    kwargs = dict(PHYSICAL[env_id], **FAST[env_id])
    env = make_vec(env_id, 3, **kwargs)
    env.reset(seed=3)
    task = env.unwrapped.task
    twin = pickle.loads(pickle.dumps(task))
    for name, values in task.parameters.values().items():
        assert np.array_equal(twin.parameters.values()[name], values)
    action = np.full((3, 3), 0.5)
    task.step(action)
    twin.step(action)
    assert all(
        np.array_equal(a, b) for a, b in zip(task.state.arrays(), twin.state.arrays(), strict=True)
    )


def test_the_drawn_mass_and_inertia_are_the_physics():
    # push_from_rest's Ω_x = limit · period / I_x with I_x the episode's: the nominal times the
    # mass scale (a denser body of the same shape) times the inertia scale.
    env = gym.make(REORIENT, spin_range=(0.0, 0.0), **PHYSICAL[REORIENT])
    task = env.unwrapped.task
    seen = []
    for seed in range(4):
        info, omega = push_from_rest(env, seed)
        inertia = task.inertia[0, 0] * info["mass_scale"] * info["inertia_scale"]
        expected = task.max_torque[0] * task.config.action_period / inertia
        assert omega == pytest.approx(expected, rel=1e-6)  # float32 observation
        seen.append(expected)
    assert np.ptp(seen) > 0.2 * np.mean(seen)


def test_the_landing_energy_is_that_of_the_drawn_mass():
    # info["energy"] = ½ m |v|² + ½ Ωᵀ I Ω + m g z with the episode's m and I.
    env = gym.make(LANDING, **PHYSICAL[LANDING])
    task = env.unwrapped.task
    for seed in range(3):
        _, info = env.reset(seed=seed)
        state = task.state
        v, z = state.linear_velocity[0, 0], state.position[0, 0, 2]
        omega = task._meas[0, :3]  # body axes
        m = task.body.mass * info["mass_scale"]
        inertia = task.inertia * info["mass_scale"] * info["inertia_scale"]
        want = 0.5 * m * v @ v + 0.5 * omega @ inertia @ omega + m * 9.81 * z
        assert info["energy"] == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize(
    ("name", "value", "match"),
    [
        ("mass_scale_range", (0.0, 1.0), "mass_scale_range"),
        ("mass_scale_range", (2.0, 1.0), "mass_scale_range"),
        ("mass_scale_range", (1.0, 2e3), "mass_scale_range"),
        ("inertia_scale_range", (1.0, float("inf")), "inertia_scale_range"),
        ("inertia_scale_range", 1.5, "inertia_scale_range"),
    ],
)
def test_bad_mass_and_inertia_ranges_are_refused(name, value, match):
    for config in (ReorientConfig, BoxLandingConfig):
        with pytest.raises(ValueError, match=match):
            config(**{name: value})


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("friction_range", (-0.1, 1.0)),
        ("friction_range", (0.5, 20.0)),
        ("restitution_range", (0.0, 1.5)),
        ("restitution_range", (0.6, 0.2)),
    ],
)
def test_bad_ground_ranges_are_refused(name, value):
    with pytest.raises(ValueError, match=name):
        BoxLandingConfig(**{name: value})


@pytest.mark.parametrize("env_id", ENVS)
def test_checkers_pass_with_physical_randomisation(env_id):
    # A drawn material may cap a contact solve in the checker's steps: the env's documented
    # once-per-env ContactCapWarning, not a checker's complaint.
    assert_checkers_pass(env_id, (ContactCapWarning,), **PHYSICAL[env_id], **FAST[env_id])
