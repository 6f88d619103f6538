"""The contact solve's Newton polish (``compiled.contact_newton``) on a
step that Gauss–Seidel alone stops at its cap: taken from a ``RigidEnv/BoxLanding-v0`` rollout
(``python -m rigid_env.bench.contact_solve --rollout boxlanding``: seed 0, the box resting on
its ±x face under a body torque, three corners loaded). From the active-set start Gauss–Seidel
needs ~600 sweeps to the tolerance (cap 500); with the polish the step converges.

Solver tests call the kernels' ``converge`` on the element's contact problem, which the
step's own detection and assembly kernels build (``contact_problem``).
"""

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.sim.compiled import contact_newton as compiled_newton
from rigid_env.sim.compiled import layout
from rigid_env.sim.compiled.contact_assembly import assemble, contact_data, contact_velocity
from rigid_env.sim.compiled.contact_gauss_seidel import (
    WORK_PER_CONTACT,
    gauss_seidel,
    velocity_scale,
)
from rigid_env.sim.compiled.contact_newton import converge as compiled_converge
from rigid_env.sim.compiled.ground import detect, ground_data

EPS = np.finfo(float).eps

# The state before the step and the body torque (BoxLanding-v0: box of half extents 0.1, 0.15,
# 0.2 m and 1 kg, Δt = 1/240 s, implicit_gyro, ground ε = 0.3, μ = 0.5).
POSITION = [0.4271659175325319, 0.543092449097959, 0.10000000000000003]
ORIENTATION = [0.5600910704027815, -0.43162251198827256, 0.5600910704027816, 0.4316225119882727]
TORQUE = [0.9674058556556702, -0.9053640961647034, 0.6765889525413513]
# A second capped step of the same rollout (resting on its ±y face), for the batching test.
POSITION_2 = [-0.11081974500672434, 0.5673844115891625, 0.15000000000000008]
ORIENTATION_2 = [0.6645081324763918, 0.24172079321551565, -0.24172079321551573, -0.664508132476392]
TORQUE_2 = [0.4297722280025482, -0.7789463996887207, 0.9834898114204407]


def landing_scene(settings=None):
    return sim.Scene(
        sim.Body.box((0.1, 0.15, 0.2), 1.0),
        1 / 240,
        integrator="implicit_gyro",
        gravity=(0.0, 0.0, -9.81),
        ground=sim.Ground(restitution=0.3, friction=0.5),
        contact_solver=settings,
    )


def regression_state(scene):
    return scene.initial_state(position=POSITION, orientation=ORIENTATION)


def contact_problem():
    """The element's contact problem as the step's solve sees it: (A (1, 3C, 3C), free
    (1, C, 3), target (1, C), μ (C,), extra (1, C), settings), built by the step's own
    detection and assembly kernels from the velocities after the velocity update. Those are
    the velocities one step of the same body without a ground ends with (the implicit_gyro
    position update moves x and q only), and the box at rest has no impact (extra = 0)."""
    scene = landing_scene()
    state = regression_state(scene)
    flight = sim.Scene(
        scene.model.bodies, scene.dt, integrator="implicit_gyro", gravity=(0, 0, -9.81)
    )
    after = flight.step(state, body_torque=[TORQUE])
    x0, q0 = state.position.reshape(1, 1, 3), state.orientation.reshape(1, 1, 4)
    st = [np.zeros((1, 1, 3)) for _ in range(layout.STEP_TUPLE_SIZE + 1)]
    st[layout.X0], st[layout.Q0], st[layout.X], st[layout.Q] = x0, q0, x0.copy(), q0.copy()
    st[layout.V] = after.linear_velocity.reshape(1, 1, 3).copy()
    st[layout.W] = after.angular_velocity.reshape(1, 1, 3).copy()
    ground = ground_data(scene.model.bodies)
    c = len(ground[2]) * int(ground[3][0])
    st[layout.CONTACT] = np.zeros((1, c, layout.CONTACT_WIDTH))
    st[layout.REPORT] = np.zeros((1, layout.REPORT_WIDTH))
    st = tuple(st)
    detect(0, st, ground)
    assemble(0, st, contact_data(scene))
    assert st[layout.REPORT][0, layout.ENGAGED] == 1.0
    cs = st[layout.CONTACT][0]
    jt = cs[:, layout.JT : layout.JT + 18].reshape(3 * c, 6)
    u = np.concatenate([st[layout.V][0], st[layout.W][0]], axis=-1)
    free = np.array([[contact_velocity(cs, i, 0, -1, u, r) for r in range(3)] for i in range(c)])
    gap = cs[:, layout.GAP]
    target = np.where(gap > 0, -gap / scene.dt, 0.0)
    mu = np.full(c, scene.model.ground.friction)
    return (jt @ jt.T)[None], free[None], target[None], mu, np.zeros((1, c)), sim.SolverSettings()


