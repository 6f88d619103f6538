"""A body's contact step does not depend on the rest of its batch (vector env == single envs)."""

from __future__ import annotations

import numpy as np

from rigid_env.sim.scenes import landing_scene


def test_body_out_of_reach_steps_bit_identically_alone_and_beside_a_contact():
    # Element 0 lands (contact impulses, solver passes for the whole batch); element 1 flies
    # high above the ground. Element 1 must come out exactly as when it is stepped alone, where
    # the contact stage returns the free step untouched (nothing in reach).
    scene, _ = landing_scene()
    both = scene.initial_state(
        position=[[[0.0, 0.0, 0.25]], [[1.0, 0.0, 3.0]]],
        orientation=[[[0.1, 0.2, 0.3, 0.9]], [[0.3, -0.1, 0.2, 0.9]]],
        linear_velocity=[[[0.0, 0.0, -2.0]], [[0.2, 0.1, 0.0]]],
        angular_velocity=[[[1.0, 2.0, 3.0]], [[-2.0, 1.0, 0.5]]],
        batch_shape=(2,),
    )
    alone = both[1:]
    touched = False
    for _ in range(40):
        before = both.linear_velocity[0, 0, 2]
        both, alone = scene.step(both), scene.step(alone)
        touched |= both.linear_velocity[0, 0, 2] > before  # the ground pushed element 0 up
        for a, b in zip(both[1:].arrays(), alone.arrays(), strict=True):
            assert np.array_equal(a, b)
    assert touched, "element 0 must have been in contact"
