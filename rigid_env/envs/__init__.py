"""Gymnasium environments on the simulator, and their registration.

``import rigid_env`` registers every id in :data:`ENV_SPECS` (so ``SubprocVecEnv`` workers and
``gymnasium.make("rigid_env:RigidEnv/...")`` find them); entry points are strings, so the
environment modules load only when an env is made.
"""

from __future__ import annotations

ENV_SPECS: dict[str, dict] = {
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
    """Register :data:`ENV_SPECS` with Gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    for env_id, spec in ENV_SPECS.items():
        if env_id not in registry:
            register(id=env_id, **spec)
