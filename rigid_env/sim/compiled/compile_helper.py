"""A cold first step compiles on two cores: a helper process compiles some of the step's kernels
into the shared cache while this process compiles the others.

numba compiles under one lock per process, so a process compiles on one core. The kernels a step
calls by address (``calls``) are independent compiles, each cached on disk for its signature.
On a first step that finds some of them uncached, this process starts a helper (a fresh
interpreter running this module) and both go through the kernels in one order, largest first
(``compile_size``), each taking the next kernel that neither holds (a lock file per kernel in
the compile cache directory, ``driver.cache_dir``) and compiling it or loading it from the cache. A kernel the other
process holds is skipped, and taken at the end, when its lock frees: by then it is cached and
loads in milliseconds.

The helper only saves time: a kernel it did not cache (it failed, was killed, could not start)
this process compiles itself, as it would without it. ``RIGID_ENV_COMPILE_HELPER=0`` turns it
off; so does a machine with one core.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import subprocess
import sys
from pathlib import Path

from .calls import address
from .first_call import fcntl, is_cached

ENV = "RIGID_ENV_COMPILE_HELPER"
_ROOT = Path(__file__).resolve().parents[3]  # the directory that holds ``rigid_env``
LINGER_S = 60.0  # how long a finished step waits for its helper to exit before killing it


def compile_size(function) -> int:
    """Bytecode bytes of a kernel and of every compiled helper it reaches by name, each once: a
    proxy for its compile time (numba types and lowers each reached function)."""
    seen: set[int] = set()
    stack = [function]
    size = 0
    while stack:
        f = stack.pop()
        py = getattr(f, "py_func", None)
        if py is None or id(py) in seen:
            continue
        seen.add(id(py))
        code = py.__code__
        size += len(code.co_code)
        stack.extend(py.__globals__.get(name) for name in code.co_names)
    return size


@contextlib.contextmanager
def _holding(path: Path, wait: bool):
    """Yield whether this process holds the lock file ``path`` (``wait``: block until it does)."""
    if fcntl is None:
        yield True
        return
    with open(path, "a+b") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _functions(callees):
    return [getattr(importlib.import_module(module), name) for module, name, _ in callees]


def _visit(callees, directory: Path, out: list[int]) -> list[int]:
    """Compile or load, largest first, every kernel no other process holds; the indices of the
    ones skipped."""
    functions = _functions(callees)
    order = sorted(range(len(callees)), key=lambda i: -compile_size(functions[i]))
    skipped = []
    for i in order:
        module, name, data = callees[i]
        with _holding(directory / f"{module}.{name}.lock", wait=False) as held:
            if held:
                out[i] = address(functions[i], data)
            else:
                skipped.append(i)
    return skipped


def _start_helper(callees) -> subprocess.Popen | None:
    if os.environ.get(ENV, "1") == "0" or (os.cpu_count() or 1) < 2 or not sys.executable:
        return None
    try:
        payload = pickle.dumps(list(callees))
        proc = subprocess.Popen(
            [sys.executable, "-m", __name__],
            # where this process found the package (``-m`` puts the working directory first
            # on the path, which may hold another checkout)
            cwd=_ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except (OSError, TypeError, pickle.PicklingError):
        return None
    try:
        assert proc.stdin is not None
        proc.stdin.write(payload)
        proc.stdin.close()
    except OSError:  # it died before reading: this process compiles everything itself
        proc.kill()
        proc.wait()
        return None
    return proc


def addresses(callees, directory: Path) -> list[int]:
    """The address of each kernel ``(module, name, data)`` (``calls.address``), compiled or
    loaded; with a helper process when two or more are not cached yet."""
    from numba.core import config

    functions = _functions(callees)
    if config.DISABLE_JIT:  # the kernels run as Python: nothing to compile
        return [address(f, data) for f, (_, _, data) in zip(functions, callees, strict=True)]
    cold = sum(not is_cached(f) for f in functions)
    helper = _start_helper(callees) if cold >= 2 else None
    out = [0] * len(callees)
    skipped = _visit(callees, directory, out)
    for i in skipped:  # held by the helper: cached once its lock frees
        module, name, data = callees[i]
        with _holding(directory / f"{module}.{name}.lock", wait=True):
            out[i] = address(functions[i], data)
    if helper is not None:
        # Every kernel is compiled: the helper has at most some cached ones left to load.
        try:
            helper.wait(timeout=LINGER_S)
        except subprocess.TimeoutExpired:
            helper.kill()
            helper.wait()
    return out


def main() -> None:
    from .driver import cache_dir

    callees = pickle.loads(sys.stdin.buffer.read())
    _visit(callees, cache_dir(), [0] * len(callees))


if __name__ == "__main__":
    main()
