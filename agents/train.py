"""Train a stable-baselines3 baseline on a native vector env.

    python -m agents.train --env RigidEnv/Reorient-v0 --algo ppo [--timesteps N --seed S
                           --n-envs K --out DIR --set KEY=VALUE ... --checkpoint-every N
                           --overwrite]
    python -m agents.train --resume RUN_DIR

Hyperparameters come from ``agents/hyperparams/<algo>.yml``. The run folder (default a fresh
``runs/<env>-<algo>-<time>``, printed at the start and the end) gets ``best_model.zip`` (best
mean return at a seeded evaluation), ``final_model.zip``, ``monitor.csv`` (every training
episode, from SB3's ``VecMonitor``), ``evaluations.csv``, ``learning_curve.png`` and ``run.json``
(settings, status and measured figures, which ``agents.evaluate`` reads to rebuild the env).

Nothing is lost or overwritten: an existing run folder is refused unless ``--overwrite`` (replace
it) or ``--resume RUN_DIR`` (continue from its last checkpoint with its own settings, appending to
its logs). ``checkpoint.zip`` is saved every ``--checkpoint-every`` env steps (default: at each
evaluation) and on Ctrl-C or SIGTERM, which then exit with status 130 and ``run.json`` status
``interrupted``; a second Ctrl-C exits at once. Every file is written atomically. A mistake in
the arguments exits with status 2 and one line on stderr, before any work.

A run folder belongs to one live process (:mod:`agents.ownership`; ``run.json`` names it under
``owner``): a second ``--out`` or ``--resume`` on a run in use is refused, naming its owner; a run
whose ``run.json`` says ``running`` but whose owner is gone stopped unexpectedly, and
``--resume`` takes it over. A fault of the file system (no space, file too large, permission,
read-only, a network file system gone) exits with status 74 and one line naming the path and
the cause; ``run.json`` is marked ``failed`` where it can still be written.

Throughput is measured on the way: env steps per second of wall time, and the shares of it spent
inside the vector env and inside the simulator's ``Scene.step``.

:func:`train` and :func:`resume` are the library entry points (used by the command line here and
by sweeps); they take a ``stop`` callable instead of handling signals themselves.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rigid_env import cli
from rigid_env.cli import UsageError
from rigid_env.envs.core import TaskVectorEnv
from rigid_env.files import atomic_open, write_text
from rigid_env.sim import StageTimer

from . import ownership, run_folder
from .plan import DEFAULT_ENV, DEFAULT_EVAL_SEED, Plan, algo_class, make_plan, plan_of_record
from .rollout import make_vec, run_episodes

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnv, VecMonitor

    from .vec_adapter import GymVectorToSB3


@dataclass
class Throughput:
    """Wall-clock accounting of one ``learn`` call."""

    env_steps: int
    learn_seconds: float  # the whole of model.learn
    cpu_seconds: float  # process CPU time of model.learn (robust to other loads on the machine)
    eval_seconds: float  # of which periodic evaluation
    env_seconds: float  # of which inside the training vector env (step + partial resets)
    sim_seconds: float  # of which inside the simulator's Scene.step

    @property
    def train_seconds(self) -> float:
        return self.learn_seconds - self.eval_seconds

    def as_dict(self) -> dict[str, float]:
        t = self.train_seconds
        return {
            "env_steps": self.env_steps,
            "learn_seconds": round(self.learn_seconds, 2),
            "eval_seconds": round(self.eval_seconds, 2),
            "cpu_seconds": round(self.cpu_seconds, 2),
            "steps_per_second": round(self.env_steps / self.learn_seconds, 1),
            "steps_per_cpu_second": round(self.env_steps / self.cpu_seconds, 1),
            "steps_per_second_without_eval": round(self.env_steps / t, 1),
            "env_share": round(self.env_seconds / t, 4),
            "sim_share": round(self.sim_seconds / t, 4),
            "learner_us_per_step": round(1e6 * (t - self.env_seconds) / self.env_steps, 1),
        }


@dataclass
class RunResult:
    out: Path
    env_id: str
    algo: str
    evaluations: list[dict] = field(default_factory=list)
    throughput: dict = field(default_factory=dict)
    analytic: dict = field(default_factory=dict)
    status: str = "finished"  # or "interrupted" (a checkpoint to resume from is in ``out``)
    steps_done: int = 0


def default_out(env_id: str, algo: str) -> Path:
    name = env_id.split("/")[-1].lower()
    stamp = time.strftime("%Y%m%d-%H%M%S")
    out = Path("runs") / f"{name}-{algo}-{stamp}"
    k = 1
    while out.exists():
        out = Path("runs") / f"{name}-{algo}-{stamp}-{k}"
        k += 1
    return out


def train(
    env_id: str = DEFAULT_ENV,
    algo: str = "ppo",
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    out: str | Path | None = None,
    overrides: dict | None = None,
    eval_seed: int = DEFAULT_EVAL_SEED,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    *,
    checkpoint_every: int | None = None,
    overwrite: bool = False,
    stop: Callable[[], bool] | None = None,
    on_evaluation: Callable[[dict], None] | None = None,
) -> RunResult:
    """Train ``algo`` on ``env_id`` with the config file's hyperparameters (``overrides`` on
    top: loop keys or algorithm kwargs) into the run folder ``out``; returns the run's figures
    (also in ``run.json``).

    Every argument and ``out`` are checked before any work (``UsageError``, a ``ValueError``);
    an existing run in ``out`` is refused unless ``overwrite``. ``stop()`` is polled at every
    vector step: when it returns True the run saves a checkpoint and returns with status
    ``"interrupted"`` (continue it with :func:`resume`). ``on_evaluation(row)`` is called after
    each periodic evaluation (e.g. to report to a tuner)."""
    out = Path(out) if out is not None else default_out(str(env_id), str(algo))
    run_folder.check_new(out, overwrite)
    plan = make_plan(env_id, algo, timesteps, seed, n_envs, overrides, eval_seed, checkpoint_every)
    env, adapter, timed = _make_env(plan)
    model = build_model(plan, env)
    with ownership.owning(out, "--out") as claim:
        run_folder.prepare_new(out, overwrite)  # checked again: no other process starts here now
        session = _Session(plan, out, env, adapter, timed, model, log, stop, on_evaluation)
        session.owner = claim.owner.as_record()
        return session.run(progress)


def build_model(plan: Plan, env: VecEnv) -> BaseAlgorithm:
    """The SB3 model of ``plan`` on ``env`` (seeded): an argument SB3 rejects is a
    :class:`UsageError` naming the overrides, when there are any (else a bug of the files)."""
    env.seed(plan.seed)
    try:
        return algo_class(plan.algo)(
            env=env, seed=plan.seed, device="cpu", verbose=0, **plan.kwargs
        )
    except (TypeError, ValueError, AssertionError) as error:
        if not plan.overrides:
            raise
        raise UsageError(
            f"overrides (--set): {plan.algo.upper()} rejects {plan.overrides}: {error}"
        ) from None


def check_model(plan: Plan) -> None:
    """Build ``plan``'s env and model once, as :func:`train` will (UsageError if SB3 rejects
    the overrides), and close them: a check before many trainings start."""
    env, _, _ = _make_env(plan)
    try:
        build_model(plan, env)
    finally:
        env.close()


def resume(
    run_dir: str | Path,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    *,
    stop: Callable[[], bool] | None = None,
    on_evaluation: Callable[[dict], None] | None = None,
) -> RunResult:
    """Continue the run in ``run_dir`` from its last checkpoint with the settings in its
    ``run.json``, appending to its logs (``stop`` and ``on_evaluation`` as in :func:`train`).

    The continuation is not bit-identical to an uninterrupted run: the environments restart
    from fresh episodes (seeded ``seed + steps done``) and PPO drops a partial rollout."""
    out = Path(run_dir)
    run_folder.read_resumable(out)  # before claiming it: a folder that is no run stays as it was
    with ownership.owning(out, "--resume") as claim:
        return _resume(out, claim, progress, log, stop, on_evaluation)


def _resume(
    out: Path,
    claim: ownership.Claim,
    progress: bool,
    log: Callable[[str], None] | None,
    stop: Callable[[], bool] | None,
    on_evaluation: Callable[[dict], None] | None,
) -> RunResult:
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    record = run_folder.read_resumable(out)  # now that no other process can start on it
    plan = plan_of_record(record)
    env, adapter, timed = _make_env(plan)
    model, algo = run_folder.load_model(out / run_folder.CHECKPOINT, "--resume", env=env)
    if algo != plan.algo:
        raise UsageError(f"--resume: {out / run_folder.CHECKPOINT} is not a {plan.algo} model")
    steps = int(model.num_timesteps)
    buffer = out / run_folder.REPLAY_BUFFER
    if isinstance(model, OffPolicyAlgorithm) and buffer.is_file():  # SAC's replay buffer
        model.load_replay_buffer(buffer)
    # Also seeds the env: new episodes and streams (numpy's legacy seeds stop at 2**32).
    model.set_random_seed((plan.seed + steps) % 2**32)
    checkpoint = record.get("checkpoint") or {}
    monitor = out / "monitor.csv"
    if checkpoint.get("steps") != steps:  # run.json was not rewritten after this checkpoint
        checkpoint = {}
    elif monitor.is_file():
        # Episodes logged after the checkpoint are run again from it: drop their lines.
        os.truncate(monitor, min(checkpoint["monitor_bytes"], monitor.stat().st_size))
    rows = [r for r in record.get("evaluations", []) if r["env_steps"] <= steps]
    best = record.get("best_mean_return")
    session = _Session(
        plan,
        out,
        env,
        adapter,
        timed,
        model,
        log,
        stop,
        on_evaluation,
        rows=rows,
        best=-math.inf if best is None else float(best),
        analytic=record.get("analytic"),
        resumed_at=[*record.get("resumed_at", []), steps],
        checkpoint=checkpoint or None,
    )
    session.owner = claim.owner.as_record()
    if record.get("status") == "running":  # its owner is gone: it was not stopped, it died
        dead = record.get("owner") or {}
        session.log(
            f"{out} stopped unexpectedly (run.json says running; its owner, pid "
            f"{dead.get('pid', '?')} on {dead.get('host', '?')}, is gone): taking it over from "
            f"the checkpoint at {steps:,d} steps"
        )
    return session.run(progress)


def _make_env(plan: Plan) -> tuple[VecMonitor, GymVectorToSB3, StageTimer]:
    """The training env: the native vector env (its simulator timed), adapted to SB3, with a
    ``VecMonitor`` whose log file is attached once the run folder is ready."""
    from stable_baselines3.common.vec_env import VecMonitor

    from .vec_adapter import GymVectorToSB3

    venv = make_vec(plan.env_id, plan.n_envs, **plan.env_kwargs)
    native = venv.unwrapped
    if not isinstance(native, TaskVectorEnv):  # the simulator's timer is reached through its task
        raise UsageError(f"env_id: {plan.env_id} is not a RigidEnv vector env")
    task = native.task
    timed = task.scene.timer = StageTimer()  # the simulator's share of the wall time
    adapter = GymVectorToSB3(venv)
    return VecMonitor(adapter, info_keywords=("is_success",)), adapter, timed


class _Session:
    """One training call on a run folder: evaluations, checkpoints, records and the end."""

    def __init__(
        self,
        plan: Plan,
        out: Path,
        env: VecMonitor,
        adapter: GymVectorToSB3,
        timed: StageTimer,
        model: BaseAlgorithm,
        log: Callable[[str], None] | None,
        stop: Callable[[], bool] | None,
        on_evaluation: Callable[[dict], None] | None,
        rows: list[dict] | None = None,
        best: float = -math.inf,
        analytic: dict | None = None,
        resumed_at: list[int] | None = None,
        checkpoint: dict | None = None,
    ):
        self.plan, self.out, self.env, self.model = plan, out, env, model
        self.adapter, self.timed = adapter, timed
        self.log = log or functools.partial(print, flush=True)  # flushed: shows when piped
        self.stop = stop or (lambda: False)
        self.on_evaluation = on_evaluation
        self.rows = list(rows or [])
        self.best = best
        self.analytic = analytic
        self.resumed_at = list(resumed_at or [])
        self.start_steps = int(model.num_timesteps)
        self.checkpoint_info = checkpoint  # the last one: where a resume would start
        self.throughput: dict = {}
        self.owner: dict | None = None  # the process training it (host, pid, start), in run.json
        self.eval_seconds = 0.0
        self.created = time.strftime("%Y-%m-%dT%H:%M:%S")

    # --- what the callback does -----------------------------------------------------------------

    def evaluate(self) -> None:
        """The deterministic policy on the same seeded episodes (batched); keeps the best."""
        start = time.perf_counter()
        plan, policy = self.plan, self.model.policy

        def act(obs: np.ndarray) -> np.ndarray:
            return policy.predict(obs, deterministic=True)[0]

        summary = run_episodes(
            plan.env_id, act, plan.eval_episodes, plan.eval_seed, plan.env_kwargs
        ).summary()
        steps = int(self.model.num_timesteps)
        row = {"env_steps": steps, **summary}
        self.rows.append(row)
        best = summary["mean_return"] > self.best
        if best:
            self.best = summary["mean_return"]
            self._save_model("best_model.zip")
        self.write_record("running")
        self.eval_seconds += time.perf_counter() - start
        self.log(
            f"eval @ {steps:>9,d} steps: return {summary['mean_return']:8.2f} "
            f"± {summary['std_return']:6.2f}, success {summary['success_rate']:6.1%}"
            + ("  (new best)" if best else "")
        )
        if self.on_evaluation is not None:
            self.on_evaluation(dict(row))

    def checkpoint(self, status: str = "running") -> None:
        """``checkpoint.zip`` (and SAC's replay buffer), then ``run.json`` pointing at it."""
        from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

        self._save_model(run_folder.CHECKPOINT)
        if isinstance(self.model, OffPolicyAlgorithm):
            with atomic_open(self.out / run_folder.REPLAY_BUFFER) as f:
                self.model.save_replay_buffer(f)
        monitor = self.out / "monitor.csv"
        steps = int(self.model.num_timesteps)
        self.checkpoint_info = {
            "steps": steps,
            "monitor_bytes": monitor.stat().st_size if monitor.is_file() else 0,
        }
        self.write_record(status)
        self.log(f"checkpoint @ {steps:>9,d} steps: {self.out / run_folder.CHECKPOINT}")

    def _save_model(self, name: str) -> None:
        with atomic_open(self.out / name) as f:
            self.model.save(f)

    # --- the run --------------------------------------------------------------------------------

    def run(self, progress: bool) -> RunResult:
        """The run; whatever ends it early is recorded in ``run.json`` where that can still be
        written (``interrupted`` after Ctrl-C, else ``failed``). A fault of the file system
        without a file name (a write of SB3's ``monitor.csv``) names the run folder."""
        try:
            return self._run(progress)
        except KeyboardInterrupt:  # no stop() was wired to the signal: the last checkpoint stays
            self._record_end("interrupted")
            raise
        except OSError as error:
            self._record_end("failed")
            if error.filename is None and cli.is_fault(error):
                raise OSError(error.errno, error.strerror, str(self.out)) from error
            raise
        except Exception:
            self._record_end("failed")
            raise

    def _record_end(self, status: str) -> None:
        with contextlib.suppress(OSError):  # the same fault again: the last record stays
            self.write_record(status)

    def _run(self, progress: bool) -> RunResult:
        import torch
        from stable_baselines3.common.monitor import ResultsWriter

        from .policies import make_policy

        torch.set_num_threads(1)  # small MLPs: threads cost more than they give on 2 cores
        plan, out, log, model = self.plan, self.out, self.log, self.model
        resumed = bool(self.resumed_at)
        monitor = out / "monitor.csv"
        self.env.results_writer = ResultsWriter(
            str(monitor),
            header={"t_start": self.env.t_start, "env_id": plan.env_id},
            extra_keys=("is_success",),
            override_existing=not (resumed and monitor.is_file()),  # a resumed run appends
        )
        if resumed and monitor.is_file():  # keep the file's clock: t is since its t_start
            self.env.t_start = _monitor_start(monitor, self.env.t_start)
        log(f"run folder: {out}")
        log(
            f"{'resuming' if resumed else 'training'} {plan.algo.upper()} on {plan.env_id}: "
            f"{plan.timesteps:,d} env steps ({self.start_steps:,d} done), {plan.n_envs} envs, "
            f"seed {plan.seed}"
        )
        self.write_record("running")
        stopped = self.stop()  # asked before the first step (polled once here, then per step)
        if self.analytic is None and not stopped:  # the reference level of the curves
            self.analytic = run_episodes(
                plan.env_id,
                lambda e: make_policy("analytic", plan.env_id, e),
                plan.eval_episodes,
                plan.eval_seed,
                plan.env_kwargs,
                policy_needs_env=True,
            ).summary()
        if self.analytic is not None:
            log(
                "analytic controller on the evaluation episodes: return "
                f"{self.analytic['mean_return']:.2f}, success {self.analytic['success_rate']:.1%}"
            )
        callback = _callback(self)
        start, cpu_start = time.perf_counter(), time.process_time()
        if not stopped:
            model.learn(
                total_timesteps=plan.timesteps - self.start_steps,
                callback=callback,
                progress_bar=progress,
                reset_num_timesteps=not resumed,
            )
        learn_seconds = time.perf_counter() - start
        cpu_seconds = time.process_time() - cpu_start
        steps = int(model.num_timesteps)
        status = "finished" if steps >= plan.timesteps else "interrupted"
        if status == "finished":
            self._save_model("final_model.zip")
        else:
            self.checkpoint("interrupted")
        self.env.close()
        if steps > self.start_steps:
            self.throughput = Throughput(
                env_steps=steps - self.start_steps,
                learn_seconds=learn_seconds,
                cpu_seconds=cpu_seconds,
                eval_seconds=self.eval_seconds,
                env_seconds=self.adapter.env_seconds,
                sim_seconds=self.timed.step_seconds,
            ).as_dict()
        result = RunResult(
            out,
            plan.env_id,
            plan.algo,
            self.rows,
            self.throughput,
            self.analytic or {},
            status,
            steps,
        )
        self._write_tables(result)
        if status == "finished":
            self.checkpoint_info = None
            self.write_record(status)
            for name in (run_folder.CHECKPOINT, run_folder.REPLAY_BUFFER):
                (out / name).unlink(missing_ok=True)  # final_model.zip supersedes them
        else:
            self.write_record(status)
        self._log_end(result)
        return result

    def _write_tables(self, result: RunResult) -> None:
        if not result.evaluations:
            return
        from .plots import learning_curve

        header = list(result.evaluations[0])
        lines = [",".join(header)]
        lines += [",".join(str(r[k]) for k in header) for r in result.evaluations]
        write_text(self.out / "evaluations.csv", "\n".join(lines) + "\n")
        title = f"{result.algo.upper()} on {result.env_id}"
        learning_curve(result.evaluations, result.analytic, self.out / "learning_curve.png", title)

    def write_record(self, status: str) -> None:
        plan = self.plan
        run_folder.write(
            self.out,
            {
                "status": status,
                "steps_done": int(self.model.num_timesteps),
                "env_id": plan.env_id,
                "algo": plan.algo,
                "timesteps": plan.timesteps,
                "n_envs": plan.n_envs,
                "seed": plan.seed,
                "eval_seed": plan.eval_seed,
                "eval_freq": plan.eval_freq,
                "eval_episodes": plan.eval_episodes,
                "checkpoint_every": plan.checkpoint_every,
                "env_kwargs": plan.env_kwargs,
                "overrides": plan.overrides,
                "loop": {k: v for k, v in plan.loop.items() if k != "env_kwargs"},
                "hyperparams": {
                    k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v))
                    for k, v in plan.kwargs.items()
                },
                "checkpoint": self.checkpoint_info,
                "resumed_at": self.resumed_at,
                "owner": self.owner,
                "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "best_mean_return": self.best if math.isfinite(self.best) else None,
                "throughput": self.throughput,
                "analytic": self.analytic,
                "evaluations": self.rows,
            },
        )

    def _log_end(self, result: RunResult) -> None:
        log, tp, analytic = self.log, result.throughput, result.analytic
        if tp:
            log(
                f"throughput: {tp['steps_per_second']:,.0f} env steps/s of wall time "
                f"({tp['steps_per_second_without_eval']:,.0f} without evaluation, "
                f"{tp['steps_per_cpu_second']:,.0f} per CPU second); "
                f"vector env {tp['env_share']:.1%} of it, simulator {tp['sim_share']:.1%}; "
                f"learner {tp['learner_us_per_step']:.0f} µs per env step"
            )
        if result.evaluations:
            best = max(result.evaluations, key=lambda r: r["mean_return"])
            log(
                f"best evaluation: return {best['mean_return']:.2f}, success "
                f"{best['success_rate']:.1%} at {best['env_steps']:,d} steps (analytic: "
                f"{analytic['mean_return']:.2f}, {analytic['success_rate']:.1%})"
            )
        if result.status == "interrupted":
            log(
                f"interrupted at {result.steps_done:,d} of {self.plan.timesteps:,d} steps; "
                f"continue with: python -m agents.train --resume {result.out}"
            )
        else:
            log(
                f"run folder: {result.out}  (best_model.zip, learning_curve.png, monitor.csv, run.json)"
            )


