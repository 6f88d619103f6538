"""Agents for the rigid_env environments: analytic controllers, SB3 baselines, evaluation.

``python -m agents`` runs the main job (train the default PPO baseline on Reorient-v0, then on
BoxLanding-v0; compare each with random and analytic policies; write a learning curve and a clip
per env). ``agents.train`` and
``agents.evaluate`` are the command-line tools behind it.
"""
