"""Measurements of the simulator from outside: accuracy, stability, speed (``python -m rigid_env.bench``)."""
