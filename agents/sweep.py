"""Seeds and hyperparameter sweeps on Ray Tune: every (config, seed) is one trial of agents.train.

    python -m agents.sweep --env RigidEnv/Reorient-v0 --algo ppo --seeds 5
        [--set KEY=YAML ...] [--search KEY=SPACE ...] [--samples N] [--metric M]
        [--address ADDRESS] [--num-cpus N] [--cpus-per-trial C] [--max-failures F] [--out DIR]
    python -m agents.sweep --resume DIR [--address ADDRESS] [--num-cpus N]

Each trial calls :func:`agents.train.train` and writes its own run folder
``DIR/runs/<config>/seed-<k>/`` (``final_model.zip``, ``best_model.zip``, ``monitor.csv``,
``run.json`` as ``agents.train`` writes them; ``trial.json``: config, seed, Ray node), and
``DIR/runs/<config>/attempts/seed-<k>.jsonl``: one line per start of the trial, so a retry
shows (a retried trial starts its run folder afresh). The sweep folder also gets
``sweep.json`` (the settings), ``tune/`` (Ray Tune's experiment state), ``results.json`` (per
config: mean and interquartile mean of the final evaluation return and success rate over seeds,
with 95 % bootstrap intervals; :mod:`agents.stats`), ``learning_curves.png`` and
``final_scores.png``.

``--set`` fixes a hyperparameter for every trial (as ``agents.train --set``); dotted keys change
one entry of a dict, e.g. ``policy_kwargs.net_arch=[64,64]``. ``--search KEY=SPACE`` varies one:
``grid(v1, v2, ...)`` runs every value (all grid axes crossed, no searcher); ``uniform(a, b)``,
``loguniform(a, b)``, ``int(a, b)`` (inclusive) and ``choice(v1, v2, ...)`` are sampled by Tune's
Optuna searcher for ``--samples`` configs, each run with every seed (Tune's ``Repeater``, which
reports the mean over seeds of ``--metric`` to Optuna).

Without ``--address`` (or ``RAY_ADDRESS``) a local Ray instance runs the trials; with it the
sweep joins a running cluster (``ray start --head`` on one machine, ``ray start --address ...`` on
the others, then ``--address auto`` on the head). On a cluster ``--out`` must be a folder every
node sees (a shared file system), as Ray Tune requires of its storage. Ray retries a trial whose
worker or node died (``--max-failures``); an interrupted sweep (Ctrl-C) resumes with
``--resume DIR``, which re-runs only the unfinished trials.
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import os
import re
import shutil
import socket
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from . import config

if TYPE_CHECKING:
    from ray.tune import ResultGrid

SETTINGS_FILE = "sweep.json"
RESULTS_FILE = "results.json"
TRIAL_FILE = "trial.json"
EXPERIMENT = "tune"  # Ray Tune's experiment folder inside the sweep folder
METRICS = ("mean_return", "success_rate")
SAMPLED = ("uniform", "loguniform", "int", "choice")
SPACES = (*SAMPLED, "grid")
LOCAL_OBJECT_STORE = 256 * 2**20  # trials exchange only small dicts: keep /dev/shm for others


# ---------------------------------------------------------------- parsing and validation


_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def parse_value(text: str) -> Any:
    """A YAML value, with ``1e-4`` read as a number (YAML 1.1 would keep it a string)."""
    return _numbers(yaml.safe_load(text))


def _numbers(value: Any) -> Any:
    if isinstance(value, str) and _NUMBER.fullmatch(value):
        return float(value)
    if isinstance(value, list):
        return [_numbers(v) for v in value]
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items()}
    return value


def parse_space(text: str) -> tuple[str, list]:
    """``"loguniform(1e-4, 1e-3)"`` → ``("loguniform", [0.0001, 0.001])``."""
    match = re.fullmatch(r"\s*(\w+)\((.*)\)\s*", text, re.S)
    if not match or match.group(1) not in SPACES:
        raise ValueError(
            f"--search: {text!r} is not one of uniform(a, b), loguniform(a, b), int(a, b), "
            "choice(v1, ...), grid(v1, ...)"
        )
    kind = match.group(1)
    try:
        values = parse_value(f"[{match.group(2)}]")
    except yaml.YAMLError as error:
        raise ValueError(f"--search: cannot read the values of {text!r}: {error}") from None
    if kind in ("choice", "grid"):
        if not values:
            raise ValueError(f"--search: {text!r} needs at least one value")
        return kind, values
    if len(values) != 2 or not all(isinstance(v, (int, float)) for v in values):
        raise ValueError(f"--search: {kind} takes two numbers, got {text!r}")
    low, high = values
    if not low < high:
        raise ValueError(f"--search: {text!r} needs a < b")
    if kind == "loguniform" and low <= 0:
        raise ValueError(f"--search: {text!r} needs a > 0")
    if kind == "int":
        if low != int(low) or high != int(high):
            raise ValueError(f"--search: int(a, b) takes integers, got {text!r}")
        return kind, [int(low), int(high)]
    return kind, [float(low), float(high)]


def parse_assignments(items: list[str], option: str) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{option}: expected KEY=VALUE, got {item!r}")
        out[key.strip()] = value
    return out


def check_keys(keys: Iterable[str], env_id: str, algo: str, option: str) -> None:
    """Every key must be a training-loop key or an argument of the SB3 algorithm; a dotted key
    must name an entry of a dict-valued one (``policy_kwargs.net_arch``)."""
    from stable_baselines3 import PPO, SAC

    cls = {"ppo": PPO, "sac": SAC}[algo]
    allowed = (set(config.LOOP_KEYS) | set(inspect.signature(cls).parameters)) - {
        "self",
        "env",
        "seed",
        "device",
        "verbose",
        "_init_setup_model",
    }
    block = raw_block(env_id, algo)
    for key in keys:
        head, dot, _ = key.partition(".")
        if head not in allowed:
            hint = " (use --seeds)" if head == "seed" else ""
            raise ValueError(f"{option}: {head!r} is not a setting of {algo.upper()}{hint}")
        if dot and not isinstance(block.get(head, {}), dict):
            raise ValueError(f"{option}: {head!r} is not a dict, so {key!r} cannot name an entry")


def raw_block(env_id: str, algo: str) -> dict:
    """The env's block of the algorithm's hyperparameter file as written (schedules
    unresolved), with ``policy_kwargs`` as a dict so that dotted keys can name its entries."""
    config.load(env_id, algo)  # ValueError naming env_id / algo when there is none
    block = dict(yaml.safe_load(config.config_path(algo).read_text())[env_id])
    if "policy_kwargs" in block:
        # Plain values only (an activation by its torch.nn name): trial settings go to run.json.
        kwargs = config.policy_kwargs(block["policy_kwargs"])
        block["policy_kwargs"] = {
            k: v.__name__ if isinstance(v, type) else v for k, v in kwargs.items()
        }
    return block


def expand(overrides: dict, block: dict) -> dict:
    """Dotted keys merged into their dict: ``policy_kwargs.net_arch`` keeps the file's other
    ``policy_kwargs`` entries (``agents.train`` replaces a dict override whole)."""
    out = {k: v for k, v in overrides.items() if "." not in k}
    for key, value in overrides.items():
        if "." in key:
            head, tail = key.split(".", 1)
            base = out.get(head, block.get(head) or {})
            out[head] = {**base, tail: value}
    return out


def config_key(params: dict) -> str:
    """Folder name of a config: a short hash of its searched values (``c-<8 hex>``)."""
    text = json.dumps(params, sort_keys=True, default=repr)
    return "c-" + hashlib.sha1(text.encode()).hexdigest()[:8]


def make_settings(args: argparse.Namespace) -> dict:
    """Validated sweep settings (what ``sweep.json`` holds)."""
    if args.algo not in config.ALGOS:
        raise ValueError(f"--algo must be one of {config.ALGOS}, got {args.algo!r}")
    if args.seeds < 1:
        raise ValueError(f"--seeds must be at least 1, got {args.seeds}")
    if args.cpus_per_trial <= 0:
        raise ValueError(f"--cpus-per-trial must be positive, got {args.cpus_per_trial}")
    if args.max_failures < 0:
        raise ValueError(f"--max-failures must be at least 0, got {args.max_failures}")
    try:
        config.load(args.env, args.algo)
    except ValueError as error:
        raise ValueError(f"--env: {error}") from None
    sets = {k: parse_value(v) for k, v in parse_assignments(args.set, "--set").items()}
    search = parse_assignments(args.search, "--search")
    spaces = {k: parse_space(v) for k, v in search.items()}
    check_keys(sets, args.env, args.algo, "--set")
    check_keys(spaces, args.env, args.algo, "--search")
    both = set(sets) & set(spaces)
    if both:
        raise ValueError(f"--set and --search both give {sorted(both)}")
    kinds = {kind for kind, _ in spaces.values()}
    sampled = bool(kinds & set(SAMPLED))
    if sampled and "grid" in kinds:
        raise ValueError("--search: grid(...) cannot be mixed with sampled spaces")
    if args.samples is not None and not sampled:
        raise ValueError("--samples: only for sampled --search spaces (uniform, choice, ...)")
    if args.samples is not None and args.samples < 1:
        raise ValueError(f"--samples must be at least 1, got {args.samples}")
    samples = (args.samples or 10) if sampled else 1
    grid_configs = 1
    for kind, values in spaces.values():
        if kind == "grid":
            grid_configs *= len(values)
    return {
        "env_id": args.env,
        "algo": args.algo,
        "seeds": list(range(args.seeds)),
        "set": sets,
        "search": search,
        "samples": samples,
        "configs": samples if sampled else grid_configs,
        "metric": args.metric,
        "cpus_per_trial": args.cpus_per_trial,
        "max_failures": args.max_failures,
    }


def _encode(value: Any) -> Any:
    """Optuna's categorical choices must be scalars: lists travel as YAML text."""
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, default_flow_style=True).strip()
    return value


