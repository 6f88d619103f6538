"""The benchmark commands run, write well-formed JSON, and measure what they claim.

Each command runs in its ``tiny`` preset (seconds): same code paths as the full run, fewer and
shorter cases. Speed figures are never asserted (timings are machine noise); their presence,
positivity and finiteness are.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench import __main__ as cli
from rigid_env.bench import accuracy, bounce, contact_cases, peers, problems, speed, stability


def _finite_or_none(obj) -> bool:
    if isinstance(obj, dict):
        return all(_finite_or_none(v) for v in obj.values())
    if isinstance(obj, list):
        return all(_finite_or_none(v) for v in obj)
    return not isinstance(obj, float) or math.isfinite(obj)


def assert_errors_shrink_with_dt(records: list[dict], keys: tuple[str, ...]) -> None:
    """Each error of each (scene, integrator, batch) is smaller at its smallest dt than at its
    largest: the methods are consistent (order >= 1), so a smaller step must shrink a truncation
    error, unless both sit at the rounding floor (below 100 ε per step over the run, the same
    floor accuracy.observed_order uses), where only rounding is left to compare. An error scored
    against the wrong reference or the wrong time does not shrink with dt."""
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r["scene"], r["integrator"], r["batch"]), []).append(r)
    for group, rs in groups.items():
        coarse, fine = max(rs, key=lambda r: r["dt"]), min(rs, key=lambda r: r["dt"])
        assert fine["dt"] < coarse["dt"], group
        floor = accuracy.ROUNDING_PER_STEP * 1e3  # ≥ the steps of any tiny-preset run
        for key in keys:
            assert math.isfinite(coarse[key]) and math.isfinite(fine[key]), (group, key)
            if coarse[key] > floor:
                assert fine[key] < coarse[key], (group, key, coarse[key], fine[key])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("reports")
    assert cli.main(["all", "--preset", "tiny", "--out", str(out)]) == 0
    docs = {}
    for command in cli.COMMANDS:
        assert (out / f"{command}.png").stat().st_size > 0
        docs[command] = json.loads((out / f"{command}.json").read_text())
    return docs


def test_every_command_writes_well_formed_json(runs):
    for command, doc in runs.items():
        assert doc["command"] == command and doc["preset"] == "tiny"
        assert doc["records"], command
        assert _finite_or_none(doc), f"{command}.json holds a NaN or infinity"
        for record in doc["records"]:
            for key in ("scene", "integrator", "dt", "batch"):
                assert key in record, (command, key)


def test_accuracy_records_hold_errors_and_costs(runs):
    doc = runs["accuracy"]
    ours = [
        r
        for r in doc["records"]
        if r["engine"] == "rigid_env" and not r["scene"].startswith("first_bounce")
    ]
    assert {r["integrator"] for r in ours} == set(sim.INTEGRATORS)
    assert {r["batch"] for r in ours} == {1, accuracy.BATCH}
    assert {r["scene"] for r in ours} >= {
        "dzhanibekov",
        "symmetric_top",
        "spin_up",
        "damped_spring",
    }
    assert all(r["wall_s_per_sim_s"] > 0 for r in ours)
    assert_errors_shrink_with_dt(
        ours, ("orientation_error", "angular_velocity_error", "energy_drift", "momentum_drift")
    )
    assert set(doc["observed_order"]) == set(sim.INTEGRATORS)
    assert [(t["batch"], t["target_rad"]) for t in doc["targets"]] == [
        (b, t) for b in (1, accuracy.BATCH) for t in accuracy.TARGETS
    ]


def test_observed_orders_match_theory(runs):
    # The tolerance: |observed - theoretical| <= 0.3. The tiny preset's dt pairs sit in
    # each method's asymptotic range on the 1 s Dzhanibekov run (errors 1e-9 .. 1e-2 rad).
    # The exact-flow methods are exact on the torque-free problem (rounding only, no order to
    # fit there); their order shows on the next problem with a force (the damped spring).
    for name, info in runs["accuracy"]["observed_order"].items():
        if name in ("exact", "exact4"):
            assert info["by_scene"]["dzhanibekov"] is None, name
        else:
            assert info["observed_on"] == "dzhanibekov", name
        assert abs(info["observed"] - info["theoretical"]) <= 0.3, (name, info)


def test_order_fit_ignores_rounding_floor_and_preasymptotic_points():
    dts = [0.1, 0.05, 0.025, 0.0125]
    assert accuracy.observed_order(dts, [0.5, 4e-3, 1e-3, 2.5e-4]) == pytest.approx(2.0)
    # Exact to rounding (1e-13 after 1 s of up to 80 steps, below 100 ε per step): no order.
    assert accuracy.observed_order(dts, [1e-13] * 4, duration=1.0) is None


def test_stability_detects_explicit_divergence_on_a_stiff_spring():
    # k Δt²/m = 1e4 puts ω Δt = 100 far outside every explicit method's stability interval
    # (|ω Δt| < 2 for symplectic Euler/Verlet, < 2.83 for RK4): the energy must blow up.
    case = next(c for c in stability.cases("tiny") if c.name == "stiff spring kΔt²/m=10000")
    cell = stability.run_case(case, "euler")
    assert cell["status"] == "diverged" and not cell["stable"]
    assert isinstance(cell["first_divergence_step"], int) and cell["first_divergence_step"] >= 1
    assert _finite_or_none(cell)


def test_stability_reports_a_nonfinite_step_as_divergence():
    # A spring so stiff that one explicit step overflows to infinity: the DivergenceError path.
    case = stability.Case(
        "overflow",
        "stiff_spring",
        lambda i: sim.Scene(
            [sim.Body.sphere(0.1, 1.0)],
            0.01,
            integrator=i,
            springs=[sim.Spring(0, (0, 0, 0), 1e305)],
        ),
        {"position": (1e10, 0.0, 0.0)},
        5,
        False,
    )
    cell = stability.run_case(case, "euler")
    assert cell["status"] == "diverged" and cell["first_divergence_step"] == 1


def test_stability_marks_a_well_resolved_free_body_stable(runs):
    cells = [
        r
        for r in runs["stability"]["records"]
        if r["scene"] == "dt=1e-6 free body" and r["integrator"] == "splitting"
    ]
    assert cells and cells[0]["status"] == "stable" and cells[0]["energy_drift"] < 1e-10


def test_speed_records_cover_every_integrator_and_breakdown(runs):
    doc = runs["speed"]
    free = [r for r in doc["records"] if r["scene"] == "free_body" and r["engine"] == "rigid_env"]
    assert {r["integrator"] for r in free} == set(sim.INTEGRATORS)
    assert all(r["body_steps_per_s"] > 0 for r in doc["records"])
    rows = doc["stage_breakdown"]["free_body"]
    # A free body lists only "integrate": no force term or contact stage appears in its step.
    assert rows["stages"] == ["integrate"]
    assert [r["stage"] for r in rows["rows"]] == [
        "Scene.step's input validation",
        "compiled kernel (integrate)",
        "Scene.step's finiteness check",
        "step total (instrumented)",
    ]
    assert doc["memory"]["free_body"]["state_bytes_per_body"] == 13 * 8


@pytest.mark.skipif(not peers.available(), reason="mujoco (extra 'peers') not installed")
def test_mujoco_runs_the_same_free_body(runs):
    mj = [r for r in runs["accuracy"]["records"] if r["engine"] == "mujoco"]
    assert {r["integrator"] for r in mj} == set(peers.INTEGRATORS)
    assert {r["scene"] for r in mj} == {"dzhanibekov", "first_bounce_flat", "first_bounce_corner"}
    # MuJoCo's Euler on the same 1 s Dzhanibekov problem: first-order error, far below 1 rad
    # and above rounding, so the two engines really integrate the same body.
    euler = [
        r
        for r in mj
        if r["integrator"] == "Euler" and r["batch"] == 1 and r["scene"] == "dzhanibekov"
    ]
    assert all(1e-6 < r["error"] < 0.1 for r in euler)


def test_problems_start_on_their_reference():
    # Each reference at t = 0 must equal the problem's own initial state (else every error
    # figure is offset by a constant).
    for problem in problems.all_problems():
        scene = problem.build("splitting", 0.01)
        start = scene.initial_state(**problem.initial)
        ref = problem.reference(np.array([0.0]))
        for key, value in ref.items():
            assert np.allclose(getattr(start, key)[0], value[0], atol=1e-12), (problem.name, key)


# --- contacts: first bounce, contact stability cases, contact scenes in speed -------------------


def test_first_bounce_records_cover_contact_integrators(runs):
    recs = [r for r in runs["accuracy"]["records"] if r["scene"].startswith("first_bounce")]
    ours = [r for r in recs if r["engine"] == "rigid_env"]
    assert {r["scene"] for r in ours} == {"first_bounce_flat", "first_bounce_corner"}
    assert {r["integrator"] for r in ours} == set(bounce.integrators())
    assert {r["batch"] for r in ours} == {1, accuracy.BATCH}
    assert all(r["wall_s_per_sim_s"] > 0 for r in ours)
    assert_errors_shrink_with_dt(ours, ("velocity_error", "momentum_error"))
    assert all("apex_error" in r for r in ours if r["scene"] == "first_bounce_flat")


def test_closed_form_obeys_newtons_restitution_law():
    # The impulse formula must leave the struck corner separating at −ε times its approach
    # speed, with no tangential impulse (frictionless) — else the reference itself is wrong.
    drop = bounce.drops()[1]
    cf = bounce.closed_form(drop)
    assert not cf["flat"]
    n = np.array([0.0, 0.0, 1.0])
    corner_after = cf["v_plus"] + np.cross(cf["w_plus"], cf["arm"])
    assert corner_after @ n == pytest.approx(-drop.restitution * (cf["v_minus"] @ n), rel=1e-12)
    assert np.allclose(cf["v_plus"][:2], 0.0, atol=1e-15)
    assert cf["t_check"] > cf["t_hit"]


@pytest.mark.parametrize("name", ["flat", "corner"])
def test_first_bounce_matches_closed_form(name):
    # Tolerance: the impact falls somewhere inside a step and the simulator resolves it at the
    # step, so gravity's impulse m g Δt is misplaced by at most one step on each side of the
    # bounce: |Δv| <= (1 + ε) g Δt, and the angular impulse r × (j n) errs by |r| times that.
    # A wrong impulse law (e.g. the particle's instead of the rigid body's) errs by O(1).
    drop = next(d for d in bounce.drops() if d.name == name)
    dt = 1 / 240
    res = bounce.run(drop, "implicit_gyro", dt, phases=4)
    speed = np.sqrt(2 * bounce.GRAVITY * drop.height)
    bound = (1 + drop.restitution) * bounce.GRAVITY * dt / speed
    assert res["velocity_error"] <= bound, res
    assert res["momentum_error"] <= bound, res
    assert res["impact_time_error"] <= dt + 1e-12


def test_stability_contact_cells(runs):
    recs = runs["stability"]["records"]
    impact = [r for r in recs if r["group"] == "impact_speed"]
    assert impact and {r["scene"] for r in impact} == {"ground impact 100 m/s, dt=1/60"}
    for r in impact:
        if r["integrator"] in contact_cases.compatible():
            # Speculative contacts stop a 100 m/s box (1.7 m per step) at the ground: it must
            # not end below it, and the penetration left after projection is the rotation's
            # second-order term |r| (|ω| Δt)² / 2, millimetres for the box's spin here.
            assert r["tunnelled"] is False and r["status"] == "stable", r
            assert 0.0 <= r["max_penetration"] < 1e-2
        else:
            assert r["status"] == "n/a"
    ratio = [r for r in recs if r["group"] == "mass_ratio" and r["status"] != "n/a"]
    assert ratio
    for r in ratio:
        # Equal and opposite impulses conserve total momentum to rounding (~steps × ε).
        assert r["momentum_kind"] == "linear" and r["momentum_drift"] < 1e-12, r
        assert r["energy_drift"] < 1e-9, r  # an impact must not add energy


def test_stability_reports_tunnelling():
    # A box thrown down at 100 m/s in a scene with gravity but no ground ends below z = 0:
    # the matrix must call that tunnelling, not stable.
    box = sim.Body.box((0.1, 0.15, 0.2), 1.0)

    def build(integrator):
        scene = sim.Scene(box, 1 / 60, integrator=integrator, gravity=(0, 0, -9.81))
        state = scene.initial_state(position=(0, 0, 0.5), linear_velocity=(0, 0, -100.0))
        return scene, state, lambda s: np.maximum(-contact_cases.lowest_point(box, s)[..., 0], 0)

    case = stability.Case(
        "no ground", "impact_speed", build, None, 5, False, contact=True, ground=True
    )
    cell = stability.run_case(case, "implicit_gyro")
    assert cell["status"] == "tunnelled" and cell["tunnelled"] is True and not cell["stable"]
    assert cell["max_penetration"] > 1.0


def test_long_run_batches_initial_conditions(runs):
    longs = {r["integrator"]: r for r in runs["stability"]["records"] if r["group"] == "long_run"}
    assert longs["splitting"]["batch"] == len(stability.LONG_SPINS)
    assert longs["splitting"]["steps"] == 10 * longs["euler"]["steps"]


def test_speed_times_every_integrator(runs):
    """Every free-body integrator, each record saying how it stepped."""
    recs = [r for r in runs["speed"]["records"] if r["engine"] == "rigid_env"]
    free = {r["integrator"] for r in recs if r["scene"] == "free_body"}
    assert free == set(sim.INTEGRATORS)
    assert {r["backend"] for r in recs} == {"compiled"}
    assert runs["speed"]["stage_breakdown"]["free_body"]["backend"] == "compiled"


def test_speed_covers_contact_scenes_and_breakdowns_add_up(runs):
    doc = runs["speed"]
    assert {"two_body_impact", "landing"} <= {r["scene"] for r in doc["records"]}
    for name, info in doc["stage_breakdown"].items():
        parts = [r["s"] for r in info["rows"] if not r["stage"].startswith("step total")]
        total = info["rows"][-1]["s"]
        # Every part is timed by its own clock reads, disjoint intervals inside the step whose
        # total is read separately: the sum can only fall short of it (by the bookkeeping
        # between the parts), never exceed it; a part counted twice or timed outside the step
        # would. Each stage of the scene has its row.
        assert 0 < sum(parts) <= total, (name, info["rows"])
        assert all(p > 0 for p in parts), (name, info["rows"])
        stages = [r["stage"] for r in info["rows"][1:-2]]
        # One kernel call runs every stage: one row, naming them in order.
        assert stages == [f"compiled kernel ({' → '.join(info['stages'])})"], name
    assert doc["stage_breakdown"]["two_body_impact"]["stages"][1:5] == [
        "collide_pairs",
        "assemble_contacts",
        "restitute",
        "solve_contacts",
    ]


def test_compile_sentence_reports_processes_started_together():
    """The README's compile sentence quotes the probe's rows, the processes that started
    together (wall time of all) beside one cold process, when the run has them."""
    from rigid_env.bench import readme, speed

    rows = [
        {"case": c, "run": r, "first_step_s": f, "process_s": p}
        for c, r, f, p in [
            ("splitting", "cold", 5.0, 6.0),
            ("splitting", "cached", 0.4, 1.1),
            ("landing", "cold", 40.0, 41.5),
            ("landing", "cached", 0.5, 1.2),
            ("landing", "together", 44.0, 47.25),
        ]
    ]
    sentence = readme.compile_summary({"compile": rows})
    assert "40.0 s (0.5 s cached) for a box on the ground" in sentence
    assert f"{speed.TOGETHER} landing processes started together" in sentence
    assert "within 47.2 s (one alone: 41.5 s" in sentence
    without = readme.compile_summary({"compile": rows[:4]})
    assert "together" not in without


def test_the_compile_probe_builds_its_scenes_on_a_backend_the_scene_takes(tmp_path):
    """The probe processes read their backend from the environment it sets (a removed one,
    such as "auto", failed every speed run's compile probe)."""
    assert speed._probe_env(str(tmp_path))["RIGID_ENV_BACKEND"] in sim.BACKENDS
