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
worker or node died (``--max-failures``); an interrupted sweep (Ctrl-C or SIGTERM: the trials
are stopped, Tune's state saved, exit status 130) resumes with ``--resume DIR``, which re-runs
only the unfinished trials. The sweep folder belongs to the one live sweep that runs it: another
``--out`` or ``--resume`` on it is refused, naming that process.

Every setting, and every value a ``--set`` or ``--search`` gives a trial, is checked before Ray
starts (as ``agents.train`` checks its own); a mistake exits with status 2 and one line on
stderr; a fault of the file system in the driver, with status 74 and one line naming the file;
a sweep some of whose trials failed, with status 1.
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import itertools
import json
import math
import os
import re
import shutil
import signal
import socket
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from rigid_env import cli
from rigid_env.cli import UsageError
from rigid_env.files import write_json as write_json_atomically

from . import config, hyperparameters, ownership, run_folder
from .plan import MAX_SEED, Plan, make_plan
from .train_cli import StopOnSignal

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
    try:
        return _numbers(yaml.safe_load(text))
    except yaml.YAMLError as error:
        problem = getattr(error, "problem", None) or "invalid YAML"
        raise UsageError(f"{problem} in {text!r}") from None


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
        raise UsageError(
            f"--search: {text!r} is not one of uniform(a, b), loguniform(a, b), int(a, b), "
            "choice(v1, ...), grid(v1, ...)"
        )
    kind = match.group(1)
    try:
        values = parse_value(f"[{match.group(2)}]")
    except UsageError as error:
        raise UsageError(f"--search: cannot read the values of {text!r}: {error}") from None
    if kind in ("choice", "grid"):
        if not values:
            raise UsageError(f"--search: {text!r} needs at least one value")
        return kind, values
    if len(values) != 2 or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values
    ):
        raise UsageError(f"--search: {kind} takes two finite numbers, got {text!r}")
    low, high = values
    if not low < high:
        raise UsageError(f"--search: {text!r} needs a < b")
    if kind == "loguniform" and low <= 0:
        raise UsageError(f"--search: {text!r} needs a > 0")
    if kind == "int":
        if low != int(low) or high != int(high):
            raise UsageError(f"--search: int(a, b) takes integers, got {text!r}")
        return kind, [int(low), int(high)]
    return kind, [float(low), float(high)]


def parse_assignments(items: list[str], option: str) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"{option}: expected KEY=VALUE, got {item!r}")
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
            raise UsageError(f"{option}: {head!r} is not a setting of {algo.upper()}{hint}")
        if dot and not isinstance(block.get(head, {}), dict):
            raise UsageError(f"{option}: {head!r} is not a dict, so {key!r} cannot name an entry")


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


MAX_TRIALS = 10_000  # (configs x seeds) of one sweep: Tune keeps every trial in memory and state
MAX_CHECKED = 256  # combinations of searched values checked together; beyond, one key at a time
# sweep.json: each setting and the JSON types it may have.
SETTINGS_TYPES: dict[str, tuple[type, ...]] = {
    "env_id": (str,),
    "algo": (str,),
    "seeds": (list,),
    "set": (dict,),
    "search": (dict,),
    "samples": (int,),
    "configs": (int,),
    "metric": (str,),
    "cpus_per_trial": (int, float),
    "max_failures": (int,),
}