def param_space(settings: dict) -> tuple[dict, bool]:
    """(Tune search space, whether it needs a searcher)."""
    from ray import tune

    space: dict = {}
    sampled = False
    for key, text in settings["search"].items():
        kind, values = parse_space(text)
        if kind == "grid":
            space[key] = tune.grid_search(values)
        elif kind == "uniform":
            space[key] = tune.uniform(*values)
        elif kind == "loguniform":
            space[key] = tune.loguniform(*values)
        elif kind == "int":
            space[key] = tune.randint(values[0], values[1] + 1)  # Tune's upper bound is open
        else:
            space[key] = tune.choice([_encode(v) for v in values])
        sampled |= kind in SAMPLED
    if not sampled:
        space["seed"] = tune.grid_search(settings["seeds"])
    return space, sampled


# ---------------------------------------------------------------- one trial (on a Ray worker)


def _strict(obj: Any) -> Any:
    """NaN (no interval from one seed) as JSON null, which every JSON reader accepts."""
    if isinstance(obj, float) and obj != obj:
        return None
    if isinstance(obj, dict):
        return {k: _strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_strict(v) for v in obj]
    return obj


def write_json(path: Path, obj: Any) -> None:
    """Write JSON atomically: a reader sees the old file or the new one, never half of one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "w") as f:
        json.dump(_strict(obj), f, indent=2, default=repr, allow_nan=False)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def run_dir(sweep_dir: str | Path, key: str, seed: int) -> Path:
    """The run folder of one trial, as ``agents.train`` writes it (plus ``trial.json``)."""
    return Path(sweep_dir) / "runs" / key / f"seed-{seed}"


def attempts_path(sweep_dir: str | Path, key: str, seed: int) -> Path:
    """One JSON line per start of the trial (node, process, time): kept outside the run folder,
    which a new attempt starts empty."""
    return Path(sweep_dir) / "runs" / key / "attempts" / f"seed-{seed}.jsonl"


def trial_params(trial_config: dict, settings: dict) -> tuple[dict, int]:
    """(searched values, seed) of a trial's Tune config."""
    params = {k: v for k, v in trial_config.items() if k not in ("seed", "__trial_index__")}
    for key, text in settings["search"].items():
        if parse_space(text)[0] == "choice" and isinstance(params.get(key), str):
            params[key] = parse_value(params[key])  # undo _encode
    if "seed" in trial_config:
        seed = int(trial_config["seed"])
    else:
        seed = settings["seeds"][int(trial_config["__trial_index__"])]
    return params, seed


