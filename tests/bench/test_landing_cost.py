"""``python -m rigid_env.bench.landing_cost`` on a small batch: the classes partition the batch,
each class is what a batched step of its elements reports, and the shares add up.

Timings are machine noise and never asserted; the classification and the arithmetic are.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rigid_env import sim
from rigid_env.bench import landing_cost


def test_each_class_is_what_a_batched_step_of_its_elements_reports():
    scene, state = landing_cost.landing_batch(64)
    kinds = landing_cost.classify(scene, state)
    assert kinds.shape == (64,) and set(kinds) <= set(range(len(landing_cost.CLASSES)))
    assert len(set(kinds)) >= 2  # the pre-rolled batch is not all one case
    for k in set(kinds):
        members = np.flatnonzero(kinds == k)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sim.ContactSolverWarning)
            scene.step(state[members])
        report = scene.report["contacts"]
        name = landing_cost.CLASSES[k]
        if name == "in flight":
            assert report.engaged == 0
            continue
        assert report.engaged == len(members)
        assert report.capped == (len(members) if name == "capped" else 0)
        low, high = {
            "first sweep": (1, 1),
            "2-20 sweeps": (2, 20),
            "over 20 sweeps": (21, sim.SolverSettings().max_iterations),
            "capped": (1, math.inf),
        }[name]
        assert low <= report.iterations <= high  # the batch's most sweeps


def test_the_table_adds_up(capsys):
    assert landing_cost.main(["--batch", "16", "--block", "0.001", "--repeats", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {}
    for line in lines[2:]:
        name, values = line[:16].strip(), line[16:].split()
        rows[name] = values
    assert list(rows)[: len(landing_cost.CLASSES) + 1] == [*landing_cost.CLASSES, "batch"]
    shares = [float(rows[c][0].rstrip("%")) for c in landing_cost.CLASSES]
    times = [float(rows[c][2].rstrip("%")) for c in landing_cost.CLASSES]
    assert sum(shares) == pytest.approx(100.0, abs=0.1 * len(shares))  # printed to 0.1 %
    assert sum(times) == pytest.approx(100.0, abs=0.1 * len(times))
    # 16 elements: every share is a whole number of sixteenths
    for share in shares:
        assert round(share * 16 / 100) == pytest.approx(share * 16 / 100, abs=0.02)


def test_a_bad_batch_is_named():
    with pytest.raises(ValueError, match="batch"):
        landing_cost.main(["--batch", "0"])