def make_settings(args: argparse.Namespace) -> dict:
    """Validated sweep settings (what ``sweep.json`` holds): :func:`check_settings` of the
    arguments (the values themselves: :func:`check_values`)."""
    if args.seeds > MAX_TRIALS:
        raise UsageError(f"--seeds {args.seeds}: at most {MAX_TRIALS} trials per sweep")
    sets = {}
    for key, text in parse_assignments(args.set, "--set").items():
        try:
            sets[key] = parse_value(text)
        except ValueError as error:
            raise UsageError(f"--set {key}: {error}") from None
    search = parse_assignments(args.search, "--search")
    sampled = any(parse_space(text)[0] in SAMPLED for text in search.values())
    if args.samples is not None and not sampled:
        raise UsageError("--samples: only for sampled --search spaces (uniform, choice, ...)")
    samples = (args.samples or 10) if sampled else 1
    grid_configs = 1
    for text in search.values():
        kind, values = parse_space(text)
        if kind == "grid":
            grid_configs *= len(values)
    settings = {
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
    return check_settings(settings)


def check_settings(settings: Any, where: str = "") -> dict:
    """``settings`` (as made from the arguments, or read back from ``sweep.json``) checked in
    full: :class:`UsageError` prefixed with ``where`` for the first one that is wrong."""

    def bad(message: str) -> UsageError:
        return UsageError(f"{where}{message}")

    if not isinstance(settings, dict):
        raise bad(f"expected a JSON object of settings, got {type(settings).__name__}")
    for key, types in SETTINGS_TYPES.items():
        value = settings.get(key)
        if not isinstance(value, types) or isinstance(value, bool):
            names = " or ".join(t.__name__ for t in types)
            raise bad(f"{key} must be of type {names}, got {value!r}")
    env_id, algo = settings["env_id"], settings["algo"]
    if algo not in config.ALGOS:
        raise bad(f"--algo must be one of {config.ALGOS}, got {algo!r}")
    try:
        config.load(env_id, algo)
    except ValueError as error:
        raise bad(f"--env: {error}") from None
    seeds = settings["seeds"]
    if not (
        1 <= len(seeds) <= MAX_TRIALS
        and all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= MAX_SEED for s in seeds
        )
        and len(set(seeds)) == len(seeds)
    ):
        raise bad(f"seeds must be 1 to {MAX_TRIALS} distinct integers in [0, {MAX_SEED}]")
    sets, search = settings["set"], settings["search"]
    if not all(isinstance(text, str) for text in search.values()):
        raise bad("search must map each key to its space's text, e.g. 'grid(1, 2)'")
    try:
        spaces = {k: parse_space(v) for k, v in search.items()}
        check_keys(sets, env_id, algo, "--set")
        check_keys(spaces, env_id, algo, "--search")
    except UsageError as error:
        raise bad(str(error)) from None
    both = set(sets) & set(spaces)
    if both:
        raise bad(f"--set and --search both give {sorted(both)}")
    kinds = {kind for kind, _ in spaces.values()}
    sampled = bool(kinds & set(SAMPLED))
    if sampled and "grid" in kinds:
        raise bad("--search: grid(...) cannot be mixed with sampled spaces")
    samples = settings["samples"]
    if not 1 <= samples <= MAX_TRIALS or (not sampled and samples != 1):
        raise bad(f"--samples must be 1 to {MAX_TRIALS} (1 without sampled spaces), got {samples}")
    configs = samples
    if not sampled:
        configs = math.prod(len(values) for _, values in spaces.values())
    if settings["configs"] != configs:
        raise bad(
            f"configs must be {configs} for these spaces and samples, got {settings['configs']}"
        )
    if configs * len(seeds) > MAX_TRIALS:
        raise bad(
            f"{configs} config(s) x {len(seeds)} seeds = {configs * len(seeds)} trials; "
            f"at most {MAX_TRIALS} per sweep"
        )
    if settings["metric"] not in METRICS:
        raise bad(f"--metric must be one of {METRICS}, got {settings['metric']!r}")
    cpus = settings["cpus_per_trial"]
    if not (math.isfinite(cpus) and cpus > 0):
        raise bad(f"--cpus-per-trial must be a finite number > 0, got {cpus!r}")
    if settings["max_failures"] < 0:
        raise bad(f"--max-failures must be an integer >= 0, got {settings['max_failures']}")
    return settings


def _candidates(kind: str, values: list) -> list:
    """The values of a space that stand for all of it: every one of a grid or a choice, the
    ends of a range (the checks are ranges and bounds, so the ends decide)."""
    return list(values) if kind in ("grid", "choice") else [values[0], values[1]]