def run_trial(trial_config: dict, settings: dict) -> None:
    """Tune trainable: train one (config, seed) with agents.train into its run folder and report
    the final evaluation."""
    import ray
    from ray import tune

    from .train import train

    params, seed = trial_params(trial_config, settings)
    key = config_key(params)
    out = run_dir(settings["sweep_dir"], key, seed)
    log_path = attempts_path(settings["sweep_dir"], key, seed)
    log_path.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():  # left by an attempt that died: this one starts the run afresh
        shutil.rmtree(out)
    node_id = ray.get_runtime_context().get_node_id()
    started = {
        "trial_id": tune.get_context().get_trial_id(),
        "node_id": node_id,
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "time": time.time(),
    }
    with open(log_path, "a") as f:
        f.write(json.dumps(started) + "\n")
        f.flush()
        os.fsync(f.fileno())

    overrides = expand({**settings["set"], **params}, settings["block"])
    tag = f"[{key} seed {seed}]"
    result = train(
        settings["env_id"],
        settings["algo"],
        seed=seed,
        out=out,
        overrides=overrides,
        progress=False,
        log=lambda message: print(f"{tag} {message}", flush=True),
    )
    final = result.evaluations[-1]
    record = {**started, "config_key": key, "config": params, "seed": seed, "final": final}
    write_json(out / TRIAL_FILE, record)
    tune.report(
        {
            **{m: final[m] for m in METRICS},
            "env_steps": final["env_steps"],
            "config_key": key,
            "seed": seed,
            "node_id": node_id,
            "run_dir": str(out),
        }
    )


