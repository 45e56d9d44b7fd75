"""Rows on disk: `<dir>/rows.jsonl`, one JSON object per line, written a unit of work at a time.

A unit of work (one suite of one solver specification on one case, or its fit) is recorded by one
write of its rows followed by a completion record, `{"_complete": {<unit key>}, "rows": n}`, flushed
and synced. The resume rule follows: a unit is done when its completion record is on disk, however
many of its rows are. A crash leaves at most a torn tail after the last completion record; it is
detected, set aside in `rows.jsonl.set-aside` (never deleted) and its unit measured again.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from solvers.atomic import atomic_write

__all__ = ["UNIT_COLUMNS", "RowStore", "StoreContents", "atomic_write", "unit_key"]

# The columns that name a unit of work; every row carries them.
UNIT_COLUMNS = ("suite", "case", "solver", "config", "variant", "seed")
_COMPLETE = "_complete"


def unit_key(row: dict) -> tuple:
    """The unit a row (or a completion record's key) belongs to."""
    return tuple(row.get(column) for column in UNIT_COLUMNS)


class StoreContents(NamedTuple):
    """What `rows.jsonl` holds: the rows of completed units in file order, the keys of those units,
    the number of lines that are not JSON objects (skipped), the number of rows after the last
    completion record (an interrupted unit: not returned), and whether the file predates completion
    records (then every row counts, each unit as complete)."""

    rows: list[dict]
    completed: set[tuple]
    bad_lines: int
    incomplete_rows: int
    legacy: bool

    def warning(self, path: Path) -> str | None:
        """One line on what was skipped, or None when nothing was."""
        parts = [f"{self.bad_lines} line(s) that are not JSON rows"] if self.bad_lines else []
        if self.incomplete_rows:
            parts.append(f"{self.incomplete_rows} row(s) of an unfinished unit")
        return f"{path}: skipped {' and '.join(parts)}" if parts else None


class RowStore:
    """The rows of one results folder. `record(key, rows)` appends a unit; `read()` parses the file
    tolerantly; `prepare_resume()` sets aside what an interrupted run left unfinished.

    `create=False` (for readers such as `swingbench report`) never makes the folder."""

    def __init__(self, directory: Path, create: bool = True) -> None:
        self.directory = Path(directory)
        self.path = self.directory / "rows.jsonl"
        self.set_aside_path = self.directory / "rows.jsonl.set-aside"
        if create:
            self.directory.mkdir(parents=True, exist_ok=True)

    def record(self, key: dict, rows: Iterable[dict]) -> None:
        """Append the rows of one unit of work and its completion record in one write, synced."""
        rows = list(rows)
        key = {column: key[column] for column in UNIT_COLUMNS}
        lines = [json.dumps(row, default=_jsonable, allow_nan=True) for row in rows]
        lines.append(json.dumps({_COMPLETE: key, "rows": len(rows)}, default=_jsonable))
        data = ("\n".join(lines) + "\n").encode("utf-8")
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)  # less the umask, as open() does
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)

    def read(self) -> StoreContents:
        """Parse the file: undecodable or non-object lines are counted and skipped."""
        if not self.path.exists():
            return StoreContents([], set(), 0, 0, legacy=False)
        done, pending, completed = [], [], set()
        bad = 0
        markers = False
        for line in self.path.read_bytes().split(b"\n"):
            if not line.strip():
                continue
            try:
                item = json.loads(line)
            except ValueError:  # JSONDecodeError and UnicodeDecodeError
                bad += 1
                continue
            if not isinstance(item, dict):
                bad += 1
            elif _COMPLETE in item:
                markers = True
                if isinstance(item[_COMPLETE], dict):
                    completed.add(unit_key(item[_COMPLETE]))
                    done.extend(pending)
                else:
                    bad += 1
                pending = []
            else:
                pending.append(item)
        if not markers:  # written before completion records: every row stands
            return StoreContents(pending, {unit_key(r) for r in pending}, bad, 0, legacy=bool(pending))
        return StoreContents(done, completed, bad, len(pending), legacy=False)

    def rows(self) -> list[dict]:
        """The rows of completed units (see `read`)."""
        return self.read().rows

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows())

    def prepare_resume(self) -> StoreContents:
        """Cut the file back to its last completion record, appending whatever followed it (a torn
        line, the rows of an interrupted unit) to `rows.jsonl.set-aside`; return the contents.
        Idempotent: on a file that ends with a completion record it changes nothing. Refuses a file
        written before completion records (ValueError): which of its units finished is unknown."""
        contents = self.read()
        if contents.legacy:
            raise ValueError(f"{self.path} was written by an older swingbench (no completion records): "
                             "which units finished is unknown; run again without --resume")
        if not self.path.exists():
            return contents
        data = self.path.read_bytes()
        end = _end_of_last_record(data)
        if end < len(data):
            with open(self.set_aside_path, "ab") as fh:
                fh.write(data[end:] if data.endswith(b"\n") else data[end:] + b"\n")
                fh.flush()
                os.fsync(fh.fileno())
            with open(self.path, "r+b") as fh:
                fh.truncate(end)
                fh.flush()
                os.fsync(fh.fileno())
        return contents


def _end_of_last_record(data: bytes) -> int:
    """Byte offset just after the last whole completion-record line of `data` (0 if none)."""
    end = len(data) if data.endswith(b"\n") else data.rfind(b"\n") + 1
    while end > 0:
        start = data.rfind(b"\n", 0, end - 1) + 1
        line = data[start:end]
        try:
            item = json.loads(line)
        except ValueError:
            item = None
        if isinstance(item, dict) and isinstance(item.get(_COMPLETE), dict):
            return end
        end = start
    return 0


def _jsonable(value):
    if hasattr(value, "item"):
        return value.item()
    if isinstance(value, (tuple, set)):
        return list(value)
    return str(value)
