"""rigid_env: a batched rigid-body simulator in numpy, with Gymnasium environments."""

__version__ = "0.1.0"
