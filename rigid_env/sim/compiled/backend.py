"""The compiled driver of a scene.

The element kernels are the simulator's one implementation: every scene the ``Scene`` accepts
has a kernel for each of its stages. ``RIGID_ENV_BACKEND`` (or ``Scene(..., backend=)``) is
``"compiled"`` (the default) or ``"compiled-threads"``, which runs the compiled step on one
chunk of the batch per core (the same per-element arithmetic, so the same bits); worth it only
for large batches. ``NUMBA_DISABLE_JIT=1`` runs the same kernel source as plain Python, a
debugging mode (``tests/sim/test_disable_jit.py``).

Compile cost. Each distinct stage tuple (integrator, force terms, contact stages) compiles once,
a few seconds, on its first step; numba caches the result on disk (the package's
``__pycache__``, or ``NUMBA_CACHE_DIR``; the compile locks in ``RIGID_ENV_CACHE_DIR`` if set),
so later processes load it in milliseconds. A CI run pays one compile per stage tuple its tests
use, once. The per-call cost is what the batch-1 speed targets measure: a few µs of Python
(validation, allocation of the fresh result) around one kernel call.
"""

from __future__ import annotations

import importlib

BACKENDS = ("compiled", "compiled-threads")
# Modules whose import registers kernels (package-relative); a new kernel module goes here.
KERNEL_MODULES = (
    "forces",
    "integrators",
    "exact_kernels",
    "ground",
    "contact_assembly",
    "contact_pairs",
    "contact_impacts",
    "contact_solve",
    "contact_energy",
)


def kernels_for(scene):
    """The scene's kernels and force kernels in stage order, or None if one stage has none."""
    from . import registry

    for module in KERNEL_MODULES:
        importlib.import_module(f"{__package__}.{module}")
    kernels, forces = [], []
    for name in scene.stages:
        if name in registry.FORCES:
            found = registry.FORCES[name](scene)
            if found is None:
                return None
            forces.append(found)
        elif name in registry.STAGES:
            found = registry.STAGES[name](scene)
            if found is None:
                return None
            kernels.extend(found if isinstance(found, tuple) else (found,))
        else:
            return None
    return kernels, forces


def driver_for(scene, backend: str):
    """The compiled driver of the scene (``backend``: one of ``BACKENDS``, already validated
    by the scene)."""
    found = kernels_for(scene)
    if found is None:  # (a stage registered without a kernel: a bug, never a fallback)
        raise ValueError(
            f"backend {backend!r}: no compiled kernel for some stage of {scene.stages}"
        )
    from .driver import Driver

    return Driver(*found, threads=backend == "compiled-threads", warm=scene.warm_start)
