"""numba's disk cache notices an edit of any simulator file (``compiled/cache.py``): without it,
a cached kernel keeps the code of the callees and constants it took from other files."""

import importlib
import shutil
import sys
from pathlib import Path

import pytest
from numba.core.dispatcher import Dispatcher

from rigid_env.sim.compiled import backend, cache

pytestmark = pytest.mark.skipif(not backend.numba_available(), reason="numba is not installed")
SIM = Path(cache.__file__).resolve().parents[1]


def kernels():
    for name in backend.KERNEL_MODULES:
        module = importlib.import_module(f"rigid_env.sim.compiled.{name}")
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value.__module__ == module.__name__:
                yield value


def test_every_cached_kernel_is_stamped_with_the_simulator_sources():
    found = list(kernels())
    assert len(found) > 20  # every kernel module was visited
    for kernel in found:
        stamp = kernel._cache._impl._locator.get_source_stamp()
        assert stamp[1] == cache.sources_hash(), kernel


def test_the_stamp_changes_with_any_simulator_source(tmp_path):
    copy = tmp_path / "sim"
    shutil.copytree(SIM, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = cache.sources_hash(copy)
    assert cache.sources_hash(copy) == before
    # A constant a kernel reads from another package (the disk step's Newton iterations).
    solve = copy / "contacts" / "solve.py"
    solve.write_text(solve.read_text() + "\nNEWTON_STEPS = 9\n")
    assert cache.sources_hash(copy) != before


def test_functions_outside_the_package_keep_numbas_locator(tmp_path, monkeypatch):
    (tmp_path / "outside_kernel.py").write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("outside_kernel")
    try:
        locator = module.f._cache._impl._locator
        assert not getattr(locator, "rigid_env_locator", False)
        assert module.f(1) == 2
    finally:
        sys.modules.pop("outside_kernel", None)
