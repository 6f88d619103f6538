"""Box–box contacts: the separating-axis manifold, then stacks and impacts against closed forms.

Resting tolerances: a resting stack is a fixed point of the step (the coupled warm start solves
the sticking contacts exactly), so only rounding moves it: velocities ~1e-16 m/s per step,
positions their sum over the run, N Δt · 1e-15 ≲ 1e-14 m; 1e-12 leaves a factor 100 and still
catches any real sinking (one step of gravity is g Δt² = 1.7e-4 m).
"""

import os

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.contacts.box_box import FAR, box_box
from rigid_env.sim.rotation import quat_exp

G = 9.81
GRAVITY = (0.0, 0.0, -G)
HALF = np.array([0.1, 0.15, 0.2])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def _detect(half_a, half_b, xa, qa, xb, qb):
    fn = box_box(np.array([half_a], float), np.array([half_b], float))
    arm_a, arm_b, n, gap = fn(*(np.array([v], float) for v in (xa, qa, xb, qb)))
    return arm_a[0] + xa, arm_b[0] + xb, n[0], gap[0]


def test_face_face_overlap_gives_four_points_at_the_depth():
    # a sits 1 mm into b's top face, shifted by (0.02, 0.01): the manifold is the overlap
    # rectangle's corners, normal +z (from b to a), every gap −1e-3.
    xa = np.array([0.02, 0.01, 0.399])
    pa, pb, n, gap = _detect(HALF, HALF, xa, IDENTITY, np.zeros(3), IDENTITY)
    np.testing.assert_allclose(n, np.broadcast_to([0, 0, 1.0], (4, 3)), atol=1e-15)
    np.testing.assert_allclose(gap, -1e-3, atol=1e-12)
    np.testing.assert_allclose(pb[:, 2], 0.2, atol=1e-12)  # on b's top face
    np.testing.assert_allclose(pa - pb, gap[:, None] * n, atol=1e-15)
    corners = {(x, y) for x in (-0.08, 0.1) for y in (-0.14, 0.15)}
    got = {(round(x, 12), round(y, 12)) for x, y in pb[:, :2]}
    assert got == corners


def test_face_axis_of_the_other_box_and_sideways_normal():
    # b is a yawed cube 2 mm into a's +x face from the side: normal −x (from b to a).
    cube = np.full(3, 0.1)
    yaw = quat_exp(np.array([0.0, 0.0, 0.3]))
    xb = np.array([0.1 + 0.1 * (np.cos(0.3) + np.sin(0.3)) - 2e-3, 0.0, 0.0])
    pa, pb, n, gap = _detect(cube, cube, np.zeros(3), IDENTITY, xb, yaw)
    np.testing.assert_allclose(n, np.broadcast_to([-1.0, 0, 0], (4, 3)), atol=1e-15)
    # b's leading vertical edge is the deepest feature: 2 mm, at both ends of the edge.
    assert abs(gap.min() + 2e-3) < 1e-12
    np.testing.assert_allclose(pa[:, 0], 0.1, atol=1e-12)  # on a's face


def test_edge_edge_crossing_at_right_angles():
    # Two cubes turned 45° about x and about y: their ridges (along x and along y) cross at
    # right angles above each other; overlap 2 mm along z. One point, at the ridges' crossing.
    cube = np.full(3, 0.1)
    qa, qb = quat_exp(np.array([np.pi / 4, 0, 0])), quat_exp(np.array([0, np.pi / 4, 0]))
    ridge = 0.1 * np.sqrt(2)
    xa = np.array([0.01, -0.02, 2 * ridge - 2e-3])
    pa, pb, n, gap = _detect(cube, cube, xa, qa, np.zeros(3), qb)
    np.testing.assert_allclose(n, np.broadcast_to([0, 0, 1.0], (4, 3)), atol=1e-12)
    np.testing.assert_allclose(gap, -2e-3, atol=1e-12)
    # a's lowest ridge runs along x at y = −0.02, b's highest along y at x = 0.
    np.testing.assert_allclose(pa, np.broadcast_to([0, -0.02, ridge - 2e-3], (4, 3)), atol=1e-12)
    np.testing.assert_allclose(pb, np.broadcast_to([0, -0.02, ridge], (4, 3)), atol=1e-12)


