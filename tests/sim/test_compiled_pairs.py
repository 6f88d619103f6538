"""The compiled step of scenes with body–body contacts (``compiled.contact_pairs``).

Which scenes it takes (every pair scene, with a ground or without one), that a batch steps as its elements alone and
with per-element parameters as a scene of each row's bodies, and that impacts in space keep
momentum. The laws themselves (resting stacks, impacts on a
resting box, friction between boxes, momentum) are tested on the compiled step by
``test_box_box``, ``test_contacts``, ``test_contact_laws`` and ``test_body_body_friction``.
"""

import numpy as np
import pytest

from rigid_env import sim

pytest.importorskip("numba")

DT = 1 / 240
GRAVITY = (0, 0, -9.81)


def boxes(restitution=0.0, ground=True, backend="compiled", bodies=None):
    if bodies is None:
        bodies = [
            sim.Body.box(half_extents=(0.1, 0.15, 0.1), mass=1.0),
            sim.Body.box(half_extents=(0.12, 0.1, 0.08), mass=2.0),
        ]
    return sim.Scene(
        bodies,
        dt=DT,
        gravity=GRAVITY,
        ground=sim.Ground(restitution, 0.5) if ground else None,
        contacts=sim.Material(restitution, 0.4),
        backend=backend,
    )


def drop_state(scene, batch=3):
    """The lower box resting, the upper one dropped tilted and spinning onto it."""
    rng = np.random.default_rng(1)
    tilt = rng.normal(size=(batch, 4)) * [0.1, 0.1, 0.1, 0] + [0, 0, 0, 1]
    tilt /= np.linalg.norm(tilt, axis=-1, keepdims=True)
    q = np.stack([np.broadcast_to([0, 0, 0, 1.0], (batch, 4)), tilt], axis=1)
    x = np.stack(
        [
            np.zeros((batch, 3)) + [0, 0, 0.1],
            rng.normal(size=(batch, 3)) * [0.03, 0.03, 0] + [0, 0, 0.45],
        ],
        axis=1,
    )
    w = np.zeros((batch, 2, 3))
    w[:, 1] = rng.normal(size=(batch, 3))
    return scene.initial_state(position=x, orientation=q, angular_velocity=w)


def run(scene, state, steps=90, **kwargs):
    for _ in range(steps):
        state = scene.step(state, **kwargs)
    return state


def test_pair_scenes_step_compiled_with_a_ground_and_without_one():
    assert boxes().backend == "compiled"
    assert boxes(restitution=0.3).backend == "compiled"
    assert boxes(ground=False).backend == "compiled"


def test_a_batch_steps_as_each_element_alone_bitwise():
    scene = boxes()
    state = drop_state(scene)
    together = run(scene, state)
    assert together.report["contacts"].engaged > 0
    for e in range(3):
        alone = run(scene, state[e : e + 1])
        for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
            assert np.array_equal(getattr(alone, field), getattr(together, field)[e : e + 1])


def test_per_element_masses_step_as_a_scene_of_each_rows_bodies():
    scene = boxes()
    state = drop_state(scene)
    masses = np.array([[1.0, 2.0], [0.3, 5.0], [4.0, 0.5]])
    params = scene.parameters(mass=masses)
    out = run(scene, state, parameters=params)
    for e, row in enumerate(masses):
        # The scene's bodies with row e's masses (their inertias stay the scene's).
        own = boxes(
            bodies=[
                sim.Body(m, b.inertia, b.shape)
                for m, b in zip(row, scene.model.bodies, strict=True)
            ]
        )
        alone = run(own, state[e : e + 1])
        assert np.array_equal(alone.position, out.position[e : e + 1])
        assert np.array_equal(alone.linear_velocity, out.linear_velocity[e : e + 1])
    # The rows differ: the masses change where the upper box comes to rest.
    assert not np.array_equal(out.position[0], out.position[1])