def _monitor_start(path: Path, default: float) -> float:
    """``t_start`` from the JSON header line SB3's monitor file starts with."""
    import json

    with path.open() as f:
        first = f.readline()
    try:
        return float(json.loads(first.lstrip("#"))["t_start"])
    except (ValueError, KeyError, TypeError):
        return default


def _callback(session: _Session) -> BaseCallback:
    from stable_baselines3.common.callbacks import BaseCallback

    plan = session.plan
    last_eval = session.rows[-1]["env_steps"] if session.rows else 0

    class RunCallback(BaseCallback):
        """At every vector step: stop when asked; evaluate every ``eval_freq`` env steps and
        save a checkpoint every ``checkpoint_every``; evaluate once more at the end."""

        def __init__(self) -> None:
            super().__init__()
            self.stopped = False
            self.next_eval = last_eval + plan.eval_freq
            self.next_checkpoint = session.start_steps + plan.checkpoint_every

        def _on_step(self) -> bool:
            if session.stop():
                self.stopped = True
                return False
            if self.num_timesteps >= self.next_eval:
                self.next_eval += plan.eval_freq * (
                    1 + (self.num_timesteps - self.next_eval) // plan.eval_freq
                )
                session.evaluate()
            if self.num_timesteps >= self.next_checkpoint:
                self.next_checkpoint += plan.checkpoint_every * (
                    1 + (self.num_timesteps - self.next_checkpoint) // plan.checkpoint_every
                )
                session.checkpoint()
            return True

        def _on_training_end(self) -> None:
            done = not session.rows or session.rows[-1]["env_steps"] != self.num_timesteps
            if not self.stopped and done:
                session.evaluate()

    return RunCallback()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents.train`` (see :mod:`agents.train_cli`)."""
    from .train_cli import main as cli_main

    return cli_main(argv)


if __name__ == "__main__":
    from .train_cli import PROG

    sys.exit(cli.run(main, PROG))
