"""Gymnasium environments on the simulator, and their registration.

``import rigid_env`` registers every id in :data:`ENV_SPECS` without importing Gymnasium
itself (so ``import rigid_env.sim`` stays free of it): if Gymnasium is already loaded the ids
are registered at once, otherwise as soon as Gymnasium finishes loading. ``SubprocVecEnv``
workers, ``gymnasium.make("RigidEnv/...")`` after ``import rigid_env``, and
``gymnasium.make("rigid_env:RigidEnv/...")`` all find them. Entry points are strings, so the
environment modules load only when an env is made.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any

from .observations import observation_slices, split_observation

__all__ = ["ENV_SPECS", "observation_slices", "register_envs", "split_observation"]

ENV_SPECS: dict[str, dict[str, Any]] = {
    "RigidEnv/Reorient-v0": dict(
        entry_point="rigid_env.envs.reorient:ReorientEnv",
        vector_entry_point="rigid_env.envs.reorient:ReorientVectorEnv",
        max_episode_steps=200,  # = rigid_env.envs.reorient.MAX_EPISODE_STEPS (checked by a test)
    ),
    "RigidEnv/BoxLanding-v0": dict(
        entry_point="rigid_env.envs.box_landing:BoxLandingEnv",
        vector_entry_point="rigid_env.envs.box_landing:BoxLandingVectorEnv",
        max_episode_steps=120,  # = rigid_env.envs.box_landing.MAX_EPISODE_STEPS (checked by a test)
    ),
}


def register_envs() -> None:
    """Register :data:`ENV_SPECS` with Gymnasium now (imports it; idempotent)."""
    from gymnasium.envs.registration import register, registry

    for env_id, spec in ENV_SPECS.items():
        if env_id not in registry:
            register(id=env_id, **spec)


class _RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """A one-shot import hook: lets Gymnasium load as usual, then registers the envs."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        load = spec.loader.exec_module

        def exec_module(module: ModuleType) -> None:
            load(module)
            register_envs()

        spec.loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def register_when_gymnasium_loads() -> None:
    """Register now if Gymnasium is loaded, else right after it loads (never imports it)."""
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _RegisterAfterGymnasium) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterGymnasium())
