"""A run folder (or a sweep's, or a main job's) belongs to one live process.

The owner holds an exclusive ``flock`` on ``FOLDER/.owner.lock`` for as long as it works in the
folder, and writes who it is into that file (host, pid, start time, command). The operating
system releases the lock when the process ends, however it ends (a SIGKILL, a lost machine), so
the lock is held exactly while the owner lives: a second process is refused with a message that
names the owner, and a folder whose record says ``running`` but whose lock is free was left by a
process that died ("stopped unexpectedly"), which ``--resume`` may take over.

On a file system without locks (``flock`` failing with ENOLCK or EOPNOTSUPP) the owner recorded
in the lock file is taken to be alive while a process of that pid, started at the recorded time,
runs on this host, or while it is on another host (which cannot be asked).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shlex
import socket
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

from rigid_env.cli import UsageError

LOCK_FILE = ".owner.lock"
_NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}
_HELD: dict[str, Claim] = {}  # resolved folder -> this process's claim on it


@dataclass(frozen=True)
class Owner:
    host: str
    pid: int
    started: str  # local time, ISO 8601
    command: str
    boot_ticks: int | None = None  # the process's start in clock ticks since boot (Linux)

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host} (since {self.started}: {self.command})"

    def as_record(self) -> dict:
        return {"host": self.host, "pid": self.pid, "started": self.started}


def this_process() -> Owner:
    return Owner(
        host=socket.gethostname(),
        pid=os.getpid(),
        started=time.strftime("%Y-%m-%dT%H:%M:%S"),
        command=_command(),
        boot_ticks=_start_ticks(os.getpid()),
    )


def _command() -> str:
    """This process's command line as typed (``python -m agents.train --out runs/r1``)."""
    argv = list(getattr(sys, "orig_argv", None) or [sys.executable, *sys.argv])
    return shlex.join([Path(argv[0]).name, *argv[1:]])


def _start_ticks(pid: int) -> int | None:
    """Field 22 of ``/proc/<pid>/stat``: tells a pid's process from a later one reusing it."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat.rsplit(")", 1)[1].split()[19])


def _read_owner(path: Path) -> Owner | None:
    try:
        data = json.loads(path.read_text())
        return Owner(**data)
    except (OSError, ValueError, TypeError):
        return None


def _pid_alive(owner: Owner) -> bool:
    """Without locks: whether the recorded owner still runs (assumed so on another host)."""
    if owner.host != socket.gethostname():
        return True
    try:
        os.kill(owner.pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process of that pid
        pass
    ticks = _start_ticks(owner.pid)
    return owner.boot_ticks is None or ticks is None or ticks == owner.boot_ticks


class Claim:
    """This process's hold on a folder; :meth:`release` (or the process's end) gives it up."""

    def __init__(self, folder: Path, fd: int | None, owner: Owner):
        self.folder, self.fd, self.owner = folder, fd, owner

    def release(self) -> None:
        if _HELD.get(str(self.folder.resolve())) is self:
            del _HELD[str(self.folder.resolve())]
        with contextlib.suppress(OSError):  # unlinked first: no one locks a file on its way out
            (self.folder / LOCK_FILE).unlink()
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def claim(folder: str | Path, name: str) -> Claim:
    """Make this process the owner of ``folder`` (created if needed): :class:`UsageError`
    naming ``name`` and the owner when another live process holds it, or when the folder cannot
    be written."""
    folder = Path(folder)
    owner = this_process()
    for attempt in range(20):  # a lock file replaced under us, or a brief probe: try again
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            raise UsageError(
                f"{name}: cannot write in {folder} ({error.strerror or error}); "
                "expected a writable folder"
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            os.close(fd)
            if error.errno in _NO_LOCKS:
                return _claim_without_locks(folder, name, owner)
            if attempt < 2:  # another process's probe (owner_of) holds it for a moment
                time.sleep(0.05)
                continue
            raise UsageError(f"{name}: {folder} is in use by {_describe(folder)}") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(folder / LOCK_FILE).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the previous owner removed the file while we opened it
            os.close(fd)
            continue
        _write_owner(fd, owner)
        held = Claim(folder, fd, owner)
        _HELD[str(folder.resolve())] = held
        return held
    raise UsageError(f"{name}: {folder} is in use by {_describe(folder)}")


def _describe(folder: Path) -> str:
    owner = _read_owner(folder / LOCK_FILE)
    return owner.describe() if owner is not None else "another process (no owner recorded yet)"


def _write_owner(fd: int, owner: Owner) -> None:
    data = json.dumps(asdict(owner)).encode()
    os.ftruncate(fd, 0)
    os.pwrite(fd, data, 0)


def _claim_without_locks(folder: Path, name: str, owner: Owner) -> Claim:
    path = folder / LOCK_FILE
    recorded = _read_owner(path)
    if recorded is not None and recorded.pid != owner.pid and _pid_alive(recorded):
        raise UsageError(f"{name}: {folder} is in use by {recorded.describe()}")
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    _write_owner(fd, owner)
    os.close(fd)
    held = Claim(folder, None, owner)
    _HELD[str(folder.resolve())] = held
    return held


def owner_of(folder: str | Path) -> Owner | None:
    """The live process other than this one that owns ``folder``, or None."""
    folder = Path(folder)
    path = folder / LOCK_FILE
    if not path.is_file() or str(folder.resolve()) in _HELD:
        return None
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno in _NO_LOCKS:
            recorded = _read_owner(path)
            return recorded if recorded is not None and _pid_alive(recorded) else None
        return _read_owner(path) or Owner("?", 0, "?", "another process")
    finally:
        os.close(fd)  # releases the probe's shared lock
    return None


@contextlib.contextmanager
def owning(folder: str | Path, name: str) -> Iterator[Claim]:
    """``with owning(folder, "--out") as claim: ...``: :func:`claim`, released at the end."""
    held = claim(folder, name)
    try:
        yield held
    finally:
        held.release()
