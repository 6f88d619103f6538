"""Train a stable-baselines3 baseline on a native vector env.

    python -m agents.train --env RigidEnv/Reorient-v0 --algo ppo [--timesteps N --seed S
                           --n-envs K --out DIR]

Hyperparameters come from ``agents/hyperparams/<env>.yml``. The run folder (default a fresh
``runs/<env>-<algo>-<time>``, printed at the start and the end) gets ``best_model.zip`` (best
mean return at a seeded evaluation), ``final_model.zip``, ``monitor.csv`` (every training
episode, from SB3's ``VecMonitor``), ``evaluations.csv``, ``learning_curve.png`` and ``run.json``
(settings and measured figures, which ``agents.evaluate`` reads to rebuild the env).

Throughput is measured on the way: env steps per second of wall time, and the shares of it spent
inside the vector env and inside the simulator's ``Scene.step``.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rigid_env.sim import StageTimer

from . import config
from .rollout import make_vec, run_episodes

DEFAULT_EVAL_SEED = 1000  # evaluation episodes are seeds 1000, 1001, ...: not training streams


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


def _eval_callback(env_id, env_kwargs, out, eval_freq, eval_episodes, eval_seed, log):
    from stable_baselines3.common.callbacks import BaseCallback

    class SeededEval(BaseCallback):
        """Every ``eval_freq`` env steps: the deterministic policy on the same seeded episodes
        (batched, :func:`agents.rollout.run_episodes`); keeps ``best_model.zip``."""

        def __init__(self):
            super().__init__()
            self.rows: list[dict] = []
            self.best = -np.inf
            self.seconds = 0.0
            self._next = 0

        def evaluate(self) -> None:
            start = time.perf_counter()
            policy = self.model.policy

            def act(obs):
                return policy.predict(obs, deterministic=True)[0]

            summary = run_episodes(env_id, act, eval_episodes, eval_seed, env_kwargs).summary()
            row = {"env_steps": int(self.num_timesteps), **summary}
            self.rows.append(row)
            best = summary["mean_return"] > self.best
            if best:
                self.best = summary["mean_return"]
                self.model.save(out / "best_model.zip")
            self.seconds += time.perf_counter() - start
            log(
                f"eval @ {self.num_timesteps:>9,d} steps: return {summary['mean_return']:8.2f} "
                f"± {summary['std_return']:6.2f}, success {summary['success_rate']:6.1%}"
                + ("  (new best)" if best else "")
            )

        def _on_training_start(self) -> None:
            self._next = self.num_timesteps + eval_freq

        def _on_step(self) -> bool:
            if self.num_timesteps >= self._next:
                self._next += eval_freq
                self.evaluate()
            return True

        def _on_training_end(self) -> None:
            if not self.rows or self.rows[-1]["env_steps"] != self.num_timesteps:
                self.evaluate()

    return SeededEval()


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
    env_id: str = "RigidEnv/Reorient-v0",
    algo: str = "ppo",
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    out: str | Path | None = None,
    overrides: dict | None = None,
    eval_seed: int = DEFAULT_EVAL_SEED,
    progress: bool = True,
    log=None,
) -> RunResult:
    """Train ``algo`` on ``env_id`` with the config file's hyperparameters (``overrides`` on
    top: loop keys or algorithm kwargs); returns the run's figures (also in ``run.json``)."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import VecMonitor

    from .plots import learning_curve
    from .policies import make_policy
    from .vec_adapter import GymVectorToSB3

    log = log or functools.partial(print, flush=True)  # flushed: progress shows when piped
    torch.set_num_threads(1)  # small MLPs: threads cost more than they give on 2 cores
    loop, kwargs = config.load(env_id, algo)
    if overrides:
        extra = dict(overrides)
        loop.update({k: extra.pop(k) for k in config.LOOP_KEYS if k in extra})
        kwargs.update(config.resolve(extra))
    timesteps = int(timesteps or loop["n_timesteps"])
    n_envs = int(n_envs or loop["n_envs"])
    env_kwargs = dict(loop["env_kwargs"])
    eval_freq = int(loop.get("eval_freq", max(timesteps // 10, n_envs)))
    eval_episodes = int(loop.get("eval_episodes", 100))

    out = Path(out) if out is not None else default_out(env_id, algo)
    out.mkdir(parents=True, exist_ok=True)
    log(f"run folder: {out}")
    log(
        f"training {algo.upper()} on {env_id}: {timesteps:,d} env steps, {n_envs} envs, seed {seed}"
    )

    venv = make_vec(env_id, n_envs, **env_kwargs)
    task = venv.unwrapped.task
    timed = task.scene.timer = StageTimer()  # the simulator's share of the wall time
    adapter = GymVectorToSB3(venv)
    env = VecMonitor(adapter, filename=str(out / "monitor.csv"), info_keywords=("is_success",))
    env.seed(seed)

    cls = {"ppo": PPO, "sac": SAC}[algo]
    model = cls(env=env, seed=seed, device="cpu", verbose=0, **kwargs)

    analytic = run_episodes(
        env_id,
        lambda e: make_policy("analytic", env_id, e),
        eval_episodes,
        eval_seed,
        env_kwargs,
        policy_needs_env=True,
    ).summary()
    log(
        f"analytic controller on the evaluation episodes: return {analytic['mean_return']:.2f}, "
        f"success {analytic['success_rate']:.1%}"
    )
    callback = _eval_callback(env_id, env_kwargs, out, eval_freq, eval_episodes, eval_seed, log)

    start, cpu_start = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=timesteps, callback=callback, progress_bar=progress)
    learn_seconds = time.perf_counter() - start
    cpu_seconds = time.process_time() - cpu_start
    model.save(out / "final_model.zip")
    env.close()

    throughput = Throughput(
        env_steps=int(model.num_timesteps),
        learn_seconds=learn_seconds,
        cpu_seconds=cpu_seconds,
        eval_seconds=callback.seconds,
        env_seconds=adapter.env_seconds,
        sim_seconds=timed.step_seconds,
    ).as_dict()
    result = RunResult(out, env_id, algo, callback.rows, throughput, analytic)
    _write_records(result, loop, kwargs, timesteps, n_envs, seed, eval_seed, env_kwargs)
    learning_curve(
        result.evaluations, analytic, out / "learning_curve.png", f"{algo.upper()} on {env_id}"
    )
    best = max(result.evaluations, key=lambda r: r["mean_return"])
    log(
        f"throughput: {throughput['steps_per_second']:,.0f} env steps/s of wall time "
        f"({throughput['steps_per_second_without_eval']:,.0f} without evaluation, "
        f"{throughput['steps_per_cpu_second']:,.0f} per CPU second); "
        f"vector env {throughput['env_share']:.1%} of it, simulator {throughput['sim_share']:.1%}; "
        f"learner {throughput['learner_us_per_step']:.0f} µs per env step"
    )
    log(
        f"best evaluation: return {best['mean_return']:.2f}, success {best['success_rate']:.1%} "
        f"at {best['env_steps']:,d} steps (analytic: {analytic['mean_return']:.2f}, "
        f"{analytic['success_rate']:.1%})"
    )
    log(f"run folder: {out}  (best_model.zip, learning_curve.png, monitor.csv, run.json)")
    return result


def _write_records(result, loop, kwargs, timesteps, n_envs, seed, eval_seed, env_kwargs) -> None:
    out = result.out
    header = list(result.evaluations[0])
    lines = [",".join(header)] + [",".join(str(r[k]) for k in header) for r in result.evaluations]
    (out / "evaluations.csv").write_text("\n".join(lines) + "\n")
    record = {
        "env_id": result.env_id,
        "algo": result.algo,
        "timesteps": timesteps,
        "n_envs": n_envs,
        "seed": seed,
        "eval_seed": eval_seed,
        "env_kwargs": env_kwargs,
        "loop": {k: v for k, v in loop.items() if k != "env_kwargs"},
        "hyperparams": {
            k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v))
            for k, v in kwargs.items()
        },
        "throughput": result.throughput,
        "analytic": result.analytic,
        "evaluations": result.evaluations,
    }
    (out / "run.json").write_text(json.dumps(record, indent=2, default=repr))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m agents.train", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--env", default="RigidEnv/Reorient-v0")
    parser.add_argument("--algo", choices=config.ALGOS, default="ppo")
    parser.add_argument("--timesteps", type=int, default=None, help="default: the config file's")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-envs", type=int, default=None, help="default: the config file's")
    parser.add_argument("--out", default=None, help="run folder (default: a fresh one in runs/)")
    parser.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="KEY=YAML",
        help="override hyperparameters, e.g. --set n_steps=128 learning_rate=lin_3e-4",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    import yaml

    overrides = {}
    for item in args.set:
        key, _, value = item.partition("=")
        overrides[key] = yaml.safe_load(value)
    train(
        args.env,
        args.algo,
        args.timesteps,
        args.seed,
        args.n_envs,
        args.out,
        overrides,
        progress=not args.no_progress,
    )


if __name__ == "__main__":
    main()
