"""The Reorient frame comparison (``bench.reorient_frame``) on a short run."""

from rigid_env.bench import reorient_frame


def test_exact_at_one_step_per_frame_beats_five_splitting_steps_on_a_tumble():
    rows = reorient_frame.accuracy(
        2, 0, frames=20, configs=(("exact", 0.05, 1), ("splitting", 0.01, 5))
    )
    tumble = {r["config"][0]: r["max"] for r in rows if r["case"] == "tumble (action 0)"}
    # Torque-free, exact is the flow: 20 steps of ≤ 64 ε (1 + |ω| Δt) + 4 ε (|ω| ≤ 2 rad/s),
    # plus the closed-form reference's 4e-11 (near the separatrix: a quarter of the episodes
    # start tumbling there); splitting's phase error is (ω Δt)² ω t ≳ 1e-7.
    assert tumble["exact"] < 4e-11 + 20 * (64 * 2.2e-16 * 1.1 + 4 * 2.2e-16)
    assert tumble["splitting"] > 1e3 * tumble["exact"]
    kicks = [r for r in rows if r["case"].endswith("body-frame kicks (proposal)")]
    driven = {r["config"][0]: r["max"] for r in rows if r["case"] == "random actions"}
    # The body-fixed torque held in world axes for a whole frame is first order; body-frame
    # kicks around the exact flow are second order: far smaller at the same frame.
    assert kicks[0]["max"] < driven["exact"]