# ---------------------------------------------------------------- the sweep (driver)


def connect(address: str | None, num_cpus: int | None) -> None:
    import ray

    if address:
        print(f"joining the Ray cluster at {address}", flush=True)
        ray.init(address=address)
    else:
        ray.init(num_cpus=num_cpus, include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE)
    cpus = ray.cluster_resources().get("CPU", 0)
    print(f"Ray: {len(ray.nodes())} node(s), {cpus:g} CPUs", flush=True)


def run_tune(settings: dict[str, Any], sweep_dir: Path, resume: bool) -> ResultGrid:
    """Run (or resume) the trials; returns Tune's ResultGrid."""
    from ray import tune
    from ray.tune.search import Repeater
    from ray.tune.search.optuna import OptunaSearch

    trial_settings = {
        **settings,
        "sweep_dir": str(sweep_dir),
        "block": raw_block(settings["env_id"], settings["algo"]),
    }
    trainable = tune.with_resources(
        tune.with_parameters(run_trial, settings=trial_settings),
        {"cpu": settings["cpus_per_trial"]},
    )
    experiment = sweep_dir / EXPERIMENT
    if resume:
        tuner = tune.Tuner.restore(
            str(experiment), trainable, resume_unfinished=True, restart_errored=True
        )
    else:
        space, sampled = param_space(settings)
        k = len(settings["seeds"])
        searcher = Repeater(OptunaSearch(seed=0), repeat=k, set_index=True) if sampled else None
        tuner = tune.Tuner(
            trainable,
            param_space=space,
            tune_config=tune.TuneConfig(
                metric=settings["metric"],
                mode="max",
                search_alg=searcher,
                num_samples=settings["samples"] * k if sampled else 1,
                reuse_actors=True,  # a trial process imports torch and SB3 once, not per trial
            ),
            run_config=tune.RunConfig(
                name=EXPERIMENT,
                storage_path=str(sweep_dir),
                failure_config=tune.FailureConfig(max_failures=settings["max_failures"]),
            ),
        )
    return tuner.fit()


