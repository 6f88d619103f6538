"""Atomic file writes: a reader (or a crash, or a second Ctrl-C) sees the old file or the new one,
never half of one.

The bytes go to a temporary file in the same folder (so the rename stays on one filesystem),
are flushed to disk, and then ``os.replace`` puts it in place, which POSIX makes atomic.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

TEMP_SUFFIX = ".partial"  # what an interrupted write leaves behind, at worst


class WriteError(OSError):
    """Writing ``filename`` failed for a reason of the file system (no space left, file too
    large, permission denied, read-only, a network file system gone): ``errno`` and
    ``strerror`` are the system's, ``filename`` the file that was being written."""


class _RecordingFile(io.FileIO):
    """A file that remembers the first ``OSError`` its writes raised, so that the cause is
    known even when the writing library turns it into an exception of its own."""

    error: OSError | None = None

    def write(self, data: Any, /) -> int:
        try:
            return super().write(data)
        except OSError as error:
            self.error = self.error or error
            raise


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "wb") -> Iterator[Any]:
    """``with atomic_open(path) as f: ...`` writes ``path`` all at once when the block succeeds;
    when it fails, ``path`` is untouched and the temporary file removed.

    A failure of the file system (creating, writing, syncing or renaming the file) is raised as
    :class:`WriteError` naming ``path``, whatever the writing code made of it; other errors of
    the block pass through unchanged."""
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    try:
        fd, temp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMP_SUFFIX)
    except OSError as error:
        raise _write_error(error, path) from None
    raw = _RecordingFile(fd, "w")
    own = True  # whether an OSError raised below is about this file
    try:
        binary = io.BufferedWriter(raw)
        f: IO = io.TextIOWrapper(binary, encoding="utf-8") if mode == "w" else binary
        with f:
            try:
                yield f
            except OSError as error:
                if error.filename is not None and raw.error is None:
                    own = False  # about another file than this one
                    raise
                raise _write_error(error, path) from None
            except Exception as error:
                if raw.error is None:
                    raise
                raise _write_error(raw.error, path) from error  # the writer's own exception
            try:
                f.flush()
                os.fsync(f.fileno())
            except OSError as error:
                raise _write_error(error, path) from None
        os.chmod(temp, 0o644)  # mkstemp makes it owner-only; a normal file is readable by all
        os.replace(temp, path)
    except BaseException as error:
        with contextlib.suppress(OSError):  # a folder gone read-only may refuse this too
            os.unlink(temp)
        if own and isinstance(error, OSError) and not isinstance(error, WriteError):
            raise _write_error(error, path) from None  # closing, chmod or the rename
        raise


def _write_error(error: OSError, path: Path) -> WriteError:
    return WriteError(error.errno, error.strerror or str(error), str(path))


def write_text(path: str | Path, text: str) -> Path:
    with atomic_open(path, "w") as f:
        f.write(text)
    return Path(path)


def write_json(path: str | Path, obj: Any, **dumps_kwargs: Any) -> Path:
    return write_text(path, json.dumps(obj, **dumps_kwargs) + "\n")


def remove_partials(folder: str | Path) -> list[Path]:
    """Delete the temporary files interrupted writes left in ``folder``; returns them."""
    stale = sorted(Path(folder).glob(f".*{TEMP_SUFFIX}"))
    for path in stale:
        path.unlink()
    return stale
