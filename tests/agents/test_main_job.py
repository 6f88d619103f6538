"""The main job (``python -m agents``) on both envs with tiny budgets: an interrupt in the second
env's training, then ``--resume``, which keeps the first env's work, finishes the second and
leaves one table, learning curve and clip per env."""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path

from tiny_budgets import TINY_SET

from agents import config, main_job, run_folder
from rigid_env import cli
from rigid_env.bench.readme import main_job_summary

TINY = ["--timesteps", "64", "--n-envs", "2", *TINY_SET, "--episodes", "2", "--no-progress"]


def stop_at_poll(polls: int):
    """Stands in for ``StopOnSignal``: its stop() turns true at the ``polls``-th call over the
    whole job (each training polls once before it starts, then once per vector step)."""
    calls = [0]

    def stop() -> bool:
        calls[0] += 1
        return calls[0] >= polls

    @contextmanager
    def stop_on_signal():
        yield stop

    return stop_on_signal


def test_interrupt_in_the_second_env_then_resume_keeps_the_first(tmp_path, capsys, monkeypatch):
    out = tmp_path / "job"
    # Reorient: 1 + 32 polls (64 steps of 2 envs); BoxLanding stops at its 11th poll.
    monkeypatch.setattr(main_job, "StopOnSignal", stop_at_poll(33 + 11))
    assert cli.run(main_job.main, main_job.PROG, [*TINY, "--out", str(out)]) == 130
    assert f"--resume {out}" in capsys.readouterr().err
    record = json.loads((out / main_job.RECORD).read_text())
    assert record["status"] == "interrupted"
    assert list(record["results"]) == ["RigidEnv/Reorient-v0"]
    first = out / "reorient-v0"
    second = run_folder.read(out / "boxlanding-v0")
    assert second["status"] == "interrupted" and second["steps_done"] == 20
    kept = {name: (first / name).read_bytes() for name in ("best_model.zip", "clip.gif")}

    monkeypatch.setattr(main_job, "StopOnSignal", stop_at_poll(10**9))
    argv = ["--resume", str(out), "--episodes", "2", "--no-progress"]
    assert cli.run(main_job.main, main_job.PROG, argv) == 0
    stdout = capsys.readouterr().out
    record = json.loads((out / main_job.RECORD).read_text())
    assert record["status"] == "finished" and record["envs"] == list(main_job.JOBS)
    for env_id in main_job.JOBS:  # one table, learning curve and clip per env
        folder = out / main_job.run_name(env_id)
        for name in ("learning_curve.png", "clip.gif", "best_model.zip", main_job.RECORD):
            assert (folder / name).is_file(), (env_id, name)
        table = json.loads((folder / main_job.RECORD).read_text())
        assert table == record["results"][env_id]
        policies = [row["policy"] for row in table["rows"]]
        assert policies == ["random", "zero", "analytic", "PPO (best_model.zip)"]
        assert all(row["episodes"] == 2 and row["env"] == env_id for row in table["rows"])
        # The physics the config trains on: BoxLanding's env_kwargs split the batch over threads.
        threads = config.load(env_id, "ppo")[0]["env_kwargs"].get("backend") == "compiled-threads"
        assert table["backend"] == ("compiled-threads" if threads else "compiled")
    assert record["results"]["RigidEnv/Reorient-v0"]["throughput"]["env_steps"] == 64
    # The first env's table is printed again from its record, then the second env's.
    assert stdout.index("Reorient-v0") < stdout.index("BoxLanding-v0: 2 episodes from seed 1000")
    # The README renders the records (copied to docs/results): one line per env.
    lines = main_job_summary(record).splitlines()
    assert lines[2].startswith("| RigidEnv/Reorient-v0 | PPO | 64 |")
    assert lines[3].startswith("| RigidEnv/BoxLanding-v0 | PPO |") and len(lines) == 6
    learned = record["results"]["RigidEnv/BoxLanding-v0"]["rows"][3]["success_rate"]
    assert lines[3].split(" | ")[-2] == f"{learned:.1%}"
    assert {name: (first / name).read_bytes() for name in kept} == kept  # not trained again
    second = run_folder.read(out / "boxlanding-v0")
    assert second["status"] == "finished" and second["resumed_at"] == [20]
    assert second["steps_done"] >= 64 and (out / "boxlanding-v0" / "clip.gif").is_file()
    capsys.readouterr()
    assert cli.run(main_job.main, main_job.PROG, ["--resume", str(out)]) == cli.EXIT_USAGE
    assert "is finished" in capsys.readouterr().err


def test_overwrite_replaces_a_main_job(tmp_path):
    out = tmp_path / "job"
    (out / "reorient-v0").mkdir(parents=True)
    (out / main_job.RECORD).write_text(json.dumps({"envs": [], "settings": {}}))
    (out / "reorient-v0" / "run.json").write_text(json.dumps({"env_id": "x", "status": "x"}))
    argv = [*TINY, "--out", str(out), "--env", "RigidEnv/Reorient-v0"]
    assert cli.run(main_job.main, main_job.PROG, argv) == cli.EXIT_USAGE  # no --overwrite
    assert cli.run(main_job.main, main_job.PROG, [*argv, "--overwrite"]) == 0
    assert run_folder.read(out / "reorient-v0")["status"] == "finished"
    record = json.loads((out / main_job.RECORD).read_text())  # --env picks one env
    assert record["envs"] == ["RigidEnv/Reorient-v0"] and not (out / "boxlanding-v0").exists()


def test_the_job_folder_name_comes_from_the_env_id():
    assert main_job.run_name("RigidEnv/BoxLanding-v0") == "boxlanding-v0"
    assert len({main_job.run_name(e) for e in main_job.JOBS}) == len(main_job.JOBS)
    assert Path(main_job.default_out()).parent == Path("runs")