def test_separated_boxes_have_no_contact_within_reach():
    # 5 cm apart along z: four speculative points with gap 0.05; beside each other with no
    # face overlap: no point at all (gap FAR). At rest, the step equals the contact-free step.
    _, _, n, gap = _detect(HALF, HALF, [0, 0, 0.45], IDENTITY, np.zeros(3), IDENTITY)
    np.testing.assert_allclose(gap, 0.05, atol=1e-12)
    _, _, _, gap = _detect(HALF, HALF, [0.3, 0.4, 0.45], IDENTITY, np.zeros(3), IDENTITY)
    assert np.all(gap >= 0.05)
    bodies = [sim.Body.box(HALF, 1.0), sim.Body.box(HALF, 1.0)]
    with_contacts = sim.Scene(bodies, 1 / 240, contacts=sim.Material())
    without = sim.Scene(bodies, 1 / 240, integrator=with_contacts.integrator)
    state = with_contacts.initial_state(
        position=[(0, 0, 0.45), (0, 0, 0)], linear_velocity=[(0, 0, -1.0), (0.0, 0, 0)]
    )
    for _ in range(5):  # closes 2 cm: still out of reach
        a, b = with_contacts.step(state), without.step(state)
        for x, y in zip(a.arrays(), b.arrays(), strict=True):
            assert np.array_equal(x, y)
        state = a


def test_no_face_overlap_gives_far_gap():
    _, _, _, gap = _detect(HALF, HALF, [0.5, 0.0, 0.0], IDENTITY, np.zeros(3), IDENTITY)
    np.testing.assert_allclose(gap, 0.3, atol=1e-12)  # face overlap along x: real points
    yaw = quat_exp(np.array([0.0, 0.0, np.pi / 4]))
    _, _, _, gap = _detect(HALF, HALF, [0.0, 0.0, 2.0], yaw, [3.0, 0.0, 0.0], IDENTITY)
    assert np.all(gap > 0)  # well separated: nothing in reach either way
    assert gap.min() == FAR or gap.min() > 1.0


def _stack(top_mass, top_height=0.6, mu=0.5):
    bodies = [sim.Body.box(HALF, 1.0), sim.Body.box(HALF, top_mass)]
    scene = sim.Scene(
        bodies,
        1 / 240,
        gravity=GRAVITY,
        ground=sim.Ground(0.3, mu),
        contacts=sim.Material(0.3, mu),
    )
    return scene, scene.initial_state(position=[(0, 0, 0.2), (0, 0, top_height)])


# 1200 steps (5 s of rest) in the suite; the long run is
# `RIGID_ENV_REST_STEPS=100000 python -m pytest tests/sim/test_box_box.py -k rest`.
REST_STEPS = int(os.environ.get("RIGID_ENV_REST_STEPS", "1200"))


@pytest.mark.parametrize("top_mass", [1.0, 1e3])
def test_stack_of_two_stays_at_rest(top_mass):
    # Mass ratio 1e3: Jacobi alone leaves a residual that grows from step to step (the light
    # box rocks under the heavy one); the coupled warm start makes rest a fixed point.
    scene, state = _stack(top_mass)
    start = state.copy()
    for _ in range(REST_STEPS):
        state = scene.step(state)
    # Velocity noise: rounding of the light box's share of the heavy load, ε λ / m ≈
    # 1e-16 · 1e3 g Δt ≈ 4e-15 m/s (measured 2e-14); positions integrate it: allow 1e-13 m/s.
    drift = 1e-12 + REST_STEPS * scene.dt * 1e-13
    np.testing.assert_allclose(state.position, start.position, rtol=0, atol=drift)
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("ratio", [1e3, 1e6])
def test_stack_of_three_at_high_mass_ratio_rests(ratio):
    # The stability bench's scene: cubes of 1, √ratio, ratio kg at Δt = 1/60. Before the fix
    # the coupled warm start began from the violated contacts only; the pair contacts' v_n is
    # rounding noise (±1e-13 m/s at 10³), so it began with 1–2 corners of a face, never
    # settled, and returned 10⁴ N·s instead of the 170 N·s load: energy ×42 at step 2.
    half = np.full(3, 0.1)
    masses = ratio ** np.array([0.0, 0.5, 1.0])
    scene = sim.Scene(
        [sim.Body.box(half, float(m)) for m in masses],
        1 / 60,
        gravity=GRAVITY,
        ground=sim.Ground(0.3, 0.5),
        contacts=sim.Material(0.3, 0.5),
    )
    state = scene.initial_state(position=[(0, 0, 0.1), (0, 0, 0.3), (0, 0, 0.5)])
    start, e0 = state.copy(), scene.energy(state)
    steps = 60  # 1 s of rest; the bug showed at step 2
    # Rounding of the solve: ε cond(A) g Δt, cond(A) ≲ ratio × 10² (the mass ratio times the
    # corners' lever-arm spread): 1.1e-16 · 1e2 · ratio · 0.16 ≈ 2e-15 · ratio m/s (measured
    # 3.5e-12 at 10³, 3e-9 at 10⁶); allow 1e-13 · ratio m/s, ω that over the 0.1 m half size.
    # Positions integrate it; the energy moves by the top box's weight times that drift.
    # The bug is metres and m/s; sinking for one step is already g Δt² = 2.7e-3 m.
    v_tol = 1e-13 * ratio
    x_tol = steps * scene.dt * v_tol
    deepest = 0.0
    for _ in range(steps):
        state = scene.step(state)
        z = state.position[:, 2]
        deepest = max(deepest, -min(z[0] - 0.1, *(np.diff(z) - 0.2)))
        assert scene.energy(state) <= e0 + masses[-1] * G * x_tol
    assert deepest <= x_tol
    np.testing.assert_allclose(state.position, start.position, rtol=0, atol=x_tol)
    np.testing.assert_allclose(state.linear_velocity, 0.0, rtol=0, atol=v_tol)
    np.testing.assert_allclose(state.angular_velocity, 0.0, rtol=0, atol=v_tol / 0.1)