def finished_trial_ids(sweep_dir: Path) -> set[str]:
    """Ids of the trials Ray Tune's saved experiment state calls finished (TERMINATED). A trial
    stopped by an interrupt may have written its folder without Tune recording it: it is run
    again on resume, so it does not count."""
    from ray import tune

    analysis = tune.ExperimentAnalysis(str(Path(sweep_dir) / EXPERIMENT))
    return {t.trial_id for t in analysis.trials if t.status == "TERMINATED"}


def load_trials(sweep_dir: Path, trial_ids: set[str]) -> list[dict]:
    """The finished trials ``trial_ids`` of a sweep folder: each ``trial.json`` plus the
    evaluations of its ``run.json``."""
    trials = []
    for path in sorted(Path(sweep_dir).glob(f"runs/*/seed-*/{TRIAL_FILE}")):
        trial = json.loads(path.read_text())
        if trial["trial_id"] not in trial_ids:
            continue
        run = json.loads((path.parent / "run.json").read_text())
        trials.append(
            {
                **trial,
                "evaluations": run["evaluations"],
                "analytic": run.get("analytic"),
                "run_dir": str(path.parent),
            }
        )
    return trials


def summarize_sweep(settings: dict, sweep_dir: Path, expected: int) -> dict:
    """Aggregate the finished trials; write results.json and the two figures."""
    from . import stats, sweep_plots

    trials = load_trials(sweep_dir, finished_trial_ids(sweep_dir))
    results = stats.aggregate(trials)
    summary = {
        "env_id": settings["env_id"],
        "algo": settings["algo"],
        "seeds": settings["seeds"],
        "set": settings["set"],
        "search": settings["search"],
        "trials_expected": expected,
        "trials_finished": len(trials),
        "complete": len(trials) == expected,
        "score": "final evaluation (the last periodic one, of the final model)",
        "confidence": stats.CONFIDENCE,
        "bootstrap": f"percentile, {stats.RESAMPLES} resamples over seeds",
        # The analytic controller on the same evaluation episodes (agents.train measures it).
        "analytic": next((t["analytic"] for t in trials if t.get("analytic")), None),
        "configs": results,
    }
    write_json(sweep_dir / RESULTS_FILE, summary)
    if results:
        title = f"{settings['algo'].upper()} on {settings['env_id']}"
        sweep_plots.learning_curves(
            results, sweep_dir / "learning_curves.png", title, summary["analytic"]
        )
        sweep_plots.final_scores(results, sweep_dir / "final_scores.png", title)
    return summary


def print_results(summary: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    from .sweep_plots import config_label

    def cell(s: dict, stat: str, scale: float, fmt: str) -> str:
        low, high = s[f"{stat}_ci"]
        if low != low:  # one seed: no interval
            return f"{scale * s[stat]:{fmt}}"
        return f"{scale * s[stat]:{fmt}} [{scale * low:{fmt}}, {scale * high:{fmt}}]"

    table = Table(
        title=f"{summary['algo'].upper()} on {summary['env_id']}: final evaluation over seeds, "
        f"{summary['confidence']:.0%} bootstrap intervals"
    )
    for name in (
        "config",
        "key",
        "seeds",
        "return mean",
        "return IQM",
        "success % mean",
        "success % IQM",
    ):
        table.add_column(name, justify="left" if name in ("config", "key") else "right")
    for entry in summary["configs"]:
        r, s = entry["mean_return"], entry["success_rate"]
        table.add_row(
            config_label(entry),
            entry["config_key"],
            str(r["n"]),
            cell(r, "mean", 1, ".2f"),
            cell(r, "iqm", 1, ".2f"),
            cell(s, "mean", 100, ".1f"),
            cell(s, "iqm", 100, ".1f"),
        )
    Console(width=160).print(table)


def default_out(env_id: str, algo: str) -> Path:
    name = env_id.split("/")[-1].lower()
    return Path("runs") / f"sweep-{name}-{algo}-{time.strftime('%Y%m%d-%H%M%S')}"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.sweep",
        description=__doc__.split("\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n".join(__doc__.split("\n")[1:]),
    )
    parser.add_argument("--env", default=None, help="default RigidEnv/Reorient-v0")
    parser.add_argument("--algo", default=None, help=f"one of {config.ALGOS} (default ppo)")
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..K-1 (default 5)")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=YAML")
    parser.add_argument("--search", nargs="*", default=[], metavar="KEY=SPACE")
    parser.add_argument("--samples", type=int, default=None, help="sampled configs (default 10)")
    parser.add_argument(
        "--metric", choices=METRICS, default=None, help="what Optuna maximises (mean_return)"
    )
    parser.add_argument("--address", default=None, help="a Ray cluster to join (or RAY_ADDRESS)")
    parser.add_argument("--num-cpus", type=int, default=None, help="CPUs of a local Ray instance")
    parser.add_argument("--cpus-per-trial", type=float, default=None, help="default 1")
    parser.add_argument("--max-failures", type=int, default=None, help="retries (default 3)")
    parser.add_argument("--out", default=None, help="sweep folder (default: a fresh one in runs/)")
    parser.add_argument("--resume", default=None, metavar="DIR", help="resume the sweep in DIR")
    return parser