def solve(a, free, target, mu, extra, settings):
    """The kernels' ``converge`` from λ = 0: (λ (C, 3), sweeps, converged, Newton steps)."""
    c = target.shape[1]
    lam = np.zeros(3 * c)
    sweeps, converged, steps = compiled_converge(
        a[0],
        free[0].ravel(),
        target[0],
        mu,
        lam,
        extra[0],
        settings.max_iterations,
        settings.tolerance,
        velocity_scale(free[0].ravel(), target[0]),
        settings.newton_after,
        settings.newton_steps,
        np.empty(WORK_PER_CONTACT * c),
    )
    return lam.reshape(c, 3), sweeps, converged, steps


def residual(a, free, target, mu, extra, lam):
    """The Alart–Curnier function's kernel at λ (C, 3): (F (3C,), z_n, z_t, ρ)."""
    c = target.shape[1]
    f, zn, zt, rho = np.empty(3 * c), np.empty(c), np.empty((c, 2)), np.empty(c)
    compiled_newton.residual(
        a[0], free[0].ravel(), target[0], mu, extra[0], lam.ravel(), f, zn, zt, rho
    )
    return f, zn, zt, rho


def velocity_bound(a, free, target, mu, extra, lam_1, lam_2):
    """A bound on |A (λ₁ − λ₂)|₂ for two approximate roots of the Alart–Curnier function F
    (``compiled.contact_newton``). Where F is smooth between them with a nonsingular Jacobian G,
    F(λ₁) − F(λ₂) = G (λ₁ − λ₂) + o(|λ₁ − λ₂|), so |A (λ₁ − λ₂)| ≤ ‖A‖ ‖G⁻¹‖ (|F(λ₁)| +
    |F(λ₂)|); the factor 2 covers the o(·) term, 100 ε ‖A‖ |λ| the rounding of A λ.
    The box's fourth corner touches (v_n = target) with next to no load: there F has its kink
    z_n = 0, and its "active" side is singular (four coplanar corners on three degrees of
    freedom: the corner may take any small share of the load, so the solution is a small set,
    not a point). Contacts carrying under 1e-6 of the largest load in both answers are taken
    on their inactive side (F_n = λ_n, F_t = λ_t), which differs from the true F by at most
    |λ_n| + |λ_t| of those contacts, added to |F|. The share only picks the smooth piece used:
    any choice with G nonsingular gives a valid bound."""
    f_1, z_n, z_t, rho = residual(a, free, target, mu, extra, lam_1)
    f_2 = residual(a, free, target, mu, extra, lam_2)[0]
    loads = np.maximum(lam_1[:, 0], lam_2[:, 0])
    unloaded = loads <= 1e-6 * np.max(loads)
    z_n = np.where(unloaded, -1.0, z_n)
    rho = np.where(unloaded, mu * extra[0], rho)
    g = np.empty((f_1.size, f_1.size))
    compiled_newton.jacobian(a[0], mu, z_n, z_t, rho, g)
    inverse = np.linalg.norm(np.linalg.inv(g), 2)
    assert inverse < 1e6  # G nonsingular on that piece
    norm_a = np.linalg.norm(a[0], 2)
    kink = sum(np.linalg.norm(lam[unloaded]) for lam in (lam_1, lam_2))
    spread = np.linalg.norm(f_1) + np.linalg.norm(f_2) + kink
    return 2 * norm_a * inverse * spread + 100 * EPS * norm_a * np.linalg.norm(lam_1)


def test_regression_step_converges_with_the_newton_polish():
    scene = landing_scene()
    scene.step(regression_state(scene), body_torque=[TORQUE])
    report = scene.report["contacts"]
    assert report.engaged == 1
    assert report.capped == 0
    assert report.newton > 0
    assert report.iterations < sim.SolverSettings().max_iterations


