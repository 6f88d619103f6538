"""``python -m agents``: the main job (see :mod:`agents.main_job`)."""

from .main_job import main

main()
