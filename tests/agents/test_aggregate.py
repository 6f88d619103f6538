"""Statistics of a sweep (agents.stats) against values computed by hand."""

from __future__ import annotations

import numpy as np
import pytest

from agents import stats


def test_iqm_cuts_a_quarter_of_the_runs_from_each_end():
    # 8 runs: int(8 / 4) = 2 cut from each end, the middle 3, 4, 5, 6 averaged.
    assert stats.iqm([8, 1, 7, 2, 6, 3, 5, 4]) == pytest.approx(4.5)
    # 5 runs: 1 cut from each end: mean of 2, 3, 4.
    assert stats.iqm([5, 1, 4, 2, 3]) == pytest.approx(3.0)
    # Outliers move the mean, not the IQM: 25.5 against 1.
    scores = [0, 0, 1, 1, 1, 1, 100, 100]
    assert np.mean(scores) == pytest.approx(25.5)
    assert stats.iqm(scores) == pytest.approx(1.0)
    # Fewer than 4 runs: nothing to cut, the IQM is the mean.
    assert stats.iqm([1.0, 2.0, 6.0]) == pytest.approx(3.0)


def test_bootstrap_interval_of_two_runs_is_their_range():
    # Resampling two runs {0, 1} with replacement gives means 0, 1/2, 1 with probabilities
    # 1/4, 1/2, 1/4: the 2.5th percentile is 0 and the 97.5th is 1, exactly.
    for statistic in ("mean", "iqm"):
        low, high = stats.bootstrap_ci([0.0, 1.0], statistic)
        assert (float(low), float(high)) == (0.0, 1.0)


def test_bootstrap_interval_of_a_tight_sample_contains_its_mean_and_is_narrow():
    rng = np.random.default_rng(3)
    tight = 10.0 + 0.01 * rng.standard_normal(20)
    wide = 10.0 + 1.0 * rng.standard_normal(20)
    for statistic in ("mean", "iqm"):
        low, high = stats.bootstrap_ci(tight, statistic)
        assert low <= np.mean(tight) <= high
        # The standard error of the mean is 0.01 / sqrt(20) ≈ 0.0022: a 95 % interval is about
        # ±2 standard errors, well inside ±0.01 (the spread of one run).
        assert high - low < 0.02
        wide_low, wide_high = stats.bootstrap_ci(wide, statistic)
        assert wide_high - wide_low > 20 * (high - low)


def test_bootstrap_is_seeded_and_vectorised_over_points():
    x = np.array([[0.0, 5.0], [1.0, 5.0], [2.0, 5.0], [9.0, 5.0]])
    low_a, high_a = stats.bootstrap_ci(x, "mean", seed=1)
    low_b, high_b = stats.bootstrap_ci(x, "mean", seed=1)
    np.testing.assert_array_equal(low_a, low_b)
    np.testing.assert_array_equal(high_a, high_b)
    assert low_a.shape == (2,)
    # The constant column has the constant as both bounds; the other brackets its mean 3.
    assert (low_a[1], high_a[1]) == (5.0, 5.0)
    assert low_a[0] < 3.0 < high_a[0]
    # Column by column it is the one-dimensional interval.
    low0, high0 = stats.bootstrap_ci(x[:, 0], "mean", seed=1)
    assert (low0, high0) == (low_a[0], high_a[0])


def test_single_run_has_no_interval_and_bad_input_names_the_parameter():
    low, high = stats.bootstrap_ci([3.0])
    assert np.isnan(low) and np.isnan(high)
    summary = stats.summarize([3.0])
    assert summary["mean"] == summary["iqm"] == 3.0 and np.isnan(summary["mean_ci"][0])
    with pytest.raises(ValueError, match="scores"):
        stats.summarize([])
    with pytest.raises(ValueError, match="scores"):
        stats.bootstrap_ci([1.0, np.nan])
    with pytest.raises(ValueError, match="statistic"):
        stats.bootstrap_ci([1.0, 2.0], "median")
    with pytest.raises(ValueError, match="confidence"):
        stats.bootstrap_ci([1.0, 2.0], confidence=95)


def _trial(key, seed, finals, config=None):
    steps = [100 * (i + 1) for i in range(len(finals))]
    rows = [
        {"env_steps": s, "mean_return": r, "success_rate": p}
        for s, (r, p) in zip(steps, finals, strict=True)
    ]
    return {"config_key": key, "config": config or {}, "seed": seed, "evaluations": rows}


def test_aggregate_groups_by_config_and_summarises_the_final_evaluation():
    trials = [
        _trial("a", 1, [(-9.0, 0.0), (-3.0, 0.0)], {"lr": 1}),
        _trial("b", 0, [(-1.0, 1.0), (-1.0, 1.0)], {"lr": 2}),
        _trial("a", 0, [(-7.0, 0.0), (-1.0, 1.0)], {"lr": 1}),
    ]
    by_key = {e["config_key"]: e for e in stats.aggregate(trials)}
    a = by_key["a"]
    assert a["seeds"] == [0, 1] and a["config"] == {"lr": 1}
    # Final (last) evaluations of a: returns -1 (seed 0) and -3 (seed 1); success 1 and 0.
    assert [f["mean_return"] for f in a["final"]] == [-1.0, -3.0]
    assert a["mean_return"]["mean"] == pytest.approx(-2.0)
    assert a["mean_return"]["iqm"] == pytest.approx(-2.0)
    assert a["mean_return"]["mean_ci"] == [-3.0, -1.0]  # two runs: their range (see above)
    assert a["success_rate"]["mean"] == pytest.approx(0.5)
    # Learning curve: per step the mean over seeds: step 100: (-7 - 9) / 2, step 200: (-1 - 3) / 2.
    curve = a["curves"]["mean_return"]
    assert curve["env_steps"] == [100, 200]
    assert curve["mean"] == pytest.approx([-8.0, -2.0])
    assert curve["ci_low"] == [-9.0, -3.0] and curve["ci_high"] == [-7.0, -1.0]
    b = by_key["b"]
    assert b["mean_return"]["n"] == 1 and b["mean_return"]["mean"] == -1.0


def test_curve_uses_only_the_steps_every_run_reached():
    runs = [
        [{"env_steps": 100, "x": 1.0}, {"env_steps": 200, "x": 3.0}],
        [{"env_steps": 100, "x": 2.0}, {"env_steps": 200, "x": 5.0}, {"env_steps": 300, "x": 9.0}],
    ]
    curve = stats.curve(runs, "x")
    assert curve["env_steps"] == [100, 200]
    assert curve["mean"] == pytest.approx([1.5, 4.0])
