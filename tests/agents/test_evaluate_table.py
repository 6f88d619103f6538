"""``agents.evaluate`` with several policies: one table over the same episodes, written as JSON
that describes its own columns (the README's result tables are generated from such files)."""

from __future__ import annotations

import json

import pytest

from agents import evaluate
from rigid_env.bench.readme import rows_table

ENV = "RigidEnv/Reorient-v0"


def test_several_policies_share_the_episodes_and_the_file_matches_them(tmp_path):
    out = tmp_path / "table.json"
    assert evaluate.main(["--env", ENV, "--policy", "zero", "analytic", "--episodes", "3", "--out", str(out)]) == 0  # fmt: skip
    doc = json.loads(out.read_text())
    assert [r["policy"] for r in doc["rows"]] == ["zero", "analytic"]
    assert (doc["env_id"], doc["episodes"], doc["eval_seed"]) == (ENV, 3, evaluate.DEFAULT_SEED)
    # Each row is what a one-policy evaluation on the same seeds gives.
    for row in doc["rows"]:
        direct = evaluate.evaluate(ENV, row["policy"], 3, evaluate.DEFAULT_SEED)
        assert row["mean_return"] == pytest.approx(direct["mean_return"], rel=0, abs=1e-9)
    # The columns render: one header, one rule, one line per policy, each value formatted.
    lines = rows_table(doc).splitlines()
    assert len(lines) == 2 + 2 and lines[2].startswith("| zero |")
    assert f"{doc['rows'][1]['mean_return']:.2f}" in lines[3]


def test_a_clip_needs_a_single_policy(tmp_path, capsys):
    from rigid_env import cli

    code = cli.run(evaluate.main, evaluate.PROG, ["--policy", "zero", "analytic", "--gif", str(tmp_path / "c.gif")])  # fmt: skip
    assert code == 2
    assert "--gif" in capsys.readouterr().err
    assert not (tmp_path / "c.gif").exists()