def test_without_newton_the_step_is_capped_and_reported():
    # The case is a hard one for Gauss–Seidel alone (what main did): the cap is reached and
    # reported, not hidden.
    scene = landing_scene(sim.SolverSettings(newton_steps=0))
    with pytest.warns(sim.ContactSolverWarning):
        scene.step(regression_state(scene), body_torque=[TORQUE])
    report = scene.report["contacts"]
    assert report.capped == 1
    assert report.newton == 0


def test_regression_solution_meets_signorini_and_coulomb():
    a, free, target, mu, extra, settings = contact_problem()
    lam, sweeps, converged, steps = solve(a, free, target, mu, extra, settings)
    assert converged and steps > 0
    v = free[0] + (a[0] @ lam.ravel()).reshape(lam.shape)
    # Tolerances. "Converged" means the last sweep changed no contact velocity by more than
    # tolerance × scale (scale: the largest |free| or |target|); each contact's update makes its
    # own conditions exact to rounding (normal: v_n = target when λ_n > 0; tangent: v_t = −γ λ_t
    # on the circle, v_t = 0 inside), and the updates of the other contacts after it in that
    # sweep move its velocity by at most that change. Rounding of v = b + A λ: 3C terms, each
    # within ε |A_ij λ_j|, for 3C = 12: 12 ε Σ|A λ| (doubled for the sweep's own update).
    scale = max(np.max(np.abs(free)), np.max(np.abs(target)))
    rounding = 24 * EPS * (np.abs(a[0]) @ np.abs(lam.ravel())).reshape(lam.shape)
    slack = settings.tolerance * scale + rounding
    lam_n, v_n = lam[:, 0], v[:, 0]
    assert np.all(lam_n >= 0)  # the normal update's max(·, 0) is the last write: exact
    assert np.all(v_n >= target[0] - slack[:, 0])
    assert np.all(np.abs(np.where(lam_n > 0, v_n - target[0], 0.0)) <= slack[:, 0])
    radius = mu * (lam_n + extra[0])
    size = np.linalg.norm(lam[:, 1:], axis=-1)
    slip = np.linalg.norm(v[:, 1:], axis=-1)
    tangent_slack = np.hypot(slack[:, 1], slack[:, 2])
    # The disk step scales λ_t onto the circle and rotates it back by the eigenvectors of A_tt
    # (orthogonal to rounding): a few roundings, 8 ε relative.
    assert np.all(size <= radius * (1 + 8 * EPS))
    sliding = slip > tangent_slack
    sticking = size < radius * (1 - 8 * EPS)
    assert np.all(slip[sticking] <= tangent_slack[sticking])
    # Sliding: on the circle and opposing the slip. After the contact's update v_t = −γ λ_t; the
    # later updates move v_t by at most the slack, so |v_t + |v_t| λ̂_t| ≤ 2 slack, i.e. the
    # angle between λ_t and −v_t is at most 2 slack / |v_t| and |λ_t + ρ v̂_t| ≤ 2 ρ slack / |v_t|.
    # A radius at rounding of the element's loads (ρ ≤ 100 ε max λ_n: a corner loaded by
    # rounding only) takes the disk step's radial branch instead, within 2 ρ of any direction:
    # an allowance of 2 × 100 ε max λ_n.
    assert np.all(size[sliding] >= radius[sliding] * (1 - 8 * EPS))
    unit_slip = v[:, 1:] / np.where(slip > 0, slip, 1.0)[:, None]
    opposed = np.linalg.norm(lam[:, 1:] + radius[:, None] * unit_slip, axis=-1)
    allowed = 2 * radius * tangent_slack / np.where(slip > 0, slip, 1.0)
    allowed += 2 * 100 * EPS * np.max(lam_n)
    assert np.all(opposed[sliding] <= allowed[sliding])


