"""Whether a command's sizes fit in this machine's memory, checked before any work.

The figures are lower bounds (about half of what was measured), so a size refused here could not
have run; one accepted may still be tight. A refusal is a :class:`~rigid_env.cli.UsageError` that
gives the estimate and what the machine has, e.g. ``--n-envs 10000000 needs ~21 GiB, this
machine has 19.6 GiB available``.
"""

from __future__ import annotations

import math
import os
import resource
from pathlib import Path

from .cli import UsageError

GiB = 2**30
# Bytes per element of a vector env, at least: the resident memory a vector env of 16384 adds
# after a reset and 5 steps is 2.1 KB per env for Reorient and 4.4 KB for BoxLanding (compiled
# backend); half of that here.
ENV_BYTES = {"RigidEnv/Reorient-v0": 1024, "RigidEnv/BoxLanding-v0": 2048}
DEFAULT_ENV_BYTES = 1024  # another env id: its own layer and a small simulator state at least
SCENE_BYTES = 1024  # one batch element of a simulator scene with contacts (state, contact arrays)
# (observation, action) sizes of the envs, for the training buffers (float32 in SB3).
ENV_SPACES = {"RigidEnv/Reorient-v0": (10, 3), "RigidEnv/BoxLanding-v0": (25, 3)}


def available_memory() -> int:
    """Bytes this process may still use: the system's ``MemAvailable`` (else its physical
    memory), or less under an address-space or data limit (``ulimit -v``, ``ulimit -d``)."""
    available = None
    meminfo = Path("/proc/meminfo")
    if meminfo.is_file():
        for line in meminfo.read_text().splitlines():
            if line.startswith("MemAvailable:"):
                available = int(line.split()[1]) * 1024
    if available is None:
        try:
            available = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError):
            available = 2**63
    for limit in (resource.RLIMIT_AS, resource.RLIMIT_DATA):
        soft = resource.getrlimit(limit)[0]
        if soft != resource.RLIM_INFINITY:
            available = min(available, soft)
    return available


def size_text(n: float) -> str:
    """``"1.5 GiB"``, ``"12 MiB"``, ``"3 KiB"``."""
    for unit, scale in (("GiB", GiB), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.0f} B"


def check_fits(needed: float, what: str) -> None:
    """:class:`UsageError` when ``needed`` bytes exceed :func:`available_memory`."""
    if not math.isfinite(needed) or needed > (available := available_memory()):
        raise UsageError(
            f"{what} needs ~{size_text(needed)}, this machine has {size_text(available)} "
            "available; use a smaller size"
        )


def env_bytes(env_id: str, num_envs: int) -> float:
    """Bytes a vector env of ``num_envs`` copies of ``env_id`` needs at least."""
    return float(num_envs) * ENV_BYTES.get(env_id, DEFAULT_ENV_BYTES)


def check_envs(env_id: str, num_envs: int, option: str) -> None:
    """A vector env of ``num_envs`` must fit (``option`` names the size in the refusal)."""
    check_fits(env_bytes(env_id, num_envs), f"{option} {num_envs} ({env_id})")
