"""Agent tests run headless and single-threaded (small MLPs; 2 shared cores)."""

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"
os.environ["SDL_AUDIODRIVER"] = "dummy"

import torch  # noqa: E402

torch.set_num_threads(1)
