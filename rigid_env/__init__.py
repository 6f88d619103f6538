"""rigid_env: a batched rigid-body simulator in numpy, with Gymnasium environments.

``rigid_env.sim`` (the physics) imports without Gymnasium; importing the package registers the
``RigidEnv/*`` ids with Gymnasium as soon as Gymnasium is loaded (see :mod:`rigid_env.envs`).
"""

from .envs import register_when_gymnasium_loads as _register

__version__ = "0.1.0"

_register()
