"""numba's disk cache, keyed by every source file of the simulator.

numba stamps a cached function with its own file only. A cached caller keeps the machine code
of the callees it inlined from other files (``contact_solve.solve`` calls
``contact_starts.active_set_start``) and of the module constants it read
(``contacts.settings.NEWTON_STEPS``) as they were when it compiled; after an edit, or an upgrade
in place, the package would run stale code without a word. The locator here adds the hash of
every ``rigid_env/sim`` source to the stamp of each function this package compiles (its kernels
and steps), so any edit recompiles everything once. Paths and file names are
numba's own (``__pycache__``, or ``NUMBA_CACHE_DIR``); only the stamp differs.

numba ≥ 0.59 picks a function's locator from ``CacheImpl._locator_classes`` (or from
``NUMBA_CACHE_LOCATOR_CLASSES`` when a user sets it, which then takes over). ``install`` puts
this locator first (the package's kernels decorate with this module's ``njit``, which installs
it); it declines every function that is not this package's, so other numba code keeps numba's
locators.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_SIM = Path(__file__).resolve().parents[1]
_OWN_MODULES = ("rigid_env.",)
_HASH: str | None = None
_INSTALLED: bool | None = None


def sources_hash(root: Path = _SIM) -> str:
    """Hash of every ``.py`` under ``root`` (the simulator) and of where it lives (none under
    ``__pycache__``, where the caches live)."""
    global _HASH
    if root == _SIM and _HASH is not None:
        return _HASH
    h = hashlib.sha256(str(root).encode())
    for path in sorted(root.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    digest = h.hexdigest()[:16]
    if root == _SIM:
        _HASH = digest
    return digest


def njit(*args, **kwargs):
    """numba's ``njit``, after ``install``: every kernel module decorates with it, so the
    locator is in place before the first cached function, and numba is imported by the modules
    that compile, not by ``import rigid_env.sim``."""
    install()
    from numba import njit as numba_njit

    return numba_njit(*args, **kwargs)


def install() -> bool:
    """Put ``PackageLocator`` first in numba's locators; False if numba's internals differ (the
    cache then works as numba's alone, with the stale-callee hazard the docstring describes)."""
    global _INSTALLED
    if _INSTALLED is None:
        _INSTALLED = _install()
    return _INSTALLED


def _install() -> bool:
    try:
        from numba.core import caching
    except ImportError:
        return False
    impl = getattr(caching, "CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if not isinstance(classes, list):
        return False
    if not any(getattr(c, "rigid_env_locator", False) for c in classes):
        classes.insert(0, _locator_class(caching))
    _lock_index_files(caching)
    return True


def _lock_index_files(caching) -> None:
    """Make numba's cache index and data files consistent across processes.

    ``IndexDataCacheFile.save`` reads the index, picks the first free data file number, writes
    the index, then the data file; ``load`` reads the index, then the data file it names. Each
    file is replaced atomically, but not the pair: two processes saving two overloads of one
    function at once can both pick ``.1.nbc`` (the index then names one key and the file holds
    the other's machine code), and a reader between a save's two writes can load a stale data
    file under a fresh index entry. Both run here under one lock per cache directory
    (``fcntl.flock``, held for the file operations only, milliseconds), so every process sees
    an index and data files that belong together. Without ``fcntl`` (Windows) nothing changes.
    """
    cls = getattr(caching, "IndexDataCacheFile", None)
    if cls is None or getattr(cls, "rigid_env_locked", False):
        return
    try:
        import fcntl
    except ImportError:
        return
    import functools
    import os

    def locked(method):
        @functools.wraps(method)
        def wrapper(self, *args, **kwargs):
            path = os.path.join(self._cache_path, "index.lock")
            try:
                handle = open(path, "a+b")  # noqa: SIM115 (held across the call)
            except OSError:  # a read-only cache directory: numba's own behaviour
                return method(self, *args, **kwargs)
            with handle:
                fcntl.flock(handle, fcntl.LOCK_EX)
                try:
                    return method(self, *args, **kwargs)
                finally:
                    fcntl.flock(handle, fcntl.LOCK_UN)

        return wrapper

    cls.save = locked(cls.save)
    cls.load = locked(cls.load)
    cls.rigid_env_locked = True


def _locator_class(caching):
    class PackageLocator(caching._CacheLocator):
        """numba's own locator for the function, with the sources hash added to its stamp."""

        rigid_env_locator = True

        def __init__(self, inner):
            self._inner = inner

        def ensure_cache_path(self):
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return (self._inner.get_source_stamp(), sources_hash())

        def get_disambiguator(self):
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func, py_file):
            if not getattr(py_func, "__module__", "").startswith(_OWN_MODULES):
                return None
            for base in caching.CacheImpl._locator_classes:
                if base is cls:
                    continue
                inner = base.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    return PackageLocator


__all__ = ["install", "njit", "sources_hash"]
