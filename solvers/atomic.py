"""Whole-file writes: a temporary file beside the target, synced, then renamed over it, so a reader
(or a crash) sees the old file or the whole new one, never half of one. The file gets the mode
`open()` would give a new file, 0o666 less the process's umask (`mkstemp` makes 0o600). Imports
nothing of ours: the solvers' model files and the harness's tables use it alike (so it sits in
solvers/, the lower of the two layers)."""

from __future__ import annotations

import os
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_write", "write_atomically"]

_UMASK_LOCK = threading.Lock()


def _umask() -> int:
    """The process's umask, left as it is: read from /proc/self/status on Linux; elsewhere set to
    0o077 and back under a lock (a file another thread creates in that instant is at most 0o600)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with _UMASK_LOCK:
        old = os.umask(0o077)
        os.umask(old)
    return old


def _new_file_mode() -> int:
    """The permission bits of a newly created file: 0o666 less the umask (0o644 under umask 022)."""
    return 0o666 & ~_umask()


def write_atomically(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """`write(binary file)` into a temporary file beside `path` (its folder made if missing), then
    rename it to `path`, whose mode is then `_new_file_mode()`. On any error the temporary file is
    removed and `path` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), _new_file_mode())
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