SWEEP_OPTIONS = (
    "env",
    "algo",
    "seeds",
    "samples",
    "metric",
    "cpus_per_trial",
    "max_failures",
    "out",
)
DEFAULTS = {
    "env": "RigidEnv/Reorient-v0",
    "algo": "ppo",
    "seeds": 5,
    "metric": "mean_return",
    "cpus_per_trial": 1.0,
    "max_failures": 3,
}


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    address = args.address or os.environ.get("RAY_ADDRESS") or None
    if address and args.num_cpus is not None:
        parser.error("--num-cpus: only for a local Ray instance (the cluster has its own)")
    if args.resume:
        given = [o for o in SWEEP_OPTIONS if getattr(args, o) is not None]
        if given or args.set or args.search:
            parser.error(
                "--resume: the settings come from DIR/sweep.json; only --address and "
                f"--num-cpus may be given (got {given + ['set'] * bool(args.set) + ['search'] * bool(args.search)})"
            )
        sweep_dir = Path(args.resume).resolve()
        if not (sweep_dir / SETTINGS_FILE).is_file() or not (sweep_dir / EXPERIMENT).is_dir():
            parser.error(f"--resume: {sweep_dir} holds no sweep ({SETTINGS_FILE}, {EXPERIMENT}/)")
        settings = json.loads((sweep_dir / SETTINGS_FILE).read_text())
    else:
        for name, value in DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, value)
        try:
            settings = make_settings(args)
        except ValueError as error:
            parser.error(str(error))
        sweep_dir = Path(args.out or default_out(args.env, args.algo)).resolve()
        if (sweep_dir / SETTINGS_FILE).exists():
            parser.error(f"--out: {sweep_dir} already holds a sweep; use --resume {sweep_dir}")
        sweep_dir.mkdir(parents=True, exist_ok=True)
        write_json(sweep_dir / SETTINGS_FILE, settings)

    expected = settings["configs"] * len(settings["seeds"])
    print(
        f"sweep folder: {sweep_dir}\n{settings['algo'].upper()} on {settings['env_id']}: "
        f"{settings['configs']} config(s) x {len(settings['seeds'])} seeds = {expected} trials"
        + (" (resuming)" if args.resume else ""),
        flush=True,
    )
    connect(address, args.num_cpus)
    grid = run_tune(settings, sweep_dir, resume=bool(args.resume))
    summary = summarize_sweep(settings, sweep_dir, expected)
    if summary["configs"]:
        print_results(summary)
        print(f"results: {sweep_dir / RESULTS_FILE}, learning_curves.png, final_scores.png")
    if not summary["complete"]:
        results = [grid[i] for i in range(len(grid))]  # ResultGrid indexes; it declares no __iter__
        failed = [str(r.error).split("\n")[0] for r in results if r.error is not None]
        print(
            f"sweep incomplete: {summary['trials_finished']} of {expected} trials finished"
            + (f" ({len(failed)} failed: {failed[0]} ...)" if failed else "")
            + f"; resume with: python -m agents.sweep --resume {sweep_dir}",
            flush=True,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