def test_tilted_landing_on_a_box_never_gains_kinetic_energy():
    # ε = 0: the contact pass alone. At its solution ΔKE = λᵀv⁺ − ½λᵀAλ ≤ 0 (the solve's
    # ``dissipative``), so each step's velocities carry no more kinetic energy than the same
    # step without contacts (both evaluated at the step's initial orientation, as the solver
    # does); 1e-12 relative is rounding. The 1/K-relaxed Jacobi overshot here: +3e4 relative.
    bodies = [sim.Body.box(HALF, 1.0), sim.Body.box(HALF, 1.0)]
    scene = sim.Scene(
        bodies,
        1 / 240,
        gravity=GRAVITY,
        ground=sim.Ground(0.0, 0.5),
        contacts=sim.Material(0.0, 0.5),
    )
    free = sim.Scene(bodies, 1 / 240, integrator=scene.integrator, gravity=GRAVITY)
    state = scene.initial_state(
        position=[(0, 0, 0.2), (0.03, -0.02, 0.75)],
        orientation=[IDENTITY, quat_exp(np.array([0.3, -0.2, 0.5]))],
        angular_velocity=[(0, 0, 0), (1.0, -2.0, 0.5)],
    )

    def kinetic(s, v, w):
        return scene.kinetic_energy(sim.State(s.position, s.orientation, v, w))

    for _ in range(300):
        new, ref = scene.step(state), free.step(state)
        got = kinetic(state, new.linear_velocity, new.angular_velocity)
        assert got <= kinetic(state, ref.linear_velocity, ref.angular_velocity) * (1 + 1e-12)
        state = new


def test_box_dropped_flat_onto_a_box_lands_without_spinning():
    # Symmetric about the vertical axis: no torque, so ω = 0 to rounding; it comes to rest at
    # the stacked height (restitution 0.3 bounces die below the 0.1 m/s threshold).
    scene, state = _stack(1.0, top_height=0.7)
    for _ in range(480):
        state = scene.step(state)
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(state.position[:, 2], [0.2, 0.6], atol=1e-12)
    np.testing.assert_allclose(state.linear_velocity, 0.0, atol=1e-12)


