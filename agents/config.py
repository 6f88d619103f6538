"""Per-environment hyperparameters from ``agents/hyperparams/<env>.yml`` (RL Zoo style).

Each file has one block per algorithm. Training-loop keys (:data:`LOOP_KEYS`) are split off;
the rest are keyword arguments of the SB3 algorithm, with two conveniences from the Zoo:
``"lin_<x>"`` for a schedule decaying linearly from ``x`` to 0, and
``policy_kwargs.activation_fn`` given as the name of a ``torch.nn`` module.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

HYPERPARAMS_DIR = Path(__file__).with_name("hyperparams")
LOOP_KEYS = ("n_timesteps", "n_envs", "env_kwargs", "eval_freq", "eval_episodes")
ALGOS = ("ppo", "sac")


def config_path(env_id: str) -> Path:
    """``RigidEnv/BoxLanding-v0`` → ``hyperparams/box_landing.yml``."""
    name = env_id.split("/")[-1].split("-v")[0]
    snake = re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower()
    return HYPERPARAMS_DIR / f"{snake}.yml"


def load(env_id: str, algo: str) -> tuple[dict, dict]:
    """(loop settings, algorithm kwargs) for ``env_id`` and ``algo``, schedules resolved."""
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    path = config_path(env_id)
    if not path.exists():
        raise ValueError(f"env_id: no hyperparameter file {path} for {env_id!r}")
    blocks = yaml.safe_load(path.read_text())
    if algo not in blocks:
        raise ValueError(f"algo: {path.name} has no {algo!r} block")
    params = dict(blocks[algo])
    loop = {k: params.pop(k) for k in LOOP_KEYS if k in params}
    loop.setdefault("env_kwargs", {})
    return loop, resolve(params)


def resolve(params: dict) -> dict:
    """Turn the file's plain values into SB3 arguments (schedules, activation classes)."""
    import torch.nn

    out = dict(params)
    for key in ("learning_rate", "clip_range"):
        value = out.get(key)
        if isinstance(value, str) and value.startswith("lin_"):
            out[key] = linear_schedule(float(value[4:]))
    kwargs = dict(out.get("policy_kwargs") or {})
    if isinstance(kwargs.get("activation_fn"), str):
        kwargs["activation_fn"] = getattr(torch.nn, kwargs["activation_fn"])
    if kwargs:
        out["policy_kwargs"] = kwargs
    return out


class linear_schedule:  # noqa: N801  (a picklable function of progress_remaining)
    """``x · progress_remaining``: from ``x`` at the start to 0 at the end of training."""

    def __init__(self, initial: float):
        self.initial = initial

    def __call__(self, progress_remaining: float) -> float:
        return self.initial * progress_remaining

    def __repr__(self) -> str:
        return f"lin_{self.initial:g}"
