"""Whole-file writes: a temporary file beside the target, synced, then renamed over it, so a reader
(or a crash) sees the old file or the whole new one, never half of one. Imports nothing of ours:
the solvers' model files and the harness's tables use it alike (so it sits in solvers/, the
lower of the two layers)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_write", "write_atomically"]


def write_atomically(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """`write(binary file)` into a temporary file beside `path` (its folder made if missing), then
    rename it to `path`. On any error the temporary file is removed and `path` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def atomic_write(path: Path, text: str | bytes) -> None:
    """Write `text` (str as UTF-8) to `path` atomically (see `write_atomically`)."""
    write_atomically(path, lambda fh: fh.write(text.encode() if isinstance(text, str) else text))
