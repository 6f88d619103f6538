"""``python -m rigid_env.bench.many_bodies`` in its ``tiny`` preset: one record per (scene,
engine, batch), positive times, finite drifts, and a bad ``--out`` refused before measuring.

Timings are machine noise and never asserted; their presence and positivity are.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rigid_env import cli
from rigid_env.bench import many_bodies, peers

TINY = many_bodies.PRESETS["tiny"]


@pytest.fixture(scope="module")
def doc(tmp_path_factory):
    out = tmp_path_factory.mktemp("reports")
    assert many_bodies.main(["--preset", "tiny", "--out", str(out)]) == 0
    return json.loads((out / "many_bodies.json").read_text())


def _records(doc, engine):
    return {(r["scene"], r["batch"]): r for r in doc["records"] if r["engine"] == engine}


def _check_engine(doc, engine):
    records = [r for r in doc["records"] if r["engine"] == engine]
    keys = [(r["scene"], r["batch"]) for r in records]
    assert sorted(keys) == sorted((s, b) for s in TINY.scenes for b in TINY.batches)
    for r in records:
        assert r["bodies"] == many_bodies.body_count(r["scene"])
        assert r["steps_timed"] >= 1
        assert r["s_per_step"] > 0 and r["us_per_step"] > 0 and r["us_per_body_step"] > 0
        assert r["us_per_body_step"] == pytest.approx(r["us_per_step"] / (r["bodies"] * r["batch"]))
        if r["batch"] == 1:  # every tiny scene is a resting one
            assert math.isfinite(r["drift_mm"]) and r["drift_mm"] >= 0
            assert r["drift_steps"] == TINY.drift_steps
    return records


def test_rigid_env_records_are_well_formed(doc):
    assert doc["command"] == "many_bodies" and doc["preset"] == "tiny"
    assert doc["settings"]["drift_steps"] == TINY.drift_steps
    for r in _check_engine(doc, many_bodies.ENGINE):
        assert r["steps_timed"] <= TINY.steps + 1
        if r["batch"] == 1:
            assert r["drift_mm"] < 1.0  # hard contacts: a stack at rest stays there


def test_mujoco_records_are_well_formed(doc):
    pytest.importorskip("mujoco")
    if not peers.available():
        pytest.skip(peers.status())
    _check_engine(doc, "mujoco")
    mine, theirs = _records(doc, many_bodies.ENGINE), _records(doc, "mujoco")
    for key, r in mine.items():
        assert r["ratio_per_body_step"] == pytest.approx(
            r["us_per_body_step"] / theirs[key]["us_per_body_step"]
        )


def test_the_starts_are_at_rest_and_apart():
    pos, _ = many_bodies.start("pyramid_4", 1)
    assert len(pos[0]) == 10 and np.min(pos[0, :, 2]) == pytest.approx(many_bodies.HALF)
    pos, q = many_bodies.start("heap_64", 2)
    assert not np.allclose(q[0], q[1])  # a draw per batch element
    assert many_bodies.free_steps("heap_64") > 0 and many_bodies.free_steps("tower_4") == 0


def test_a_bad_out_exits_2_with_one_line(tmp_path, capsys):
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("")
    code = cli.run(
        many_bodies.main, many_bodies.PROG, ["--preset", "tiny", "--out", str(not_a_dir)]
    )
    assert code == cli.EXIT_USAGE
    captured = capsys.readouterr()
    assert captured.out == ""
    assert len(captured.err.strip().splitlines()) == 1 and "--out" in captured.err
