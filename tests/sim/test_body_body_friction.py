"""Coulomb friction between two bodies, pushed from rest (the compiled step, ``conftest``).

A box of mass m rests on a box of mass M on the ground, every contact with friction μ and no
restitution. A horizontal force F at the top box's centre:

- F < μ m g: static friction between the boxes holds; nothing moves.
- F > μ m g: the top box slides, a = F/m − μ g, so after k semi-implicit steps its velocity is
  k Δt a and it has travelled Δt² a k(k + 1)/2 (each step adds F Δt/m, and the sliding
  friction takes μ λ_n = μ m g Δt, the normal impulse that holds it up). The bottom box takes
  μ m g forward from the top and up to μ (m + M) g back from the ground: it stays.

The cube does not tip while F h < m g w (push height h = w = the half extent): F < m g.
"""

import numpy as np
import pytest

from rigid_env import sim

G = 9.81
MU = 0.3
HALF = 0.1
DT = 1 / 240
STEPS = 120
M_TOP, M_BOTTOM = 1.0, 2.0


def stacked():
    bodies = [
        sim.Body.box(half_extents=(HALF, HALF, HALF), mass=M_BOTTOM),
        sim.Body.box(half_extents=(HALF, HALF, HALF), mass=M_TOP),
    ]
    scene = sim.Scene(
        bodies,
        dt=DT,
        gravity=(0, 0, -G),
        ground=sim.Ground(0.0, MU),
        contacts=sim.Material(0.0, MU),
    )
    state = scene.initial_state(position=[(0, 0, HALF), (0, 0, 3 * HALF)])
    return scene, state


def push(force, steps=STEPS):
    scene, state = stacked()
    start = state.position.copy()
    load = np.array([[0.0, 0.0, 0.0], [force, 0.0, 0.0]])
    velocities = []
    for _ in range(steps):
        state = scene.step(state, force=load)
        velocities.append(state.linear_velocity[1, 0])
    assert scene.report["contacts"].capped == 0
    return scene, start, state, np.array(velocities)


def test_a_push_inside_the_cone_moves_neither_box():
    scene, start, state, _ = push(0.6 * MU * M_TOP * G)
    # The solve stops at 1e-12 of the velocity scale (g Δt ≈ 0.04 m/s) per step; over STEPS
    # steps of Δt that is far below 1e-9 m.
    assert np.abs(state.position - start).max() < 1e-9
    assert np.abs(state.linear_velocity).max() < 1e-9


# The steps keep the top box's centre over the bottom box (travel under 0.05 m of 0.1).
@pytest.mark.parametrize(("share", "steps"), [(1.5, 60), (3.0, 30)])
def test_a_push_beyond_the_cone_slides_the_top_box_at_the_closed_form(share, steps):
    force = share * MU * M_TOP * G
    scene, start, state, velocities = push(force, steps)
    a = force / M_TOP - MU * G
    k = np.arange(1, steps + 1)
    # Each step's velocity is exact to the solve's tolerance (1e-12 of a scale of ~1 m/s) and
    # rounding; 1e-9 m/s leaves room for both over the run.
    np.testing.assert_allclose(velocities, k * DT * a, rtol=0, atol=1e-9)
    travelled = state.position[1, 0] - start[1, 0]
    np.testing.assert_allclose(travelled, DT**2 * a * steps * (steps + 1) / 2, rtol=1e-9)
    assert np.abs(state.position[0] - start[0]).max() < 1e-9  # the bottom box stays
    assert abs(state.position[1, 2] - start[1, 2]) < 1e-9  # on top, not tipping
    assert np.abs(state.angular_velocity).max() < 1e-9
