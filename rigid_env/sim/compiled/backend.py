"""Which backend a scene steps with, and the compiled driver for it.

``RIGID_ENV_BACKEND`` (or ``Scene(..., backend=)``) is ``"numpy"``, ``"compiled"`` or ``"auto"``
(the default): ``auto`` uses the compiled driver when numba imports and every stage of the scene
has a kernel, else numpy; ``compiled`` insists and raises ``ValueError`` when it cannot;
``numpy`` never compiles. Threads are opt-in: ``"compiled-threads"`` runs
the compiled step on one chunk of the batch per core (the same per-element arithmetic, so the
same bits); worth it only for large batches.

Compile cost. Each distinct stage tuple (integrator, force terms, contact stages) compiles once,
a few seconds, on its first step; numba caches the result on disk (the package's
``__pycache__``, or ``NUMBA_CACHE_DIR``; generated drivers in ``RIGID_ENV_CACHE_DIR`` if set),
so later processes load it in milliseconds. A CI run pays one compile per stage tuple its tests
use, once. The per-call cost is what the batch-1 speed targets measure: a few µs of Python
(validation, allocation of the fresh result) around one kernel call.
"""

from __future__ import annotations

import importlib

BACKENDS = ("auto", "numpy", "compiled", "compiled-threads")
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


def numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


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
    """The compiled driver the scene should use, or None for the numpy path (``backend`` is
    one of ``BACKENDS``, already validated by the scene)."""
    if backend == "numpy":
        return None
    if not numba_available():
        if backend == "auto":
            return None
        raise ValueError(f"backend {backend!r} needs numba, which is not installed")
    found = kernels_for(scene)
    if found is None:
        if backend == "auto":
            return None
        raise ValueError(
            f"backend {backend!r}: no compiled kernel for some stage of {scene.stages}; "
            "use backend='numpy' or 'auto'"
        )
    from .driver import Driver

    return Driver(*found, threads=backend == "compiled-threads", warm=scene.warm_start)