@pytest.mark.parametrize("eps", [0.0, 0.7])
def test_a_scene_without_a_ground_steps_as_with_a_ground_out_of_reach(eps):
    """Without a ground each body's record has a row of its own after the contacts
    (``contact_assembly.O_RECORD``); with one, its first ground slot. A spinning box struck on
    two faces by spheres, with friction, no gravity, 2 km above a ground: its ground slots are
    beyond every reach (and beyond ``FAR_GAP``, so in no stopping scale), and the two scenes
    must step bit for bit alike."""
    bodies = [
        sim.Body.box(half_extents=(0.1, 0.15, 0.2), mass=2.0),
        sim.Body.sphere(radius=0.05, mass=0.5),
        sim.Body.sphere(radius=0.07, mass=0.8),
    ]
    results = []
    for ground in (None, sim.Ground(eps, 0.3)):
        scene = sim.Scene(bodies, dt=DT, ground=ground, contacts=sim.Material(eps, 0.3))
        state = scene.initial_state(
            position=[(0, 0, 2000.0), (-0.3, 0.02, 2000.05), (0.01, 0.4, 1999.97)],
            linear_velocity=[(0, 0, 0), (1.0, 0, 0), (0, -0.8, 0.1)],
            angular_velocity=[(0.3, 0.5, 2.0), (0, 0, 0), (0, 0, 0)],
        )
        touched = 0
        for _ in range(120):
            state = scene.step(state)
            touched += int(state.report["contacts"].touched.any())
        assert touched > 0  # the spheres strike the box
        results.append(state)
    for a, b in zip(results[0].arrays(), results[1].arrays(), strict=True):
        assert np.array_equal(a, b)


def test_the_broad_phase_keeps_a_pair_that_closes_within_the_step():
    """Two spheres on a frictionless ground, 0.3 m apart, one shot at the other at 100 m/s:
    it covers the gap in τ = 0.003 s, within one step of 1/240 s, so the pair must pass the
    broad phase (its bounding spheres are farther apart than they touch) and the elastic
    impact hand the velocity over at τ: the striker stops where it touches (x = 0.3 m) and
    the struck ball travels the rest of the step, x = 0.5 + 100 (Δt − τ) m (to rounding of
    the event's time, 1e-12 m)."""
    scene = sim.Scene(
        [sim.Body.sphere(radius=0.1, mass=1.0), sim.Body.sphere(radius=0.1, mass=1.0)],
        dt=DT,
        gravity=GRAVITY,
        ground=sim.Ground(0.0, 0.0),
        contacts=sim.Material(1.0, 0.0),
    )
    state = scene.initial_state(
        position=[(0, 0, 0.1), (0.5, 0, 0.1)], linear_velocity=[(100.0, 0, 0), (0, 0, 0)]
    )
    state = scene.step(state)
    np.testing.assert_allclose(state.linear_velocity[:, 0], [0.0, 100.0], atol=1e-9)
    tau = 0.3 / 100.0
    np.testing.assert_allclose(
        state.position[:, 0], [0.3, 0.5 + 100.0 * (DT - tau)], rtol=0, atol=1e-12
    )


def test_far_pairs_get_no_contact_point_and_near_ones_their_detection():
    from rigid_env.sim.compiled import contact_assembly as ca
    from rigid_env.sim.contacts.box_box import FAR

    assert ca.bounding_radius(sim.Body.box(half_extents=(1, 2, 2), mass=1.0).shape) == 3.0
    cube = sim.Body.box(half_extents=(0.1, 0.1, 0.1), mass=1.0)
    scene = sim.Scene(
        [cube, cube, cube],
        dt=DT,
        gravity=GRAVITY,
        ground=sim.Ground(0.0, 0.5),
        contacts=sim.Material(0.0, 0.5),
        backend="compiled",
    )
    # Boxes 0 and 1 stacked; box 2 a metre away, at rest: pairs (0, 2) and (1, 2) are far.
    state = scene.initial_state(position=[(0, 0, 0.1), (0, 0, 0.3), (1.0, 0, 0.1)])
    arrays = [np.ascontiguousarray(a.reshape(1, 3, -1)) for a in state.arrays()]
    x, q = arrays[0][0], arrays[1][0]
    ints, floats, _ = ca.contact_data(scene)
    o = ca.offsets.py_func(ints)
    rows = 3 * 4
    out = [np.zeros((rows, 3)) for _ in range(3)]
    gap = np.zeros(rows)
    from rigid_env.sim.compiled.contact_pairs import detect_pairs

    detect_pairs(ints, floats, o, x, q, 0.0, DT, *out, gap)
    np.testing.assert_allclose(gap[:4], 0.0, atol=1e-12)  # (0, 1): face on face, touching
    assert np.all(gap[4:] == FAR)  # (0, 2), (1, 2): no contact point
