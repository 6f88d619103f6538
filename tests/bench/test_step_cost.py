"""``python -m rigid_env.bench.step_cost`` runs on both batch-1 cases and prints every part.

Timings are machine noise and never asserted; their presence and finiteness are, and that the
differences are the differences of the figures printed (a breakdown whose parts do not add up
to its totals would mislead).
"""

from __future__ import annotations

import math

import pytest

from rigid_env.bench import step_cost


def test_step_cost_prints_each_part_of_both_cases(capsys):
    assert step_cost.main(["--block", "0.002", "--repeats", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split() == list(step_cost.CASES)
    rows = {line[:24].strip(): [float(v) for v in line[24:].split()] for line in lines[2:]}
    assert list(rows) == [
        "bench row",
        "Scene.step",
        "driver call",
        "kernel",
        "empty kernel",
        "Python in Scene.step",
        "Python in the driver",
        "physics in the kernel",
    ]
    for values in rows.values():
        assert len(values) == len(step_cost.CASES)
        assert all(math.isfinite(v) for v in values)
    for i in range(len(step_cost.CASES)):
        col = {key: values[i] for key, values in rows.items()}
        for part, (total, inner) in {
            "Python in Scene.step": ("Scene.step", "driver call"),
            "Python in the driver": ("driver call", "kernel"),
            "physics in the kernel": ("kernel", "empty kernel"),
        }.items():
            assert col[part] == pytest.approx(col[total] - col[inner], abs=0.011)  # 2 decimals
