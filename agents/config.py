"""Hyperparameters from ``agents/hyperparams/<algo>.yml``, in the RL Zoo's format.

Each file has one block per env id, so the same file trains with ``agents.train`` and with
``python -m rl_zoo3.train --algo <algo> --env <id> --gym-packages rigid_env --conf-file <file>``.
Training-loop keys (:data:`LOOP_KEYS`) are split off (the evaluation schedule comes from the
file's ``evaluation`` section, which the Zoo does not read); the rest are keyword arguments of
the SB3 algorithm, resolved as the Zoo does: ``"lin_<x>"`` for a schedule decaying linearly from
``x`` to 0, and ``policy_kwargs`` given as a Python expression over ``dict`` and ``nn``
(``torch.nn``). Every value is checked as :mod:`agents.hyperparameters` does, naming the file,
the env and the parameter.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

HYPERPARAMS_DIR = Path(__file__).with_name("hyperparams")
LOOP_KEYS = ("n_timesteps", "n_envs", "env_kwargs", "eval_freq", "eval_episodes")
ALGOS = ("ppo", "sac")
EVALUATION = "evaluation"  # the files' section for agents.train's evaluation schedule


def config_path(algo: str) -> Path:
    """``"ppo"`` → ``hyperparams/ppo.yml``."""
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    return HYPERPARAMS_DIR / f"{algo}.yml"


def env_ids(algo: str) -> list[str]:
    """The env ids ``algo``'s file has a block for."""
    blocks = yaml.safe_load(config_path(algo).read_text())
    return [k for k in blocks if k != EVALUATION]


def load(env_id: str, algo: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(loop settings, algorithm kwargs) for ``env_id`` and ``algo``, schedules resolved."""
    path = config_path(algo)
    blocks = yaml.safe_load(path.read_text())
    if env_id == EVALUATION or env_id not in blocks:
        raise ValueError(f"env_id: {path.name} has no block for {env_id!r}")
    params = dict(blocks[env_id])
    loop = {k: params.pop(k) for k in LOOP_KEYS if k in params}
    from .hyperparameters import check

    check(algo, params, f"{path.name} ({env_id})")  # values SB3 accepts but cannot train with
    loop.update(blocks.get(EVALUATION, {}).get(env_id, {}))
    loop.setdefault("env_kwargs", {})
    return loop, resolve(params)


def resolve(params: dict[str, Any]) -> dict[str, Any]:
    """Turn the file's plain values into SB3 arguments (schedules, policy keyword arguments)."""
    import torch.nn

    out = dict(params)
    for key in ("learning_rate", "clip_range"):
        value = out.get(key)
        if isinstance(value, str) and value.startswith("lin_"):
            out[key] = linear_schedule(float(value[4:]))
    if isinstance(out.get("train_freq"), list):  # YAML has no tuples: [1, episode], as the Zoo
        out["train_freq"] = tuple(out["train_freq"])
    kwargs = policy_kwargs(out.get("policy_kwargs"))
    if isinstance(kwargs.get("activation_fn"), str):
        kwargs["activation_fn"] = getattr(torch.nn, kwargs["activation_fn"])
    if kwargs:
        out["policy_kwargs"] = kwargs
    return out


def policy_kwargs(value: Any) -> dict[str, Any]:
    """The file's ``policy_kwargs`` as a dict: the Zoo writes an expression over dict and nn."""
    import torch.nn

    if isinstance(value, str):
        value = eval(value, {"__builtins__": {}, "dict": dict, "nn": torch.nn})
    return dict(value or {})


class linear_schedule:  # noqa: N801  (a picklable function of progress_remaining)
    """``x · progress_remaining``: from ``x`` at the start to 0 at the end of training."""

    def __init__(self, initial: float):
        self.initial = initial

    def __call__(self, progress_remaining: float) -> float:
        return self.initial * progress_remaining

    def __repr__(self) -> str:
        return f"lin_{self.initial:g}"
