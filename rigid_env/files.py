"""Atomic file writes: a reader (or a crash, or a second Ctrl-C) sees the old file or the new one,
never half of one.

The bytes go to a temporary file in the same folder (so the rename stays on one filesystem),
are flushed to disk, and then ``os.replace`` puts it in place, which POSIX makes atomic.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

TEMP_SUFFIX = ".partial"  # what an interrupted write leaves behind, at worst


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "wb") -> Iterator[Any]:
    """``with atomic_open(path) as f: ...`` writes ``path`` all at once when the block succeeds;
    when it fails, ``path`` is untouched and the temporary file removed."""
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    fd, temp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMP_SUFFIX)
    try:
        f: IO = os.fdopen(fd, "w", encoding="utf-8") if mode == "w" else os.fdopen(fd, "wb")
        with f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(temp, 0o644)  # mkstemp makes it owner-only; a normal file is readable by all
        os.replace(temp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp)
        raise


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
