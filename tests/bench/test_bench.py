"""The benchmark commands run, write well-formed JSON, and measure what they claim.

Each command runs in its ``tiny`` preset (seconds): same code paths as the full run, fewer and
shorter cases. Speed figures are never asserted (timings are machine noise); their presence,
positivity and finiteness are.
"""

from __future__ import annotations

import json
import math

import pytest

from rigid_env import sim
from rigid_env.bench import __main__ as cli
from rigid_env.bench import accuracy, peers, problems, stability


def _finite_or_none(obj) -> bool:
    if isinstance(obj, dict):
        return all(_finite_or_none(v) for v in obj.values())
    if isinstance(obj, list):
        return all(_finite_or_none(v) for v in obj)
    return not isinstance(obj, float) or math.isfinite(obj)


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
    ours = [r for r in doc["records"] if r["engine"] == "rigid_env"]
    assert {r["integrator"] for r in ours} == set(sim.INTEGRATORS)
    assert {r["batch"] for r in ours} == {1, accuracy.BATCH}
    assert {r["scene"] for r in ours} >= {
        "dzhanibekov",
        "symmetric_top",
        "spin_up",
        "damped_spring",
    }
    for r in ours:
        for key in (
            "orientation_error",
            "angular_velocity_error",
            "energy_drift",
            "momentum_drift",
            "wall_s_per_sim_s",
        ):
            assert r[key] is not None and r[key] >= 0, (r["scene"], r["integrator"], key)
    assert set(doc["observed_order"]) == set(sim.INTEGRATORS)
    assert [(t["batch"], t["target_rad"]) for t in doc["targets"]] == [
        (b, t) for b in (1, accuracy.BATCH) for t in accuracy.TARGETS
    ]


def test_observed_orders_match_theory(runs):
    # The tolerance: |observed - theoretical| <= 0.3. The tiny preset's dt pairs sit in
    # each method's asymptotic range on the 1 s Dzhanibekov run (errors 1e-9 .. 1e-2 rad).
    for name, info in runs["accuracy"]["observed_order"].items():
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
        "integrate (core, no forces)",
        "rest of Scene.step (checks, force sum)",
        "step total",
    ]
    assert doc["memory"]["free_body"]["state_bytes_per_body"] == 13 * 8


@pytest.mark.skipif(not peers.available(), reason="mujoco (extra 'peers') not installed")
def test_mujoco_runs_the_same_free_body(runs):
    mj = [r for r in runs["accuracy"]["records"] if r["engine"] == "mujoco"]
    assert {r["integrator"] for r in mj} == set(peers.INTEGRATORS)
    # MuJoCo's Euler on the same 1 s Dzhanibekov problem: first-order error, far below 1 rad
    # and above rounding, so the two engines really integrate the same body.
    euler = [r for r in mj if r["integrator"] == "Euler" and r["batch"] == 1]
    assert all(1e-6 < r["error"] < 0.1 for r in euler)


def test_problems_start_on_their_reference():
    # Each reference at t = 0 must equal the problem's own initial state (else every error
    # figure is offset by a constant).
    import numpy as np

    for problem in problems.all_problems():
        scene = problem.build("splitting", 0.01)
        start = scene.initial_state(**problem.initial)
        ref = problem.reference(np.array([0.0]))
        for key, value in ref.items():
            assert np.allclose(getattr(start, key)[0], value[0], atol=1e-12), (problem.name, key)
