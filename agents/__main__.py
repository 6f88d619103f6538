"""``python -m agents``: the main job (see :mod:`agents.main_job`)."""

import sys

from rigid_env import cli

from .main_job import PROG, main

sys.exit(cli.run(main, PROG))
