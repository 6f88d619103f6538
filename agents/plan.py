"""The settings of a training run, checked before anything is created.

:func:`make_plan` fills the defaults from the config file (:mod:`agents.config`), applies the
user's overrides and checks every value; :func:`plan_of_record` reads them back from a run's
``run.json`` for ``--resume``. Every failure is a :class:`~rigid_env.cli.UsageError` (a
``ValueError``) naming the setting.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigid_env import resources
from rigid_env.cli import UsageError

from . import config, hyperparameters
from .rollout import make_vec

DEFAULT_ENV = "RigidEnv/Reorient-v0"
DEFAULT_EVAL_SEED = 1000  # evaluation episodes are seeds 1000, 1001, ...: not training streams
MAX_SEED = 2**32 - 1  # numpy's legacy seeding (used by SB3's set_random_seed) stops here
POSITIVE_LOOP_KEYS = ("n_timesteps", "n_envs", "eval_freq", "eval_episodes")
# Set by agents.train itself, never by a config file or an override.
RESERVED = ("self", "env", "seed", "device", "verbose", "_init_setup_model", "tensorboard_log")


def algo_class(algo: str) -> Any:
    """The SB3 class of ``algo`` (``"ppo"`` or ``"sac"``)."""
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[algo]


def split_overrides(algo: str, overrides: dict[str, Any]) -> tuple[dict, dict]:
    """(loop settings, algorithm kwargs) from user ``overrides``; UsageError for a key that is
    neither a loop key nor an argument of the algorithm, or a loop value of the wrong kind."""
    allowed = set(inspect.signature(algo_class(algo).__init__).parameters) - set(RESERVED)
    loop, kwargs = {}, {}
    for key, value in overrides.items():
        if key in config.LOOP_KEYS:
            loop[key] = value
        elif key in allowed:
            kwargs[key] = value
        else:
            expected = sorted((*config.LOOP_KEYS, *allowed))
            raise UsageError(
                f"overrides (--set): unknown key {key!r} for {algo}; expected one of {expected}"
            )
    for key in POSITIVE_LOOP_KEYS:
        value = loop.get(key)
        if value is not None and (type(value) is not int or value < 1):
            raise UsageError(f"overrides (--set): {key} must be an integer >= 1, got {value!r}")
    if not isinstance(loop.get("env_kwargs", {}), dict):
        raise UsageError(
            f"overrides (--set): env_kwargs must be a mapping, got {loop['env_kwargs']!r}"
        )
    return loop, kwargs


@dataclass
class Plan:
    """The validated settings of a run; all of them are stored in ``run.json``."""

    env_id: str
    algo: str
    timesteps: int
    n_envs: int
    seed: int
    eval_seed: int
    eval_freq: int  # env steps between evaluations
    eval_episodes: int
    checkpoint_every: int  # env steps between checkpoints
    env_kwargs: dict
    overrides: dict  # as the user gave them (plain values)
    loop: dict  # the config file's loop settings, overrides applied
    kwargs: dict  # SB3 algorithm arguments, schedules resolved


def _count(value: object, name: str, minimum: int = 1, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise UsageError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        raise UsageError(f"{name} must be an integer <= {maximum}, got {value!r}")
    return int(value)


def make_plan(
    env_id: str = DEFAULT_ENV,
    algo: str = "ppo",
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    overrides: dict | None = None,
    eval_seed: int = DEFAULT_EVAL_SEED,
    checkpoint_every: int | None = None,
) -> Plan:
    """Check every setting (``UsageError``, a ``ValueError``, naming the bad one) and fill the
    defaults from the config file; nothing is created."""
    import gymnasium as gym

    if not isinstance(env_id, str) or env_id not in gym.registry:
        ours = sorted(i for i in gym.registry if i.startswith("RigidEnv/"))
        raise UsageError(f"env_id: unknown env id {env_id!r}; expected one of {ours}")
    if algo not in config.ALGOS:
        raise UsageError(f"algo must be one of {config.ALGOS}, got {algo!r}")
    try:
        loop, kwargs = config.load(env_id, algo)
    except ValueError as error:  # no hyperparameters for this env and algorithm
        raise UsageError(str(error)) from None
    overrides = dict(overrides or {})
    loop_overrides, kwarg_overrides = split_overrides(algo, overrides)
    hyperparameters.check(algo, kwarg_overrides, "overrides (--set)")
    loop.update(loop_overrides)
    try:
        kwargs.update(config.resolve(kwarg_overrides))
    except (ValueError, TypeError, AttributeError, NameError, SyntaxError) as error:
        raise UsageError(f"overrides (--set): {kwarg_overrides}: {error}") from None
    timesteps = _count(loop["n_timesteps"] if timesteps is None else timesteps, "timesteps")
    n_envs = _count(loop["n_envs"] if n_envs is None else n_envs, "n_envs")
    eval_freq = _count(loop.get("eval_freq", max(timesteps // 10, n_envs)), "eval_freq")
    plan = Plan(
        env_id=env_id,
        algo=algo,
        timesteps=timesteps,
        n_envs=n_envs,
        seed=_count(seed, "seed", 0, MAX_SEED),
        eval_seed=_count(eval_seed, "eval_seed", 0, MAX_SEED),
        eval_freq=eval_freq,
        eval_episodes=_count(loop.get("eval_episodes", 100), "eval_episodes"),
        checkpoint_every=_count(
            eval_freq if checkpoint_every is None else checkpoint_every, "checkpoint_every"
        ),
        env_kwargs=dict(loop["env_kwargs"]),
        overrides=overrides,
        loop=loop,
        kwargs=kwargs,
    )
    hyperparameters.check_combination(algo, plan.kwargs, plan.n_envs, "settings")
    check_memory(plan)
    if "env_kwargs" in loop_overrides:  # the user's: try them on a one-env instance
        try:
            make_vec(env_id, 1, **plan.env_kwargs).close()
        except (TypeError, ValueError) as error:
            raise UsageError(f"env_kwargs: {env_id} rejects {plan.env_kwargs}: {error}") from None
    return plan


def check_memory(plan: Plan, kwargs: dict | None = None) -> None:
    """UsageError when the run's training env, evaluation env, SB3 buffer and networks cannot
    fit in this machine's memory (``kwargs``: the algorithm's, default the plan's)."""
    kwargs = plan.kwargs if kwargs is None else kwargs
    envs = resources.env_bytes(plan.env_id, plan.n_envs)
    evaluation = resources.env_bytes(plan.env_id, plan.eval_episodes)
    parts = {"training envs": envs, "evaluation envs": evaluation}
    spaces = resources.ENV_SPACES.get(plan.env_id)
    if spaces is not None:
        parts.update(
            hyperparameters.memory_bytes(plan.algo, kwargs, plan.n_envs, plan.timesteps, spaces)
        )
    sizes = ", ".join(f"{k} {resources.size_text(v)}" for k, v in parts.items())
    resources.check_fits(
        sum(parts.values()),
        f"training {plan.env_id} with n_envs {plan.n_envs} and eval_episodes "
        f"{plan.eval_episodes} ({sizes})",
    )