def test_newton_answer_equals_a_long_gauss_seidel_run():
    a, free, target, mu, extra, settings = contact_problem()
    lam, *_ = solve(a, free, target, mu, extra, settings)
    c = target.shape[1]
    reference = np.zeros(3 * c)
    sweeps, converged = gauss_seidel(
        a[0],
        free[0].ravel(),
        target[0],
        mu,
        reference,
        extra[0],
        3,
        200_000,
        1e-15,
        velocity_scale(free[0].ravel(), target[0]),
        np.empty(WORK_PER_CONTACT * c),
    )
    assert converged and sweeps > settings.max_iterations  # a long run indeed
    reference = reference.reshape(c, 3)
    bound = velocity_bound(a, free, target, mu, extra, lam, reference)
    change = np.linalg.norm(a[0] @ (lam.ravel() - reference.ravel()))
    assert change <= bound


def test_batched_step_equals_each_element_alone():
    scene = landing_scene()
    both = scene.initial_state(
        position=[[POSITION], [POSITION_2]], orientation=[[ORIENTATION], [ORIENTATION_2]]
    )
    out = scene.step(both, body_torque=[[TORQUE], [TORQUE_2]])
    assert scene.report["contacts"].capped == 0
    for i, (x, q, t) in enumerate(
        [(POSITION, ORIENTATION, TORQUE), (POSITION_2, ORIENTATION_2, TORQUE_2)]
    ):
        alone = scene.step(scene.initial_state(position=x, orientation=q), body_torque=[t])
        for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
            assert np.array_equal(getattr(out, field)[i], getattr(alone, field))


@pytest.mark.parametrize(
    "name, value",
    [("newton_after", 0), ("newton_after", 2.5), ("newton_steps", -1), ("newton_steps", True)],
)
def test_newton_settings_are_validated(name, value):
    with pytest.raises(ValueError, match=name):
        sim.SolverSettings(**{name: value})
    assert sim.SolverSettings(**{name: 1}).__getattribute__(name) == 1  # the next call works


# Two steps of a BoxLanding-v0 rollout under a trained PPO policy where the Newton polish stalls
# on a change of contact mode it cannot see (``newton.CRAWL_STEP``'s note): without jumps along
# G's null direction the first stops at the cap; the second's polish then leaves λ worse and is
# undone, and Gauss–Seidel alone converges (``solve.converge``). (position, orientation,
# velocity, angular velocity, body torque) before the step.
STALLS = {
    "after an impact": (
        [-0.18883042278527906, 0.159609038913498, 0.2002247011516451],
        [0.00019336544245523483, 0.0007219133802784401, -0.9656362980150791, -0.2598960973285488],
        [-0.030141478060073834, 0.03198859458841607, -0.09587513285986526],
        [-0.5547282835116276, 0.32219655732148433, 0.32387846725147645],
        [-0.6255986094474792, 0.22248294949531555, -0.22121697664260864],
    ),
    "settling on a face": (
        [-0.009102139901015032, 0.12292576402910617, 0.20008367569039776],
        [0.0001895257817476403, 0.00037278951253777605, 0.45319304230770896, -0.8914123016381591],
        [0.029061341908146424, -0.03984934827435047, -0.024566172668431557],
        [0.19906166473143683, 0.1451717368057606, -1.3877787807814457e-17],
        [-0.07756172865629196, -0.5876874327659607, -0.21998272836208344],
    ),
}


def stalled_step(scene, name):
    x, q, v, w, torque = STALLS[name]
    state = scene.initial_state(position=x, orientation=q, linear_velocity=v, angular_velocity=w)
    scene.step(state, body_torque=[torque])
    return scene.report["contacts"]


@pytest.mark.parametrize("name", STALLS)
def test_newton_jumps_past_the_mode_change_that_stalls_it(name):
    report = stalled_step(landing_scene(), name)
    assert report.engaged == 1 and report.newton > 0
    assert report.capped == 0


# A box of the speed bench's landing scene (Δt = 0.01 s, 1 s after the drop) settling on a face,
# its four lowest corners 0.04-0.1 mm above the ground (speculative contacts, all four loaded
# by the answer). Gauss–Seidel alone converges in 30 sweeps; the Newton polish after the first round carries λ ~1e-2 N s along the null space of
# the face's corners (the next sweep changes a velocity 3e4× more than the last sweep before
# it), from where Gauss–Seidel crawls: before the polish was judged, the step stopped at the
# cap (500 sweeps, 50 Newton steps) on both backends.
WORSE_POLISH = (
    [0.035706976254310865, -0.06317129199706589, 0.20006819375589388],
    [9.872175936495912e-05, 2.3558847364784406e-05, 0.2321208947239867, 0.9726869382959404],
    [0.0038415718562678112, -0.007590549605262682, 0.014241802025152232],
    [0.0380039132207675, 0.019233753950533873, -5.949549034796867e-18],
)


