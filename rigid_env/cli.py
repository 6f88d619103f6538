"""Command-line plumbing shared by ``agents`` and ``rigid_env.bench``.

A mistake by the user (a bad argument, an unusable output path, a file that is not what it should
be) raises :class:`UsageError`; :func:`run` turns it into one line on stderr and exit status 2,
before any work is done. A fault of the file system met while working (no space left, a file
too large, permission denied, a read-only folder, a network file system gone: see
:func:`is_fault`) is one line naming the path and the cause, exit status 74. Anything else is a
bug in the package and keeps its traceback.
"""

from __future__ import annotations

import argparse
import errno
import gc
import math
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import NoReturn

EXIT_USAGE = 2  # as argparse
EXIT_FAULT = 74  # EX_IOERR of sysexits.h: an input/output error of the file system
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention
EXIT_STATUSES = (
    "exit status: 0 done, 2 a mistake in the arguments (nothing done), 74 a file-system fault "
    "(no space, file too large, permission, read-only, network; files written before are kept), "
    "130 interrupted"
)
# The causes of an OSError that are the file system's, not the package's: storage full or
# limited, access refused, the device or network file system failing or gone.
FAULT_ERRNOS = frozenset(
    getattr(errno, name)
    for name in (
        "ENOSPC", "EDQUOT", "EFBIG", "EACCES", "EPERM", "EROFS", "EIO", "ESTALE", "ENOTCONN",
        "EHOSTDOWN", "EHOSTUNREACH", "ENETDOWN", "ENETUNREACH", "ETIMEDOUT", "ENOLCK",
        "EREMOTEIO", "ENOMEDIUM", "ENXIO", "ENODEV", "EMFILE", "ENFILE",
    )
    if hasattr(errno, name)
)  # fmt: skip


class UsageError(ValueError):
    """What the user asked for cannot be done; the message says what is wrong and what is
    expected. A ``ValueError``, so library callers can treat it like any bad argument."""


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are :class:`UsageError` (one line, no usage block)."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{message} (see {self.prog} --help)")


def run(
    main: Callable[[Sequence[str] | None], int | None], prog: str, argv: Sequence[str] | None = None
) -> int:
    """Call ``main(argv)``; return its exit status, 2 after a :class:`UsageError` and 130 after
    Ctrl-C or SIGTERM (raised as ``KeyboardInterrupt``, so ``finally`` blocks and atomic writes
    clean up), each reported in one line on stderr."""
    main_thread = threading.current_thread() is threading.main_thread()  # signals live there
    previous = signal.signal(signal.SIGTERM, _raise_interrupt) if main_thread else None
    hook = sys.unraisablehook
    try:
        try:
            return main(argv) or 0
        except UsageError as error:
            print(f"{prog}: error: {error}", file=sys.stderr, flush=True)
            return EXIT_USAGE
        except OSError as error:
            if not is_fault(error):
                raise
            print(f"{prog}: error: {fault_message(error)}", file=sys.stderr, flush=True)
            return EXIT_FAULT
        except KeyboardInterrupt:
            _quiet_finalizers()
        gc.collect()  # the traceback is gone: what the interrupt left half-built goes now
        print(f"{prog}: interrupted", file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED
    finally:
        sys.unraisablehook = hook
        if main_thread:
            signal.signal(signal.SIGTERM, previous)


def _raise_interrupt(signum: int, frame: FrameType | None) -> NoReturn:
    _quiet_finalizers()
    raise KeyboardInterrupt


def _quiet_finalizers() -> None:
    """After an interrupt, an object it left half-built (an LLVM module numba was compiling when
    it came) may fail in its ``__del__`` as the stack unwinds, which Python prints as "Exception
    ignored ..." with a traceback. That is no error of the command, and the one line ``run``
    prints is its report: until ``run`` returns (after collecting such objects), finalizer
    errors are not printed."""
    sys.unraisablehook = lambda unraisable: None


def is_fault(error: BaseException) -> bool:
    """Whether ``error`` is a fault of the file system (:data:`FAULT_ERRNOS`, or a failed write
    of :func:`rigid_env.files.atomic_open`, e.g. into a folder that vanished)."""
    from .files import WriteError

    return isinstance(error, OSError) and (
        isinstance(error, WriteError) or error.errno in FAULT_ERRNOS
    )


def fault_message(error: OSError) -> str:
    """``"runs/r1/checkpoint.zip: No space left on device (ENOSPC); files written before are
    kept"``: the path, the system's words for the cause and its errno name."""
    code = errno.errorcode.get(error.errno or 0, "")
    cause = (error.strerror or str(error)) + (f" ({code})" if code else "")
    path = error.filename
    if error.filename2 is not None:  # a rename: the file it was to become
        path = error.filename2
    where = f"{path}: " if path is not None else ""
    return f"{where}{cause}; files written before are kept"


# --- argparse types: each failure names the value and what is expected ----------------------------


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def positive_int(text: str) -> int:
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def nonnegative_int(text: str) -> int:
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def env_id(text: str) -> str:
    """A registered Gymnasium id (the ``RigidEnv`` ids are registered by importing rigid_env)."""
    import gymnasium as gym

    import rigid_env  # noqa: F401  (registers the ids)

    if text not in gym.registry:
        ours = sorted(i for i in gym.registry if i.startswith("RigidEnv/"))
        raise argparse.ArgumentTypeError(f"unknown env id {text!r}; expected one of {ours}")
    return text


# --- output paths, checked before the work that fills them ----------------------------------------


def writable_dir(path: str | Path, name: str) -> Path:
    """Create directory ``path`` if needed and check that files can be written in it."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{name}: {path} is a file; expected a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as error:
        raise UsageError(
            f"{name}: cannot write in {path} ({error.strerror or error}); "
            "expected a writable directory"
        ) from None
    return path


def writable_file(path: str | Path, name: str, suffixes: tuple[str, ...] = ()) -> Path:
    """Check that file ``path`` (with one of ``suffixes``) can be written; creates its folder."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{name}: {path} is a directory; expected a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise UsageError(f"{name}: {path} should end in {' or '.join(suffixes)}")
    writable_dir(path.parent, name)
    if path.exists() and not os.access(path, os.W_OK):
        raise UsageError(f"{name}: {path} is not writable")
    return path
