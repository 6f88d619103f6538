"""agents.sweep on Ray Tune, end to end with tiny trainings: a local sweep interrupted and resumed,
a two-node cluster that loses its worker node; and the command line's parsing.

Every Ray process of these tests is started here, in its own process group and temp dir, and
stopped here. The cluster's nodes listen on 127.0.0.2 (loopback; Ray replaces 127.0.0.1 by the
machine's external address, not 127.0.0.2); a local instance is kept on loopback by Ray's own
switch for single-machine use (RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from agents import evaluate, ownership, sweep
from rigid_env import cli

ROOT = Path(__file__).resolve().parents[2]
ID = "RigidEnv/Reorient-v0"
EPISODES = 3
# A few seconds of training per trial: 2 updates of a tiny net, 2 evaluations of 3 episodes.
TINY = [
    "n_timesteps=128",
    "n_envs=2",
    "n_steps=32",
    "batch_size=32",
    "eval_freq=64",
    f"eval_episodes={EPISODES}",
    "policy_kwargs.net_arch=[8]",
]
RAY = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"  # this Python's Ray
TIMEOUT = 600  # seconds for one sweep process: a hang fails the test instead of the CI run


@pytest.fixture(scope="module")
def ray_env():
    """Environment of every Ray process here: no usage report, a token of our own (nothing
    written to ~/.ray), no cluster inherited from the caller."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env.update(
        RAY_USAGE_STATS_ENABLED="0",
        RAY_AUTH_MODE="token",
        RAY_AUTH_TOKEN=secrets.token_hex(16),
        PYTHONUNBUFFERED="1",
    )
    return env


@pytest.fixture(scope="module")
def local_env(ray_env):
    tmp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths must fit
    yield {**ray_env, "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_TMPDIR": tmp}
    shutil.rmtree(tmp, ignore_errors=True)


def sweep_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "agents.sweep", *args]


def run(cmd: list[str], env: dict) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    return proc


def folders(out: Path) -> list[Path]:
    """Run folders of the trials that have started."""
    return sorted(p.parent.parent / p.stem for p in out.glob("runs/*/attempts/seed-*.jsonl"))


def attempts(folder: Path) -> list[dict]:
    path = folder.parent / "attempts" / f"{folder.name}.jsonl"  # sweep.attempts_path
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def finished(folder: Path) -> dict | None:
    path = folder / sweep.TRIAL_FILE
    return json.loads(path.read_text()) if path.exists() else None


def wait_for(condition, proc: subprocess.Popen, what: str, timeout: float = TIMEOUT):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        if proc.poll() is not None:
            raise AssertionError(f"the sweep ended before {what}:\n{proc.stdout.read()[-4000:]}")
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


# Put on PYTHONPATH of the local sweep only: Python imports it at start-up in every process of
# the sweep (driver and Ray workers). Once agents.train is imported, its train() first waits
# for a release file of its run folder (or "all") in $SWEEP_TEST_GATE, so the test decides
# which trial finishes before the interrupt and which are still running.
GATE_HOOK = """
import importlib.abc, importlib.util, os, sys, time
from pathlib import Path

GATE = Path(os.environ["SWEEP_TEST_GATE"])


def gated(train):
    def wait_then_train(*args, out, **kwargs):
        run = Path(out)
        own = GATE / f"{run.parent.name}-{run.name}"
        while not (own.exists() or (GATE / "all").exists()):
            time.sleep(0.1)
        return train(*args, out=out, **kwargs)

    return wait_then_train


class GateTrain(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != "agents.train":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        load = spec.loader.exec_module

        def exec_module(module):
            load(module)
            module.train = gated(module.train)

        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, GateTrain())
"""


def release(gate: Path, folder: Path | None = None) -> None:
    """Let the trial of run folder ``folder`` (None: every trial) start training."""
    (gate / ("all" if folder is None else f"{folder.parent.name}-{folder.name}")).touch()


