"""Policies by name, all batched ``(N, obs_dim) -> (N, act_dim)``: random, zero, analytic, or a
saved SB3 model (``.zip``; PPO or SAC, told apart by the policy class stored in the zip)."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .controllers import for_env
from .rollout import Policy

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

BUILTIN = ("random", "zero", "analytic")


def algo_of(path: str | Path) -> str:
    """``"ppo"`` or ``"sac"``, from the policy class SB3 stores in the zip's ``data`` entry."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    module = data["policy_class"]["__module__"]  # e.g. "stable_baselines3.sac.policies"
    for algo in ("ppo", "sac"):
        if f".{algo}." in module or module.endswith(f".{algo}"):
            return algo
    if ".common." in module:  # ActorCriticPolicy lives in common: PPO (A2C is not offered here)
        return "ppo"
    raise ValueError(f"policy: cannot tell the algorithm of {path} (policy class in {module})")


def load_model(path: str | Path) -> BaseAlgorithm:
    """The SB3 model saved at ``path`` (on CPU)."""
    from stable_baselines3 import PPO, SAC

    cls: type[BaseAlgorithm] = PPO if algo_of(path) == "ppo" else SAC
    return cls.load(str(path), device="cpu")


def run_info(path: str | Path) -> dict[str, Any]:
    """The ``run.json`` written by ``agents.train`` next to a model, if there is one."""
    sidecar = Path(path).with_name("run.json")
    return json.loads(sidecar.read_text()) if sidecar.exists() else {}


def make_policy(spec: str, env_id: str, env: Any, seed: int = 0) -> Policy:
    """Policy ``spec`` (random, zero, analytic or a .zip path) for ``env`` (single or vector)."""
    space = getattr(env, "single_action_space", env.action_space)
    if spec == "zero":
        return lambda obs: np.zeros((len(obs), *space.shape), dtype=space.dtype)
    if spec == "random":
        rng = np.random.default_rng(seed)
        return lambda obs: rng.uniform(space.low, space.high, (len(obs), *space.shape)).astype(
            space.dtype
        )
    if spec == "analytic":
        return for_env(env_id, env)
    path = Path(spec)
    if path.suffix != ".zip" or not path.exists():
        raise ValueError(f"policy must be one of {BUILTIN} or an existing .zip, got {spec!r}")
    model = load_model(path)
    return lambda obs: model.predict(obs, deterministic=True)[0]
