"""Rows on disk: one JSON line per row, appended as produced, so an interrupted run loses nothing."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import pandas as pd

__all__ = ["RowStore", "atomic_write"]


def atomic_write(path: Path, text: str | bytes) -> None:
    """Write `text` to `path` through a temporary file and a rename: readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(text.encode() if isinstance(text, str) else text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


class RowStore:
    """Append-only rows in `<directory>/rows.jsonl`. Each `add` writes one whole line with a single
    write call, flushed and synced, so a crash leaves at most a torn last line, which `rows` skips."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.path = self.directory / "rows.jsonl"
        self.directory.mkdir(parents=True, exist_ok=True)

    def add(self, row: dict) -> None:
        line = json.dumps(row, default=_jsonable, allow_nan=True) + "\n"
        with open(self.path, "a", encoding="utf-8") as fh:
            fh.write(line)
            fh.flush()
            os.fsync(fh.fileno())

    def extend(self, rows: Iterable[dict]) -> None:
        for row in rows:
            self.add(row)

    def rows(self) -> list[dict]:
        if not self.path.exists():
            return []
        out = []
        for line in self.path.read_text(encoding="utf-8").splitlines():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:  # a torn last line of an interrupted run
                continue
        return out

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows())

    def clear(self) -> None:
        if self.path.exists():
            self.path.unlink()


def _jsonable(value):
    if hasattr(value, "item"):
        return value.item()
    if isinstance(value, (tuple, set)):
        return list(value)
    return str(value)