def saved_as_finished(out: Path, folder: Path) -> bool:
    """Whether Ray Tune's saved experiment state calls the trial of ``folder`` finished."""
    trial = finished(folder)
    if trial is None or not list((out / sweep.EXPERIMENT).glob("experiment_state-*.json")):
        return False
    try:
        return trial["trial_id"] in sweep.finished_trial_ids(out)
    except json.JSONDecodeError:  # Tune copies its state file over the old one: read mid-copy
        return False


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory, local_env):
    """A local sweep of 2 configs x 2 seeds on 2 CPUs, interrupted (SIGINT, as Ctrl-C) once one
    trial has finished, as Tune's saved state records, while others wait at the gate, then
    resumed to the end. One sweep serves the resume test and the local-sweep test (a Ray start
    and cold trial processes cost tens of seconds)."""
    tmp = tmp_path_factory.mktemp("local")
    out, gate, hook = tmp / "sweep", tmp / "gate", tmp / "hook"
    gate.mkdir()
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(GATE_HOOK)
    # Tune saves its state every 10 s or more by default; every second keeps the wait short.
    env = {
        **local_env,
        "PYTHONPATH": str(hook),
        "SWEEP_TEST_GATE": str(gate),
        "TUNE_GLOBAL_CHECKPOINT_S": "1",
    }
    cmd = sweep_cmd(
        "--env", ID, "--algo", "ppo", "--seeds", "2", "--search", "n_epochs=grid(1, 2)",
        "--set", *TINY, "--num-cpus", "2", "--out", str(out),
    )  # fmt: skip
    proc = subprocess.Popen(
        cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        # Both CPUs' trials start and wait; the first one is let through and finishes.
        first, second = wait_for(lambda: folders(out)[:2] if len(folders(out)) >= 2 else None,
                                 proc, "two trials started")  # fmt: skip
        release(gate, first)
        wait_for(lambda: saved_as_finished(out, first), proc, "Tune's state to save the first")
        proc.send_signal(signal.SIGINT)
        interrupted = proc.communicate(timeout=TIMEOUT)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    code = proc.returncode
    started = folders(out)  # trials that began before the sweep stopped
    partial = json.loads((out / sweep.RESULTS_FILE).read_text())
    release(gate)
    resumed = run(sweep_cmd("--resume", str(out), "--num-cpus", "2"), env)
    return {
        "out": out,
        "code": code,
        "interrupted": interrupted,
        "first": first,
        "second": second,
        "started": started,
        "partial": partial,
        "resumed": resumed.stdout,
    }


def test_interrupted_sweep_resumes_without_rerunning_finished_trials(local_sweep):
    out, partial = local_sweep["out"], local_sweep["partial"]
    # Ctrl-C exits as every command does (130), after Tune saved a state to resume from.
    assert local_sweep["code"] == 130, local_sweep["interrupted"][-4000:]
    assert (
        f"interrupted: 1 of 4 trials finished; resume with --resume {out}"
        in (local_sweep["interrupted"])
    )
    assert "Traceback" not in local_sweep["interrupted"]
    assert not partial["complete"]
    # Finished before the interrupt, as Ray Tune's saved state says: only the trial let through.
    done = {
        out / "runs" / e["config_key"] / f"seed-{f['seed']}"
        for e in partial["configs"]
        for f in e["final"]
    }
    stopped = set(local_sweep["started"]) - done  # held at the gate when the sweep stopped
    assert done == {local_sweep["first"]}
    assert local_sweep["second"] in stopped
    assert partial["trials_finished"] == len(done) == 1
    for folder in folders(out):
        assert finished(folder) is not None
        # Finished ones were not run again, stopped ones ran again, the others ran once.
        assert len(attempts(folder)) == (2 if folder in stopped else 1), folder
    assert len(folders(out)) == 4


def test_local_sweep_of_two_configs_and_two_seeds(local_sweep):
    out = local_sweep["out"]
    assert "return IQM" in local_sweep["resumed"]
    results = json.loads((out / sweep.RESULTS_FILE).read_text())
    assert results["complete"] and results["trials_finished"] == 4
    assert len(results["configs"]) == 2
    for name in ("learning_curves.png", "final_scores.png"):
        assert (out / name).stat().st_size > 10_000, name

    from stable_baselines3 import PPO

    recomputed: dict[str, list] = {}
    assert len(folders(out)) == 4
    for folder in folders(out):
        trial = finished(folder)
        run_json = json.loads((folder / "run.json").read_text())
        assert trial is not None and (folder / "monitor.csv").is_file()
        # The model is loadable and was trained with this trial's config: the searched n_epochs,
        # the --set dotted key (net_arch [8] with the file's other policy_kwargs), this seed.
        model = PPO.load(folder / "final_model.zip", device="cpu")
        assert model.n_epochs == trial["config"]["n_epochs"]
        assert model.policy.mlp_extractor.policy_net[0].out_features == 8
        assert model.policy.net_arch == [8] and model.policy.log_std_init == -1.0
        assert run_json["seed"] == trial["seed"] and model.seed == trial["seed"]
        # The final model, evaluated again on the same seeded episodes, gives the figures the
        # run recorded (deterministic policy, same seeds, same batch).
        again = evaluate.evaluate(ID, str(folder / "final_model.zip"), EPISODES)
        last = run_json["evaluations"][-1]
        assert again["mean_return"] == pytest.approx(last["mean_return"], rel=1e-12)
        assert again["success_rate"] == last["success_rate"]
        recomputed.setdefault(trial["config_key"], []).append(
            (trial["seed"], again["mean_return"], again["success_rate"])
        )

    # The aggregate is the statistics of those re-evaluations, seed by seed.
    for entry in results["configs"]:
        seeds, returns, success = zip(*sorted(recomputed[entry["config_key"]]), strict=True)
        assert entry["seeds"] == [0, 1] == list(seeds)
        r = entry["mean_return"]
        assert r["mean"] == pytest.approx(np.mean(returns))
        assert r["iqm"] == pytest.approx(np.mean(returns))  # 2 runs: nothing to trim
        # Two runs: the percentile bootstrap interval is their range (tests/agents/test_aggregate).
        assert r["mean_ci"] == pytest.approx([min(returns), max(returns)])
        assert entry["success_rate"]["mean"] == pytest.approx(np.mean(success))
        assert len(entry["curves"]["mean_return"]["env_steps"]) == 2  # evaluations at 64, 128


# ---------------------------------------------------------------- a two-node cluster


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.2", 0))
        return s.getsockname()[1]


def start_node(args: list[str], env: dict, log: Path) -> subprocess.Popen:
    """``ray start ... --block`` in a new process group (the node's raylet and workers with it),
    so stopping it stops exactly this node."""
    with open(log, "w") as f:
        proc = subprocess.Popen(
            [RAY, "start", *args, "--block"],
            env=env,
            stdout=f,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    deadline = time.monotonic() + 120
    while "Ray runtime started" not in log.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            stop_node(proc)
            raise AssertionError(f"ray start failed:\n{log.read_text()[-3000:]}")
        time.sleep(0.2)
    return proc


def stop_node(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    """Signal the node's process group (its ``ray start``, raylet, workers and, on the head,
    GCS); SIGKILL what is left after a few seconds."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, sig)
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=10)
        # The group may outlive its leader: make sure nothing of it stays.
        os.killpg(proc.pid, signal.SIGKILL)
    if proc.poll() is None:
        proc.wait()


@pytest.fixture
def cluster(ray_env, tmp_path):
    """A head and a worker node on this machine, one CPU each; stopped whatever happens. Their
    trials wait at the gate (``GATE_HOOK``) until the test releases them, so none can finish
    before the test has killed the node it runs on."""
    gate, hook = tmp_path / "gate", tmp_path / "hook"
    gate.mkdir()
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(GATE_HOOK)
    ray_env = {**ray_env, "PYTHONPATH": str(hook), "SWEEP_TEST_GATE": str(gate)}
    tmp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths must fit
    address = f"127.0.0.2:{free_port()}"
    common = ["--num-cpus", "1", "--node-ip-address", "127.0.0.2"]
    common += ["--object-store-memory", str(100 * 2**20), "--disable-usage-stats"]
    nodes = []
    try:
        nodes.append(
            start_node(
                ["--head", "--port", address.split(":")[1], "--temp-dir", tmp,
                 "--include-dashboard", "false", *common],
                ray_env,
                tmp_path / "head.log",
            )
        )  # fmt: skip
        nodes.append(start_node(["--address", address, *common], ray_env, tmp_path / "worker.log"))
        probe = (
            f"import json, ray; ray.init(address={address!r});"
            "print(json.dumps([(n['NodeID'], 'node:__internal_head__' in n['Resources'])"
            " for n in ray.nodes() if n['Alive']]))"
        )
        listed = json.loads(run([sys.executable, "-c", probe], ray_env).stdout.splitlines()[-1])
        assert len(listed) == 2, listed
        head_id = next(node for node, is_head in listed if is_head)
        worker_id = next(node for node, is_head in listed if not is_head)
        yield {
            "address": address,
            "head": head_id,
            "worker": worker_id,
            "worker_proc": nodes[1],
            "gate": gate,
        }
    finally:
        for proc in reversed(nodes):
            stop_node(proc, signal.SIGKILL)  # a throwaway cluster: nothing to shut down gently
        shutil.rmtree(tmp, ignore_errors=True)


def test_cluster_runs_trials_on_both_nodes_and_retries_a_lost_one(tmp_path, ray_env, cluster):
    out = tmp_path / "sweep"
    # A sampled search (Optuna through Tune's Repeater): one config, run with both seeds.
    cmd = sweep_cmd(
        "--seeds", "2", "--set", *TINY, "--search", "learning_rate=loguniform(1e-4, 1e-3)",
        "--samples", "1", "--address", cluster["address"], "--out", str(out),
    )  # fmt: skip
    proc = subprocess.Popen(
        cmd, env=ray_env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    head, worker = cluster["head"], cluster["worker"]
    try:
        # Two trials, one CPU per node: they start together, one on each node, and wait at the
        # gate. Once both run, kill the worker node (SIGKILL to its raylet and workers, as a
        # machine lost), then let every trial train.
        def running_on_both():
            running = {attempts(f)[-1]["node_id"]: f for f in folders(out) if attempts(f)}
            return running.get(worker) if set(running) == {head, worker} else None

        lost = wait_for(running_on_both, proc, "a trial running on each node")
        assert finished(lost) is None
        stop_node(cluster["worker_proc"], signal.SIGKILL)
        release(cluster["gate"])
        output = proc.communicate(timeout=TIMEOUT)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, output[-4000:]

    results = json.loads((out / sweep.RESULTS_FILE).read_text())
    assert results["complete"] and len(results["configs"]) == 1
    (entry,) = results["configs"]
    assert entry["seeds"] == [0, 1] and 1e-4 <= entry["config"]["learning_rate"] <= 1e-3
    # The lost trial was retried by Tune on the head (the only node left) and finished there;
    # the other ran once, on the head.
    assert [t["node_id"] for t in attempts(lost)] == [worker, head]
    assert finished(lost)["node_id"] == head and (lost / "final_model.zip").is_file()
    (other,) = [f for f in folders(out) if f != lost]
    assert [t["node_id"] for t in attempts(other)] == [head]
    assert finished(other)["node_id"] == head


# ---------------------------------------------------------------- the command line


def test_search_spaces_and_values_are_parsed():
    assert sweep.parse_space("loguniform(1e-4, 1e-3)") == ("loguniform", [1e-4, 1e-3])
    assert sweep.parse_space("int(1, 4)") == ("int", [1, 4])
    assert sweep.parse_space("choice([64, 64], [128, 128])") == ("choice", [[64, 64], [128, 128]])
    assert sweep.parse_space("grid(lin_1e-3, 3e-4)") == ("grid", ["lin_1e-3", 3e-4])
    assert sweep.parse_value("1e-4") == 1e-4 and sweep.parse_value("[8, 8]") == [8, 8]
    assert sweep.parse_value("Tanh") == "Tanh"
    for bad in ("normal(0, 1)", "uniform(1)", "uniform(2, 1)", "loguniform(0, 1)", "int(1.5, 3)"):
        with pytest.raises(ValueError, match="--search"):
            sweep.parse_space(bad)


def test_trials_map_to_configs_and_seeds():
    from ray import tune

    settings = {
        "search": {"net": "choice([8], [16, 16])", "gamma": "grid(0.9, 0.99)"},
        "seeds": [0, 1, 2],
    }
    space, sampled = sweep.param_space({**settings, "search": {"gamma": "grid(0.9, 0.99)"}})
    assert not sampled and space["seed"] == tune.grid_search([0, 1, 2])
    space, sampled = sweep.param_space({**settings, "search": {"net": "choice([8], [16, 16])"}})
    assert sampled and "seed" not in space  # seeds come from the Repeater's trial index
    # Optuna's categorical choices must be scalars: lists travel as YAML text and come back.
    assert sorted(space["net"].categories) == ["[16, 16]", "[8]"]
    params, seed = sweep.trial_params({"net": "[16, 16]", "__trial_index__": 2}, settings)
    assert params == {"net": [16, 16]} and seed == 2
    params, seed = sweep.trial_params({"gamma": 0.99, "seed": 1}, settings)
    assert params == {"gamma": 0.99} and seed == 1
    # One folder per config, the same for every seed, different between configs.
    assert sweep.config_key({"gamma": 0.99}) == sweep.config_key({"gamma": 0.99})
    assert sweep.config_key({"gamma": 0.99}) != sweep.config_key({"gamma": 0.9})


def test_dotted_keys_keep_the_rest_of_the_dict():
    block = sweep.raw_block(ID, "ppo")
    merged = sweep.expand({"policy_kwargs.net_arch": [8], "gamma": 0.9}, block)
    assert merged["gamma"] == 0.9
    assert merged["policy_kwargs"] == {**block["policy_kwargs"], "net_arch": [8]}
    assert block["policy_kwargs"]["net_arch"] == [128, 128]  # the file's block is not changed


@pytest.fixture()
def no_ray(monkeypatch):
    """Fails the test if Ray would start: every refusal comes before."""

    def connect(*args, **kwargs):
        raise AssertionError("Ray was started")

    monkeypatch.setattr(sweep, "connect", connect)


def refused(capsys, argv: list[str]) -> str:
    """``agents.sweep argv`` exits 2 with one line on stderr (returned), no usage block."""
    capsys.readouterr()
    code = cli.run(sweep.main, sweep.PROG, argv)
    out, err = capsys.readouterr()
    assert code == cli.EXIT_USAGE, (out, err)
    assert err.startswith(f"{sweep.PROG}: error: ") and err.count("\n") == 1, err
    assert "usage:" not in err
    return err


BAD_SETTINGS = [
    (["--set", "no_such_key=1"], "--set: 'no_such_key' is not a setting of PPO"),
    (["--set", "seed=3"], "(use --seeds)"),
    (["--set", "n_steps=[1"], "--set n_steps:"),
    (["--set", "gamma=1.5"], "--set: gamma must be a number in (0, 1], got 1.5"),
    (["--set", "policy_kwargs.net_arch=[-8]"], "policy_kwargs net_arch must be a list"),
    (["--set", "n_envs=1000000000"], "needs ~"),
    (["--set", "policy_kwargs.no_such_option=1"], "--set: PPO rejects"),  # SB3's own check
    (["--search", "n_epochs=grid(5, 0)"], "--search (n_epochs=0): n_epochs must be an integer"),
    (["--search", "gamma=uniform(0.9, 1.5)"], "--search (gamma=1.5): gamma must be a number"),
    (["--search", "learning_rate=loguniform(1e-4, 1e999)"], "two finite numbers"),
    (
        ["--search", "policy_kwargs.net_arch=choice([8], [0])"],
        "--search (policy_kwargs.net_arch=[0])",
    ),
    (["--search", "gamma=grid(0.9, 0.99)", "learning_rate=uniform(1e-4, 1e-3)"], "grid"),
    (["--search", "gamma=grid(0.9, 0.99)", "--samples", "3"], "--samples"),
    (["--seeds", "0"], "--seeds"),
    (["--seeds", "1000000000000"], "at most 10000 trials"),
    (["--search", "gamma=uniform(0.9, 0.99)", "--samples", "5000", "--seeds", "3"], "15000 trials"),
    (["--algo", "dqn"], "--algo"),
    (["--env", "RigidEnv/NoSuch-v0"], "unknown env id"),
    (["--num-cpus", "0"], "--num-cpus"),
    (["--num-cpus", "-2"], "--num-cpus"),
    (["--cpus-per-trial", "0"], "--cpus-per-trial"),
    (["--cpus-per-trial", "-1"], "--cpus-per-trial"),
    (["--cpus-per-trial", "nan"], "--cpus-per-trial"),
    (["--cpus-per-trial", "inf"], "--cpus-per-trial"),
    (["--cpus-per-trial", "3", "--num-cpus", "2"], "more than the 2 CPUs"),
    (["--cpus-per-trial", "100000"], "more than the"),
    (["--max-failures", "-1"], "--max-failures"),
    (["--num-cpus", "2", "--address", "auto"], "only for a local Ray instance"),
]


@pytest.mark.parametrize("argv, message", BAD_SETTINGS, ids=[" ".join(a) for a, _ in BAD_SETTINGS])
def test_bad_settings_are_one_line_before_ray_starts(tmp_path, capsys, no_ray, argv, message):
    err = refused(capsys, [*argv, "--out", str(tmp_path / "s")])
    assert message in err, err
    assert not (tmp_path / "s").exists()  # nothing written for a refused sweep


def test_unusable_out_and_resume_folders_are_one_line(tmp_path, capsys, no_ray, monkeypatch):
    (tmp_path / "file.txt").write_text("x")
    assert "is a file" in refused(capsys, ["--out", str(tmp_path / "file.txt")])
    assert "holds no sweep" in refused(capsys, ["--resume", str(tmp_path)])
    err = refused(capsys, ["--resume", str(tmp_path), "--seeds", "2"])
    assert "only --address and --num-cpus" in err
    # A read-only place (injected: the tests may run as root, whom permissions do not stop).
    real_mkdir = Path.mkdir

    def mkdir(self, *args, **kwargs):
        if "readonly" in self.parts:
            raise OSError(errno.EROFS, "Read-only file system", str(self))
        return real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    err = refused(capsys, ["--seeds", "1", "--out", str(tmp_path / "readonly" / "s")])
    assert "Read-only file system" in err and "--out" in err


CORRUPT_SETTINGS = [
    ("{not json", "is unreadable"),
    ("[1, 2]", "expected a JSON object"),
    ('{"env_id": "RigidEnv/Reorient-v0"}', "algo must be of type str"),
    ({"seeds": list(range(10**4 + 1))}, "seeds must be 1 to 10000"),
    ({"seeds": [0, 0]}, "distinct"),
    ({"seeds": [-1]}, "seeds must be"),
    ({"cpus_per_trial": 0}, "--cpus-per-trial must be a finite number > 0"),
    ({"max_failures": -1}, "--max-failures"),
    ({"configs": 7}, "configs must be 2"),
    ({"search": {"gamma": 3}}, "search must map"),
    ({"search": {"gamma": "normal(0, 1)"}}, "--search"),
    ({"set": {"gamma": 2.0}}, "--set: gamma must be"),
    ({"metric": "loss"}, "--metric"),
    ({"algo": "dqn"}, "--algo"),
]


@pytest.mark.parametrize(
    "content, message", CORRUPT_SETTINGS, ids=[str(c)[:40] for c, _ in CORRUPT_SETTINGS]
)
def test_a_corrupt_sweep_json_on_resume_is_one_line(tmp_path, capsys, no_ray, content, message):
    good = {
        "env_id": ID, "algo": "ppo", "seeds": [0, 1], "set": {"n_timesteps": 64},
        "search": {"n_epochs": "grid(1, 2)"}, "samples": 1, "configs": 2,
        "metric": "mean_return", "cpus_per_trial": 1.0, "max_failures": 3,
    }  # fmt: skip
    text = content if isinstance(content, str) else json.dumps({**good, **content})
    (tmp_path / sweep.SETTINGS_FILE).write_text(text)
    err = refused(capsys, ["--resume", str(tmp_path)])
    assert f"{tmp_path / sweep.SETTINGS_FILE}" in err and message in err, err


def sweep_without_ray(monkeypatch, interrupt: str | None = None):
    """Stand-ins for Ray: ``connect`` does nothing; ``run_tune`` installs a SIGUSR1 handler as
    Tune's fit() does, then receives ``interrupt`` (a signal name) as from the terminal, and
    returns no trials. Returns the list of signals Tune's handler saw."""
    seen: list[int] = []

    def run_tune(settings, sweep_dir, resume):
        previous = signal.signal(signal.SIGUSR1, lambda sig, frame: seen.append(sig))
        try:
            if interrupt is not None:
                os.kill(os.getpid(), getattr(signal, interrupt))
            return []
        finally:
            signal.signal(signal.SIGUSR1, previous)

    monkeypatch.setattr(sweep, "connect", lambda *args: None)
    monkeypatch.setattr(sweep, "run_tune", run_tune)
    monkeypatch.setattr(sweep, "finished_trial_ids", lambda sweep_dir: set())
    return seen


@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM"])
def test_ctrl_c_asks_tune_to_stop_and_exits_130_with_a_resumable_sweep(
    tmp_path, capsys, monkeypatch, name
):
    seen = sweep_without_ray(monkeypatch, interrupt=name)
    out = tmp_path / "s"
    handlers = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    code = cli.run(sweep.main, sweep.PROG, ["--seeds", "2", "--set", *TINY, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == cli.EXIT_INTERRUPTED, err
    assert seen == [signal.SIGUSR1]  # Tune was asked to stop its trials and save its state
    assert f"interrupted: 0 of 2 trials finished; resume with --resume {out}" in err
    assert sweep.read_settings(out)["seeds"] == [0, 1]  # what --resume reads back
    assert not (out / ownership.LOCK_FILE).exists()
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers
    assert "TUNE_DISABLE_SIGINT_HANDLER" not in os.environ


def test_a_fault_of_the_driver_is_one_line(tmp_path, capsys, monkeypatch):
    sweep_without_ray(monkeypatch)
    out = tmp_path / "s"
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        if os.readlink(f"/proc/self/fd/{fd}").split("/")[-1].startswith(".results.json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    code = cli.run(sweep.main, sweep.PROG, ["--seeds", "1", "--set", *TINY, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == cli.EXIT_FAULT, err
    assert err == (
        f"{sweep.PROG}: error: {out / sweep.RESULTS_FILE}: No space left on device (ENOSPC); "
        "files written before are kept\n"
    )
    assert sweep.read_settings(out)["seeds"] == [0]  # written before: intact
    assert sorted(p.name for p in out.iterdir()) == [sweep.SETTINGS_FILE]  # no partial file


def test_sweep_entry_point_is_one_line_without_traceback(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-m", "agents.sweep", "--num-cpus", "0", "--out", str(tmp_path / "s")],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "--num-cpus" in proc.stderr and "usage:" not in proc.stderr


def test_ctrl_c_before_tune_runs_exits_130_and_the_sweep_resumes(tmp_path, capsys, monkeypatch):
    """While Ray starts (no Tune to ask yet) Ctrl-C ends the sweep at once; sweep.json is
    written, so --resume starts its trials (Tune saved no state: afresh)."""
    sweep_without_ray(monkeypatch)

    def connect(*args):
        os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(sweep, "connect", connect)
    out = tmp_path / "s"
    code = cli.run(sweep.main, sweep.PROG, ["--seeds", "1", "--set", *TINY, "--out", str(out)])
    assert code == cli.EXIT_INTERRUPTED
    assert capsys.readouterr().err == f"{sweep.PROG}: interrupted\n"
    resumed = []
    monkeypatch.setattr(sweep, "connect", lambda *args: None)
    monkeypatch.setattr(sweep, "run_tune", lambda s, d, resume: resumed.append(resume) or [])
    assert cli.run(sweep.main, sweep.PROG, ["--resume", str(out)]) == 1  # no trial finished here
    assert resumed == [True]