def _plain(message: str) -> str:
    return message.removeprefix("overrides (--set): ")


def check_values(settings: dict, build: bool = True) -> None:
    """Every ``--set`` value and every value a ``--search`` space can take, checked against the
    algorithm as ``agents.train`` checks them (:func:`agents.plan.make_plan`: ranges, memory),
    before any trial starts; with ``build``, SB3 builds the first config's model once (and
    once per value of a searched key that no check of ours covers)."""
    from .train import check_model

    env_id, algo, sets = settings["env_id"], settings["algo"], settings["set"]
    block = raw_block(env_id, algo)
    spaces = {k: parse_space(v) for k, v in settings["search"].items()}
    options = {k: _candidates(kind, values) for k, (kind, values) in spaces.items()}

    def plan(params: dict) -> Plan:
        overrides = expand({**sets, **params}, block)
        try:
            return make_plan(env_id, algo, overrides=overrides)
        except UsageError as error:
            if params:
                try:
                    make_plan(env_id, algo, overrides=expand(sets, block))
                except UsageError:
                    pass  # the --set values alone are wrong: say so below
                else:
                    given = ", ".join(f"{k}={v!r}" for k, v in params.items())
                    raise UsageError(f"--search ({given}): {_plain(str(error))}") from None
            raise UsageError(f"--set: {_plain(str(error))}") from None

    first = {k: values[0] for k, values in options.items()}
    if math.prod(len(values) for values in options.values()) <= MAX_CHECKED:
        combos = [dict(zip(options, c, strict=True)) for c in itertools.product(*options.values())]
    else:  # each key's values, the others at their first
        combos = [{**first, k: v} for k, values in options.items() for v in values]
    plans = [plan(params) for params in combos] or [plan({})]
    if not build:
        return
    rules = hyperparameters.RULES[algo]
    policy_rules = hyperparameters.policy_rules(algo)
    uncovered = [
        k
        for k in options
        if not (
            k in rules or k in config.LOOP_KEYS or k.removeprefix("policy_kwargs.") in policy_rules
        )
    ]
    builds = [first] + [{**first, k: v} for k in uncovered for v in options[k][1:]]
    for params in builds:
        try:
            check_model(plan(params) if params != first else plans[0])
        except UsageError as error:
            given = ", ".join(f"{k}={v!r}" for k, v in params.items())
            where_ = f"--search ({given})" if params else "--set"
            raise UsageError(f"{where_}: {_plain(str(error))}") from None


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
    write_json_atomically(path, _strict(obj), indent=2, default=repr, allow_nan=False)


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
        run_folder.refuse_if_in_use(out, "trial")  # unless that attempt still runs somewhere
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


def connect(address: str | None, num_cpus: int | None, cpus_per_trial: float) -> None:
    """Start a local Ray instance or join the cluster at ``address``; UsageError when no node
    of it has the CPUs of one trial (the trials would wait forever)."""
    import ray

    if address:
        print(f"joining the Ray cluster at {address}", flush=True)
        ray.init(address=address)
    else:
        ray.init(num_cpus=num_cpus, include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE)
    cpus = ray.cluster_resources().get("CPU", 0)
    print(f"Ray: {len(ray.nodes())} node(s), {cpus:g} CPUs", flush=True)
    largest = max((n["Resources"].get("CPU", 0) for n in ray.nodes() if n["Alive"]), default=0)
    if largest < cpus_per_trial:
        raise UsageError(
            f"--cpus-per-trial {cpus_per_trial:g}: no node of the Ray cluster has that many CPUs "
            f"(the largest has {largest:g}); no trial could start"
        )


def local_cpus() -> int:
    """The CPUs a local Ray instance gets by default (Ray counts the machine's)."""
    return os.cpu_count() or 1