def test_a_polish_that_leaves_the_sweeps_worse_is_undone():
    x, q, v, w = WORSE_POLISH
    results = []
    for settings in (None, sim.SolverSettings(newton_steps=0)):
        scene = sim.Scene(
            sim.Body.box((0.1, 0.15, 0.2), 1.0),
            0.01,
            integrator="implicit_gyro",
            gravity=(0.0, 0.0, -9.81),
            ground=sim.Ground(restitution=0.3, friction=0.5),
            contact_solver=settings,
        )
        state = scene.initial_state(
            position=x, orientation=q, linear_velocity=v, angular_velocity=w
        )
        results.append((scene.step(state), scene.report["contacts"]))
    (polished, report), (plain, plain_report) = results
    assert report.newton > 0 and report.capped == 0 and plain_report.capped == 0
    # Undone: λ is where the sweeps had it, so the step is Gauss–Seidel's, bit for bit, after
    # one more sweep (the one that judged the polish).
    assert report.iterations == plain_report.iterations + 1
    for field in ("position", "orientation", "linear_velocity", "angular_velocity"):
        assert np.array_equal(getattr(polished, field), getattr(plain, field))


def quadratic_roots(c0, c1, c2):
    """The kernel's roots of c0 + 2 c1 s + c2 s², (N, 2) with NaN where there are fewer."""
    out = np.full((len(c0), 2), np.nan)
    for k in range(len(c0)):
        compiled_newton.quadratic_roots(c0[k], c1[k], c2[k], out[k], 0)
    return out


def test_quadratic_roots_are_the_real_roots():
    rng = np.random.default_rng(0)
    c0, c1, c2 = rng.normal(size=(3, 200))
    c2[:20] = 0.0  # linear
    c1[:5] = 0.0  # and constant: no root
    roots = quadratic_roots(c0, c1, c2)
    for k in range(200):
        expected = np.roots([c2[k], 2 * c1[k], c0[k]])
        expected = np.sort(expected[np.abs(expected.imag) == 0].real)
        found = np.sort(roots[k][np.isfinite(roots[k])])
        assert len(found) == len(expected)
        # Backward stable: each root is exact for coefficients perturbed by a few ε
        # relative, so it errs by at most that perturbation of p over |p'| (the condition of a
        # simple root: Wilkinson, "Rounding Errors in Algebraic Processes", 1963); 100 ε covers
        # both computations' few roundings.
        size = np.abs(c2[k]) * expected**2 + 2 * np.abs(c1[k] * expected) + np.abs(c0[k])
        slope = np.abs(2 * c2[k] * expected + 2 * c1[k])
        assert np.all(np.abs(found - expected) <= 100 * EPS * size / slope)


def test_mode_events_are_where_a_contact_changes_mode():
    a, free, target, mu, extra, _ = contact_problem()
    rng = np.random.default_rng(1)
    lam = np.abs(rng.normal(scale=0.05, size=free.shape))
    x = rng.normal(size=(1, free[0].size))
    x /= np.linalg.norm(x)

    def at(s):
        return residual(a, free, target, mu, extra, lam + s * x.reshape(lam.shape))[1:]

    def flips(s, t):
        return compiled_newton.mode_changed(*at(t), *at(s))

    _, z_n, z_t, rho = residual(a, free, target, mu, extra, lam)
    events = np.full(5 * z_n.shape[0], np.nan)
    count = compiled_newton.mode_events(a[0], mu, extra[0], z_n, z_t, rho, x[0], events)
    events = np.sort(events[:count][np.isfinite(events[:count])])
    assert len(events) > 0
    # Across each event some contact's mode flips (1e-7 relative: far above the roots'
    # rounding, below the gaps between events, checked); between events none does.
    assert np.all(np.diff(events) > 1e-6 * np.abs(events[1:]))
    for s in events:
        assert flips(s * (1 - 1e-7), s * (1 + 1e-7))
    for lo, hi in zip(events[:-1], events[1:], strict=True):
        inside = np.linspace(lo, hi, 12)[1:-1]
        assert not any(flips(inside[0], s) for s in inside[1:])