@pytest.mark.parametrize(("eps", "top_mass"), [(0.5, 1.0), (0.8, 3.0)])
def test_box_dropped_on_a_resting_box_rebounds_as_from_a_fixed_support(eps, top_mass):
    # The lower box rests on the ground: for the upper box's impact it is a fixed support (its
    # ground contacts hold through the event), so the upper box leaves with ε times its impact
    # speed, whatever the masses, and its apex above the impact is ε² times its drop; the lower
    # box stays. The drop is swept over one step (4 phases), and the bound per bounce is the
    # bouncing ball's (test_contact_laws: g Δt²/4, from the step after the impact and the
    # apex's sampling). The lower box: the resting bound of this module's docstring.
    dt, h, phases = 1e-3, 0.2, 4
    bodies = [sim.Body.box(HALF, 1.0), sim.Body.box(HALF, top_mass)]
    scene = sim.Scene(
        bodies, dt, gravity=GRAVITY, ground=sim.Ground(0.3, 0.5), contacts=sim.Material(eps, 0.5)
    )
    t_hit = np.sqrt(2 * h / G) + dt * np.arange(phases) / phases
    drop = 0.5 * G * t_hit**2
    position = np.zeros((phases, 2, 3))
    position[:, 0, 2] = 0.2
    position[:, 1, 2] = 0.6 + drop
    state = scene.initial_state(position=position, batch_shape=(phases,))
    start = state.copy()
    z = []
    for _ in range(int((t_hit.max() + 2 * eps * np.sqrt(2 * h / G)) / dt) + 20):
        state = scene.step(state)
        z.append(state.position[:, 1, 2] - 0.6)
        np.testing.assert_allclose(state.position[:, 0], start.position[:, 0], rtol=0, atol=1e-12)
    z = np.array(z)
    for p in range(phases):
        after = z[int(t_hit[p] / dt) + 1 :, p]
        assert after.min() >= -1e-12  # it bounced at once, and did not sink into the box
        assert abs(after.max() - eps**2 * drop[p]) <= G * dt**2 / 4


def _space(eps, mu, offset, masses=(1.0, 2.0)):
    bodies = [sim.Body.box(HALF, m) for m in masses]
    scene = sim.Scene(bodies, 1e-3, contacts=sim.Material(eps, mu, 0.0))
    state = scene.initial_state(
        position=[(-0.5, *offset), (0, 0, 0)], linear_velocity=[(2.0, 0, 0), (0, 0, 0)]
    )
    return scene, state


