"""A driver's first call: one process compiles, the others wait and load; one line says so.

numba compiles a composition's step (``steps.free_step`` or ``contact_step``, specialised for
the scene's argument types) on its first call, after the kernels it calls by address
(``calls``; on two cores, ``compile_helper``), and caches the machine code on disk. Two hazards come with processes that start together on an empty cache
(async vector envs, ``SubprocVecEnv``, Ray trials):

- each compiles the same code, so four processes on two cores take four compiles' time;
- numba's cache is an index file (key → data file name) and numbered data files, each written
  atomically but not together (``numba.core.caching.IndexDataCacheFile.save``: read the index,
  pick the first free number, write the index, then the data). Two processes saving two
  overloads of one function at once can both pick ``.1.nbc``; the index then names one
  overload's key and the file holds the other's machine code, which a later process loads
  without a check and runs with the wrong signature.

So every first call of a driver runs under the lock of its composition (``fcntl.flock`` on
``<step>-<hash of the argument types>.lock`` in the cache directory, released by the kernel if
the holder dies): a composition compiles once, and a process that waited finds the code the
holder cached and loads it in about a second; other compositions compile meanwhile, in
parallel. The second hazard is
closed below the steps, for every function this package compiles: numba's index and data
files are read and written under one short lock per cache directory (``cache.py``). Only the
first call takes the driver's lock; later calls never touch it.

A compile of more than a second or so is announced before it starts, on the logger
``rigid_env.compile`` at WARNING level (Python's last-resort handler prints it to stderr when
logging is not configured; ``logging.getLogger("rigid_env.compile").setLevel(logging.ERROR)``
silences it), with how long the last compile of that kind took here (``compile_times.json`` in
the cache directory) or, the first time, the figure measured by the bench.

With ``NUMBA_DISABLE_JIT=1`` numba's decorators return the functions themselves, so the same
kernel source and the same steps run as plain Python (breakpoints and prints work
inside a kernel; ~1000× slower): no compile, no lock, no notice.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import time
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows: no lock (compiles may then overlap, as numba's own)
    fcntl = None  # type: ignore[assignment]

LOG = logging.getLogger("rigid_env.compile")
TIMES_NAME = "compile_times.json"
# First compiles with empty caches on 2 cores, from the bench's compile run (README, Limits):
# what a user is told before the first compile of a kind on a machine.
USUAL_SECONDS = {"contacts": 40.0, "free": 6.0}


def is_cached(dispatcher, args=None) -> bool:
    """Whether numba's disk cache holds a fresh entry for the dispatcher's function (its index
    loads with the current source stamp and names at least one overload; with ``args``, the
    overload for their types). False when numba's internals differ from what this expects: a
    notice too many, never a missing one."""
    try:
        index = dispatcher._cache._cache_file._load_index()
        if args is None:
            return bool(index)
        signature = tuple(dispatcher.typeof_pyval(a) for a in args)
        return any(key[0] == signature for key in index)
    except Exception:  # noqa: BLE001 (any internal difference: say it compiles)
        return False


def signature_name(dispatcher, args) -> str:
    """A file name for the dispatcher's overload for these arguments' types."""
    signature = str(tuple(dispatcher.typeof_pyval(a) for a in args))
    return f"{dispatcher.__name__}-{hashlib.sha256(signature.encode()).hexdigest()[:20]}"


@contextlib.contextmanager
def compile_lock(path: Path, what: str):
    """Hold the lock file ``path``; if another process holds it, say so and wait."""
    if fcntl is None:
        yield
        return
    with open(path, "a+b") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            LOG.warning(
                "rigid_env: waiting for another process that is compiling the same step "
                "(%s; lock %s); this process then loads what it cached",
                what,
                path,
            )
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def first_call(dispatcher, args, call, directory: Path, kind: str, what: str):
    """``call()`` (a driver's first call of the step ``dispatcher`` with ``args``) under the
    lock of that overload, announced if it is going to compile; the compile's duration is
    recorded for the next announcement of ``kind`` ("contacts" or "free"). With numba's JIT
    disabled (``NUMBA_DISABLE_JIT=1``, the debugging mode) the kernels run as plain Python:
    nothing compiles, so there is nothing to lock, announce or record."""
    from numba.core import config

    if config.DISABLE_JIT:
        return call()
    with compile_lock(directory / f"{signature_name(dispatcher, args)}.lock", what):
        if is_cached(dispatcher, args):
            return call()
        LOG.warning(
            "rigid_env: compiling the simulator's step for %s, once (%s); later processes "
            "load it from the cache in %s",
            what,
            _usual(directory, kind),
            directory,
        )
        start = time.perf_counter()
        result = call()
        _record(directory, kind, time.perf_counter() - start)
        return result


def _usual(directory: Path, kind: str) -> str:
    seconds = _times(directory).get(kind)
    if seconds is None:
        return f"about {USUAL_SECONDS[kind]:.0f} s with empty caches on 2 cores"
    return f"it took {seconds:.0f} s the last time here"


def _times(directory: Path) -> dict:
    try:
        data = json.loads((directory / TIMES_NAME).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _record(directory: Path, kind: str, seconds: float) -> None:
    """Write the duration (atomically: a reader never sees half a file); a failure to write it
    costs only the next notice's figure."""
    times = _times(directory)
    times[kind] = round(seconds, 1)
    tmp = directory / f"{TIMES_NAME}.{os.getpid()}.tmp"
    try:
        tmp.write_text(json.dumps(times))
        os.replace(tmp, directory / TIMES_NAME)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()


__all__ = ["LOG", "compile_lock", "first_call", "is_cached"]
