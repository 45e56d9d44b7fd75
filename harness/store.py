"""Rows on disk: `<dir>/rows.jsonl`, one JSON object per line, written a unit of work at a time.

A unit of work (one suite of one solver specification on one case, or its fit) is recorded by one
write of its rows followed by a completion record, `{"_complete": {<unit key>}, "rows": n}`, flushed
and synced. The resume rule follows: a unit is done when its completion record is on disk and the
lines since the record before it hold its n rows. A crash leaves at most a torn tail after the last
completion record; a damaged disk or an edit can spoil a row anywhere. Either way `--resume` sets
the lines aside in `rows.jsonl.set-aside` (never deleted) and measures their units again.

A long unit of work may also keep its rows so far in `<dir>/partial/` (a suite marked
`checkpoints`: the verdict suite after each round but the last), one whole file per unit (`write_partial`),
so that a unit stopped part-way (a limit, a failure, a killed process) keeps what it measured
(`read_partial`; `harness.run.runner` records it).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from solvers.atomic import atomic_write

__all__ = ["UNIT_COLUMNS", "RowStore", "StoreContents", "partial_path", "read_partial", "unit_key", "write_partial"]

# The columns that name a unit of work; every row carries them.
UNIT_COLUMNS = ("suite", "case", "solver", "config", "variant", "seed")
_COMPLETE = "_complete"


def unit_key(row: dict) -> tuple:
    """The unit a row (or a completion record's key) belongs to."""
    return tuple(row.get(column) for column in UNIT_COLUMNS)


def partial_path(directory: Path, key: dict) -> Path:
    """The file in `directory` where the unit of work named by `key` (`UNIT_COLUMNS`) keeps its rows
    so far: `<suite>-<16 hex digits of the key's digest>.json`."""
    text = json.dumps(list(_named(key).values()), default=_jsonable)
    return Path(directory) / f"{key['suite']}-{hashlib.sha256(text.encode('utf-8')).hexdigest()[:16]}.json"


def write_partial(path: Path, key: dict, rows: list[dict], progress: str) -> None:
    """Replace the file `path` whole (`atomic_write`) with the rows so far of the unit of work `key`
    and how far it got (`progress`, words: "1 of 2 rounds")."""
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {"key": _named(key), "progress": progress, "rows": rows}
    atomic_write(path, json.dumps(record, default=_jsonable, allow_nan=True).encode("utf-8"))


def read_partial(path: Path, key: dict) -> tuple[list[dict], str] | None:
    """(rows, progress) that `write_partial` kept at `path` for the unit of work `key`; None when
    there is no such file, or it is unreadable or another unit's (then it stays where it is)."""
    try:
        record = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return None
    if (not isinstance(record, dict) or not isinstance(record.get("rows"), list)
            or record.get("key") != _named(key)
            or not all(isinstance(row, dict) for row in record["rows"])):
        return None
    return record["rows"], str(record.get("progress", ""))


def _named(key: dict) -> dict:
    """The columns of `key` that name a unit of work, as JSON gives them back."""
    return json.loads(json.dumps({column: key.get(column) for column in UNIT_COLUMNS}, default=_jsonable))


class StoreContents(NamedTuple):
    """What `rows.jsonl` holds: the rows of completed units in file order, the keys of those units,
    the number of lines that are not JSON objects (skipped), the number of rows after the last
    completion record (an interrupted unit: not returned), whether the file predates completion
    records (then every row counts, each unit as complete), and the number of damaged units: those
    whose completion record counts other than the rows since the record before it (a row spoilt or
    lost; their rows are not returned, their units not complete)."""

    rows: list[dict]
    completed: set[tuple]
    bad_lines: int
    incomplete_rows: int
    legacy: bool
    damaged_units: int = 0

    def problems(self) -> str | None:
        """What the file holds that is not a whole unit, in words, or None when it holds nothing else."""
        parts = [f"{self.bad_lines} line(s) that are not JSON rows"] if self.bad_lines else []
        if self.damaged_units:
            parts.append(f"the rows of {self.damaged_units} unit(s) that lost a row")
        if self.incomplete_rows:
            parts.append(f"{self.incomplete_rows} row(s) of an unfinished unit")
        return " and ".join(parts) or None

    def warning(self, path: Path) -> str | None:
        """One line on what was skipped, or None when nothing was."""
        problems = self.problems()
        return f"{path}: skipped {problems}" if problems else None


class _Segment(NamedTuple):
    """The non-blank lines of `rows.jsonl` after one completion record up to and including the
    next (`record`: that record; None for the lines after the last one): those that are rows, and
    the indices in `lines` of those that are neither rows nor a completion record."""

    lines: list[bytes]
    rows: list[dict]
    bad: list[int]
    record: dict | None

    @property
    def whole(self) -> bool:
        """A completion record whose row count (when it gives one) is that of the rows before it."""
        count = self.record.get("rows") if self.record is not None else None
        return self.record is not None and (not isinstance(count, int) or count == len(self.rows))


def _segments(data: bytes) -> tuple[list[_Segment], bool]:
    """`data` cut after each completion record, and whether any line is meant as a completion
    record (a file that has none predates them)."""
    segments: list[_Segment] = []
    current = _Segment([], [], [], None)
    markers = False
    for line in data.split(b"\n"):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except ValueError:  # JSONDecodeError and UnicodeDecodeError
            item = None
        if isinstance(item, dict) and _COMPLETE in item:
            markers = True
        if isinstance(item, dict) and isinstance(item.get(_COMPLETE), dict):
            current.lines.append(line)
            segments.append(current._replace(record=item))
            current = _Segment([], [], [], None)
            continue
        if isinstance(item, dict) and _COMPLETE not in item:
            current.rows.append(item)
        else:  # not JSON, not an object, or a completion record without a key
            current.bad.append(len(current.lines))
        current.lines.append(line)
    if current.lines:
        segments.append(current)
    return segments, markers


class RowStore:
    """The rows of one results folder. `record(key, rows)` appends a unit; `read()` parses the file
    tolerantly; `prepare_resume()` sets aside whatever is not a whole unit.

    `create=False` (for readers such as `swingbench report`) never makes the folder."""

    def __init__(self, directory: Path, create: bool = True) -> None:
        self.directory = Path(directory)
        self.path = self.directory / "rows.jsonl"
        self.set_aside_path = self.directory / "rows.jsonl.set-aside"
        self.partial_dir = self.directory / "partial"
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
        segments, markers = _segments(self.path.read_bytes())
        bad = sum(len(segment.bad) for segment in segments)
        if not markers:  # written before completion records: every row stands
            rows = [row for segment in segments for row in segment.rows]
            return StoreContents(rows, {unit_key(r) for r in rows}, bad, 0, legacy=bool(rows))
        whole = [segment for segment in segments if segment.whole]
        tail = segments[-1] if segments and segments[-1].record is None else None
        return StoreContents([row for segment in whole for row in segment.rows],
                             {unit_key(segment.record[_COMPLETE]) for segment in whole}, bad,
                             len(tail.rows) if tail else 0, legacy=False,
                             damaged_units=sum(s.record is not None and not s.whole for s in segments))

    def rows(self) -> list[dict]:
        """The rows of completed units (see `read`)."""
        return self.read().rows

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows())

    def prepare_resume(self) -> StoreContents:
        """Keep in the file only the whole units (`StoreContents`) and append every other line (a
        torn line, the rows of an interrupted unit, the surviving lines of a unit that lost a row, a
        line that is not a row) to `rows.jsonl.set-aside`, synced before the file is replaced
        whole; return the contents as they were. Idempotent: on a file of whole units it changes
        nothing. Refuses a file written before completion records (ValueError): which of its units
        finished is unknown."""
        contents = self.read()
        if contents.legacy:
            raise ValueError(f"{self.path} was written by an older swingbench (no completion records): "
                             "which units finished is unknown; run again without --resume")
        if contents.problems() is None:
            return contents
        keep: list[bytes] = []
        aside: list[bytes] = []
        for segment in _segments(self.path.read_bytes())[0]:
            for i, line in enumerate(segment.lines):
                (keep if segment.whole and i not in segment.bad else aside).append(line)
        with open(self.set_aside_path, "ab") as fh:
            fh.write(b"\n".join(aside) + b"\n")
            fh.flush()
            os.fsync(fh.fileno())
        atomic_write(self.path, b"".join(line + b"\n" for line in keep))
        return contents


def _jsonable(value):
    if hasattr(value, "item"):
        return value.item()
    if isinstance(value, (tuple, set)):
        return list(value)
    return str(value)
