"""The Reorient frame comparison (``bench.reorient_frame``) on a short run."""

from rigid_env.bench import reorient_frame


def test_exact_at_one_step_per_frame_against_finer_stepping():
    rows = reorient_frame.accuracy(
        2,
        0,
        frames=20,
        configs=(("exact", 0.05, 1), ("exact4", 0.05, 1), ("splitting", 0.01, 5)),
        held=(("exact", 0.05, 1),),
    )
    tumble = {r["config"][0]: r["max"] for r in rows if r["case"] == "tumble (action 0)"}
    # Torque-free, exact is the flow: 20 steps of ≤ 64 ε (1 + |ω| Δt) + 4 ε (|ω| ≤ 2 rad/s),
    # plus the closed-form reference's 4e-11 (near the separatrix: a quarter of the episodes
    # start tumbling there); splitting's phase error is (ω Δt)² ω t ≳ 1e-7.
    assert tumble["exact"] < 4e-11 + 20 * (64 * 2.2e-16 * 1.1 + 4 * 2.2e-16)
    assert tumble["splitting"] > 1e3 * tumble["exact"]
    driven = {r["config"][0]: r["max"] for r in rows if r["case"] == "random actions"}
    held = [r["max"] for r in rows if r["case"].endswith("held in world (former)")]
    # Held in the world over a step, a body torque errs by ~½ Δt² |Ω| |τ| / I a step (first
    # order); turned at each kick, Strang errs by ~Δt³ |Ω|² |τ| / (12 I) (second order): a
    # ratio ~6 / (|Ω| Δt) ≈ 60 at |Ω| ≈ 2 rad/s, Δt = 0.05 s; asserted with a margin, 10.
    assert driven["exact"] < held[0] / 10
    # The triple jump is fourth order: the second-order error times ~(|Ω| Δt)² = 1e-2 up to
    # constants of order one; asserted at 1/10.
    assert driven["exact4"] < driven["exact"] / 10