@pytest.mark.parametrize(("eps", "mu"), [(1.0, 0.0), (0.5, 0.4)])
def test_off_centre_impact_in_space_conserves_momentum(eps, mu):
    # Equal and opposite impulses: linear momentum exact to rounding (|p| = 2 kg m/s, so
    # 1e-14). About the origin: the two impulses act at points p_a − p_b = gap n, so the normal
    # impulse has no net moment; the offset is along y only, so the boxes spin about z, a
    # principal axis, where implicit_gyro's step has no gyroscopic error (ω × M ω = 0): L is
    # then conserved to rounding too (|L| = 0.16; 1e-14). Friction's moment gap·λ_t vanishes
    # with the gap of active contacts (< rounding here, measured 2e-16).
    scene, state = _space(eps, mu, (0.08, 0.0))
    p0, l0 = scene.linear_momentum(state), scene.angular_momentum(state)
    for _ in range(400):
        state = scene.step(state)
    assert abs(state.angular_velocity[0, 2]) > 1.0  # it was hit off centre and spins
    assert state.linear_velocity[1, 0] > 0.5  # b was pushed
    np.testing.assert_allclose(scene.linear_momentum(state), p0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(scene.angular_momentum(state), l0, rtol=0, atol=1e-14)


def test_generic_impact_conserves_linear_momentum():
    # Offset in y and z: a tumbles (not about a principal axis, so L drifts with the
    # integrator's gyroscopic error and is not asserted here); p is exact to rounding.
    scene, state = _space(0.5, 0.4, (0.05, 0.03))
    p0 = scene.linear_momentum(state)
    for _ in range(400):
        state = scene.step(state)
    assert np.linalg.norm(state.angular_velocity[0]) > 1.0
    np.testing.assert_allclose(scene.linear_momentum(state), p0, rtol=0, atol=1e-14)


def test_equal_mass_elastic_head_on_impact_exchanges_velocities():
    # Newton's law with ε = 1 between equal masses, face on face through the centres: the
    # four corner impulses are equal, so a stops dead and b leaves with a's speed (rounding).
    scene, state = _space(1.0, 0.0, (0.0, 0.0), masses=(1.0, 1.0))
    for _ in range(400):
        state = scene.step(state)
    np.testing.assert_allclose(state.linear_velocity, [[0, 0, 0], [2.0, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, 0.0, atol=1e-12)


def test_batch_equals_single_bitwise():
    # Element 0: a tilted spinning box lands on a resting one; 1: dropped flat; 2: apart in
    # the air. Each element's step must not depend on its neighbours.
    scene, _ = _stack(1.0)
    batch = scene.initial_state(
        position=[
            [(0, 0, 0.2), (0.03, -0.02, 0.75)],
            [(0, 0, 0.2), (0.0, 0.0, 0.7)],
            [(0, 0, 1.0), (1.0, 0.0, 1.0)],
        ],
        orientation=[
            [IDENTITY, quat_exp(np.array([0.3, -0.2, 0.5]))],
            [IDENTITY, IDENTITY],
            [IDENTITY, quat_exp(np.array([0.1, 0.2, 0.3]))],
        ],
        angular_velocity=[[(0, 0, 0), (1.0, -2.0, 0.5)], [(0, 0, 0)] * 2, [(0, 0, 0)] * 2],
        batch_shape=(3,),
    )
    singles = [batch[i] for i in range(3)]
    for k in range(200):
        batch = scene.step(batch)
        singles = [scene.step(s) for s in singles]
        for i in range(3):
            for got, want in zip(batch[i].arrays(), singles[i].arrays(), strict=True):
                assert np.array_equal(got, want)
        if k == 60:
            # Element 0's upper box landed on the lower one (top face at 0.4 m): free fall
            # would have taken it to 0.75 − ½ g (61 Δt)² = 0.43 m by now.
            assert batch.position[0, 1, 2] > 0.55


def test_unsupported_pairs_name_the_pair():
    corners = np.array([[x, y, z] for x in (0, 0.2) for y in (0, 0.4) for z in (0, 0.6)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    cuboid = sim.Body.polyhedron(corners, faces, 1.0)
    with pytest.raises(ValueError, match="Box–Polyhedron"):
        sim.Scene([sim.Body.box(HALF, 1.0), cuboid], 0.01, contacts=sim.Material())


# Steps of the bench's resting scenes: 0.05 s. The 4-3-2-1 pyramid's dense active-set start
# (780 rows) costs ~0.3 s a step on one core; the bug moved the boxes from the first step on
# (~0.1 mm a step), so a short window catches it. The 2 s of the bench (480 steps):
# `RIGID_ENV_PYRAMID_STEPS=480 python -m pytest tests/sim/test_box_box.py -k bench_stacks`.
PYRAMID_STEPS = int(os.environ.get("RIGID_ENV_PYRAMID_STEPS", "12"))


@pytest.mark.parametrize("name", ["tower_4", "pyramid_3", "pyramid_4"])
def test_bench_stacks_and_pyramids_stay_at_rest(name):
    """The many-body bench's resting scenes (``bench.many_bodies``: 1 kg cubes exactly at
    rest, a pyramid's rows offset by half a box with 1 mm between the boxes of a row) move by
    less than what the contact solve's stated tolerance lets through.

    Bound: a converged solve leaves the contact velocities within ``tolerance`` × ``scale`` of
    the answer (``solve.py``'s stopping test), and the answer of a scene exactly at rest is
    v = 0; ``scale`` is the largest free contact velocity (g Δt) or target of a contact
    (−d/Δt for a gap d), and no gap between two boxes or a box and the ground exceeds the
    diagonal D of the box of the scene's corners and the ground: scale ≤ max(g Δt, D/Δt).
    Each step moves a body by Δt times that in the position update, and the separation stage
    removes at most the overlap this made (as much again): over N steps, at most
    2 N Δt tolerance scale ≤ 2 N tolerance D (2–3e-11 m here; rounding, ε |x| ≈ 1e-16 m a step,
    is far below). Before the fix a box–box slot with no contact point (``box_box.FAR``) set
    the scale to 2.4e11 m/s, the particle start passed the probe sweep, and the pyramids moved
    by ~0.1 mm a step (5 mm over the bench's 2 s); the tower, with no such slot, by 0.
    """
    from rigid_env.bench import many_bodies

    scene = many_bodies.rigid_scene(many_bodies.body_count(name))
    position, orientation = many_bodies.start(name, 1)
    state = scene.initial_state(position=position[0], orientation=orientation[0])
    start = state.copy()
    corners = np.concatenate((position[0] - many_bodies.HALF, position[0] + many_bodies.HALF))
    corners = np.concatenate((corners, [[0.0, 0.0, 0.0]]))  # the ground under the scene
    diagonal = np.linalg.norm(np.ptp(corners, axis=0))
    dt, tolerance = scene.dt, sim.SolverSettings().tolerance
    scale = max(G * dt, diagonal / dt)
    bound = 2 * PYRAMID_STEPS * dt * tolerance * scale
    moved = 0.0
    for _ in range(PYRAMID_STEPS):
        state = scene.step(state)
        assert scene.report["contacts"].converged
        moved = max(moved, float(np.max(np.linalg.norm(state.position - start.position, axis=-1))))
    assert moved <= bound, (
        f"{name} moved {moved:.3g} m in {PYRAMID_STEPS} steps (bound {bound:.3g})"
    )