def check_cpus(cpus_per_trial: float, address: str | None, num_cpus: int | None) -> None:
    """Before Ray starts: a trial must fit in a local instance (on a cluster: in ``connect``)."""
    if address:
        return
    have = num_cpus if num_cpus is not None else local_cpus()
    if cpus_per_trial > have:
        given = "--num-cpus" if num_cpus is not None else "this machine's"
        raise UsageError(
            f"--cpus-per-trial {cpus_per_trial:g}: more than the {have} CPUs of the local Ray "
            f"instance ({given}); no trial could start"
        )


def run_tune(settings: dict[str, Any], sweep_dir: Path, resume: bool) -> ResultGrid:
    """Run (or resume) the trials; returns Tune's ResultGrid. A sweep stopped before Tune
    saved its first state starts its trials afresh."""
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
    if resume and tune.Tuner.can_restore(str(experiment)):
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


PROG = "python -m agents.sweep"


def build_parser() -> cli.Parser:
    parser = cli.Parser(
        prog=PROG,
        description=__doc__.split("\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n".join(__doc__.split("\n")[1:]),
    )
    parser.add_argument("--env", type=cli.env_id, help="default RigidEnv/Reorient-v0")
    parser.add_argument("--algo", choices=config.ALGOS, help="default ppo")
    parser.add_argument("--seeds", type=cli.positive_int, help="seeds 0..K-1 (default 5)")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=YAML")
    parser.add_argument("--search", nargs="*", default=[], metavar="KEY=SPACE")
    parser.add_argument("--samples", type=cli.positive_int, help="sampled configs (default 10)")
    parser.add_argument("--metric", choices=METRICS, help="what Optuna maximises (mean_return)")
    parser.add_argument("--address", help="a Ray cluster to join (or RAY_ADDRESS)")
    parser.add_argument(
        "--num-cpus", type=cli.positive_int, help="CPUs of a local Ray instance (default: all)"
    )
    parser.add_argument("--cpus-per-trial", type=cli.positive_float, help="default 1")
    parser.add_argument("--max-failures", type=cli.nonnegative_int, help="retries (default 3)")
    parser.add_argument("--out", help="sweep folder (default: a fresh one in runs/)")
    parser.add_argument("--resume", metavar="DIR", help="resume the sweep in DIR")
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


def read_settings(sweep_dir: Path) -> dict:
    """The checked settings of the sweep in ``sweep_dir`` (UsageError naming ``sweep.json``)."""
    path = sweep_dir / SETTINGS_FILE
    if not path.is_file():
        raise UsageError(f"--resume: {sweep_dir} holds no sweep ({SETTINGS_FILE})")
    try:
        settings = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise UsageError(
            f"--resume: {path} is unreadable ({error}); expected the {SETTINGS_FILE} "
            "agents.sweep writes"
        ) from None
    return check_settings(settings, f"--resume: {path}: ")


def check_new_sweep(sweep_dir: Path) -> None:
    """UsageError unless a new sweep may be written to ``sweep_dir``; changes nothing."""
    if sweep_dir.exists() and not sweep_dir.is_dir():
        raise UsageError(f"--out: {sweep_dir} is a file; expected a new folder")
    if sweep_dir.is_dir():
        run_folder.refuse_if_in_use(sweep_dir, "--out")
        if (sweep_dir / SETTINGS_FILE).exists():
            raise UsageError(f"--out: {sweep_dir} already holds a sweep; use --resume {sweep_dir}")
        if (sweep_dir / run_folder.RUN_JSON).exists():
            raise UsageError(
                f"--out: {sweep_dir} holds a run of agents.train; expected a new folder"
            )


class StopTune(StopOnSignal):
    """While active, the first SIGINT (Ctrl-C) or SIGTERM asks Ray Tune to stop as its own
    Ctrl-C handling does (its SIGUSR1 handler: the trials are stopped and the experiment state
    saved, so the sweep resumes), and ``requested`` is set; before Tune runs, or at a second
    signal, ``KeyboardInterrupt`` is raised (exit status 130; the sweep resumes from the state
    Tune saved last). The handlers are installed and restored as the training's."""

    def __init__(self) -> None:
        super().__init__()
        self._environ: str | None = None

    def __enter__(self) -> StopTune:
        self._environ = os.environ.get("TUNE_DISABLE_SIGINT_HANDLER")
        os.environ["TUNE_DISABLE_SIGINT_HANDLER"] = "1"  # SIGINT is handled here, not by Tune
        super().__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        super().__exit__(*exc)
        if self._environ is None:
            os.environ.pop("TUNE_DISABLE_SIGINT_HANDLER", None)
        else:
            os.environ["TUNE_DISABLE_SIGINT_HANDLER"] = self._environ

    def _handle(self, signum: int, frame: Any) -> None:
        tune_listens = callable(signal.getsignal(signal.SIGUSR1))  # Tune's, during fit()
        if self.requested or not tune_listens:
            raise KeyboardInterrupt
        self.requested = True
        os.write(
            2,
            f"\n{signal.Signals(signum).name}: stopping the trials and saving the sweep's state "
            "(Ctrl-C again to quit at once)\n".encode(),
        )
        os.kill(os.getpid(), signal.SIGUSR1)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    address = args.address or os.environ.get("RAY_ADDRESS") or None
    if address and args.num_cpus is not None:
        raise UsageError("--num-cpus: only for a local Ray instance (the cluster has its own)")
    resuming = args.resume is not None
    if resuming:
        given = [o for o in SWEEP_OPTIONS if getattr(args, o) is not None]
        given += ["set"] * bool(args.set) + ["search"] * bool(args.search)
        if given:
            raise UsageError(
                "--resume: the settings come from DIR/sweep.json; only --address and "
                f"--num-cpus may be given (got {given})"
            )
        sweep_dir = Path(args.resume).resolve()
        if sweep_dir.is_dir():
            run_folder.refuse_if_in_use(sweep_dir, "--resume")
        settings = read_settings(sweep_dir)
    else:
        for name, value in DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, value)
        settings = make_settings(args)
        sweep_dir = Path(args.out or default_out(args.env, args.algo)).resolve()
        check_new_sweep(sweep_dir)
    check_cpus(settings["cpus_per_trial"], address, args.num_cpus)
    try:  # every value a trial will train with, before Ray starts
        check_values(settings)
    except UsageError as error:
        if not resuming:
            raise
        raise UsageError(f"--resume: {sweep_dir / SETTINGS_FILE}: {error}") from None
    option = "--resume" if resuming else "--out"
    with ownership.owning(sweep_dir, option):
        if resuming:
            settings = read_settings(sweep_dir)  # as it stands now that it is ours
        else:
            check_new_sweep(sweep_dir)
            cli.writable_dir(sweep_dir, "--out")
            write_json(sweep_dir / SETTINGS_FILE, settings)
        return _run(settings, sweep_dir, resuming, address, args.num_cpus)


def _run(
    settings: dict, sweep_dir: Path, resuming: bool, address: str | None, num_cpus: int | None
) -> int:
    expected = settings["configs"] * len(settings["seeds"])
    print(
        f"sweep folder: {sweep_dir}\n{settings['algo'].upper()} on {settings['env_id']}: "
        f"{settings['configs']} config(s) x {len(settings['seeds'])} seeds = {expected} trials"
        + (" (resuming)" if resuming else ""),
        flush=True,
    )
    with StopTune() as stopping:
        connect(address, num_cpus, settings["cpus_per_trial"])
        grid = run_tune(settings, sweep_dir, resume=resuming)
    summary = summarize_sweep(settings, sweep_dir, expected)
    if summary["configs"]:
        print_results(summary)
        print(f"results: {sweep_dir / RESULTS_FILE}, learning_curves.png, final_scores.png")
    if stopping.requested:
        print(
            f"{PROG}: interrupted: {summary['trials_finished']} of {expected} trials finished; "
            f"resume with --resume {sweep_dir}",
            file=sys.stderr,
            flush=True,
        )
        return cli.EXIT_INTERRUPTED
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
    sys.exit(cli.run(main, PROG))