def plan_of_record(record: dict) -> Plan:
    """The plan stored in a run's ``run.json`` (checked again)."""
    import gymnasium as gym

    try:
        plan = Plan(
            env_id=record["env_id"],
            algo=record["algo"],
            timesteps=_count(record["timesteps"], "timesteps"),
            n_envs=_count(record["n_envs"], "n_envs"),
            seed=_count(record["seed"], "seed", 0, MAX_SEED),
            eval_seed=_count(record["eval_seed"], "eval_seed", 0, MAX_SEED),
            eval_freq=_count(record["eval_freq"], "eval_freq"),
            eval_episodes=_count(record["eval_episodes"], "eval_episodes"),
            checkpoint_every=_count(record["checkpoint_every"], "checkpoint_every"),
            env_kwargs=dict(record["env_kwargs"]),
            overrides=dict(record.get("overrides", {})),
            loop=dict(record["loop"]),
            kwargs={},  # the checkpoint holds the algorithm's own settings
        )
    except (KeyError, TypeError, ValueError) as error:
        raise UsageError(f"run.json: missing or bad setting ({error}); cannot resume") from None
    if plan.algo not in config.ALGOS:
        raise UsageError(f"run.json: algo must be one of {config.ALGOS}, got {plan.algo!r}")
    if not isinstance(plan.env_id, str) or plan.env_id not in gym.registry:
        raise UsageError(f"run.json: unknown env id {plan.env_id!r}; cannot resume")
    check_memory(plan, {})  # the buffers are the checkpoint's, sized as it was trained
    try:
        make_vec(plan.env_id, 1, **plan.env_kwargs).close()
    except (TypeError, ValueError) as error:
        raise UsageError(
            f"run.json: env_kwargs: {plan.env_id} rejects {plan.env_kwargs}: {error}"
        ) from None
    return plan
