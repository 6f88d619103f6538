"""rigid_env: a batched rigid-body simulator in numpy, with Gymnasium environments."""

from .envs import register_envs as _register_envs

__version__ = "0.1.0"

_register_envs()  # at import time, so SubprocVecEnv workers find the RigidEnv namespace
