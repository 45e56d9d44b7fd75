"""The output folder of `swingbench run` and `swingbench sweep`: opened and checked before any
work (`open_results`), continued by `--resume`, and the line that says, on Ctrl-C, what was kept
and how to continue (`interrupted_message`)."""

from __future__ import annotations

import itertools
import json
import os
import shlex
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from harness.store import RowStore, StoreContents
from harness.usage import UsageError

__all__ = ["interrupted_message", "open_results"]


def open_results(out: Path, resume: bool, command: str, same: dict[str, Any] | None = None,
                 overwrite: bool = False) -> tuple[RowStore, StoreContents | None]:
    """The RowStore of the output folder `out`, checked before any work: a usable folder (made if
    missing), writable. A folder whose rows.jsonl holds rows is refused unless `resume` or
    `overwrite`: `overwrite` moves the earlier run aside (`_move_aside`), never deleting it; with
    `resume`, the run being continued must have recorded the values `same` in `out/metadata.json`
    (rows of other settings would mix), and what is not a whole unit (an interrupted unit's rows,
    a unit that lost a row) is set aside, saying so in one line (`RowStore.prepare_resume`).
    Problems exit with one line (`UsageError`)."""
    out = Path(out)
    if resume and same:
        _check_same_run(out / "metadata.json", same, command)
    try:  # inside a folder the user cannot enter, even exists() raises (PermissionError)
        if out.exists() and not out.is_dir():
            raise UsageError(f"swingbench {command}: --out {out} is a file, not a folder")
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise UsageError(f"swingbench {command}: cannot write to --out {out}: {exc.strerror or exc}") from None
    store = RowStore(out)
    if not resume:
        if store.path.exists() and store.path.stat().st_size > 0:
            if not overwrite:
                raise UsageError(f"swingbench {command}: --out {out} holds the rows of an earlier run ({store.path.name}): "
                                 "add --resume to continue it, or --overwrite to start again with its rows moved aside")
            print(f"[swingbench] --overwrite: the earlier run's {_move_aside(out)} in {out}", file=sys.stderr)
        elif store.partial_dir.exists():  # an earlier run that recorded no unit kept rows part-way: not this run's
            print(f"[swingbench] an earlier run that recorded no unit: its {_move_aside(out)} in {out} "
                  "(--resume would have recorded its rows kept part-way)", file=sys.stderr)
        return store, None
    try:
        contents = store.prepare_resume()
    except ValueError as exc:
        raise UsageError(f"swingbench {command}: {exc}") from None
    problems = contents.problems()
    if problems:
        print(f"[swingbench] {store.path}: set aside {problems} in {store.set_aside_path.name}; "
              "their units run again", file=sys.stderr)
    return store, contents


# What a run writes that describes it, and nothing rewrites from its rows: kept with the rows
# (partial/: the rows so far of units stopped part-way, `harness.store.write_partial`)
ASIDE = ("rows.jsonl", "metadata.json", "partial")


def _move_aside(out: Path) -> str:
    """Rename each file (or folder) of `ASIDE` in `out` to `<stem>.<UTC time>.<suffix>` beside it
    (the one time for all, e.g. rows.20260314T091500Z.jsonl; -2, -3 ... after the time when one of
    those names is taken); return what moved, in words ("rows.jsonl moved to rows.<time>.jsonl and
    ..."). `.gitignore` ignores the renamed files."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    present = [out / name for name in ASIDE if (out / name).exists()]
    for n in itertools.count(1):
        moved = [(p, p.with_name(f"{p.stem}.{stamp}{'' if n == 1 else f'-{n}'}{p.suffix}")) for p in present]
        if not any(new.exists() for _, new in moved):
            break
    for old, new in moved:
        os.rename(old, new)
    return " and ".join(f"{old.name} moved to {new.name}" for old, new in moved)


def _check_same_run(path: Path, same: dict[str, Any], command: str) -> None:
    """UsageError when the metadata at `path` records another value of a key of `same` (an
    unreadable or missing file, or a missing key, is no evidence either way)."""
    try:
        recorded = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if not isinstance(recorded, dict):
        return
    for key, value in same.items():
        if key in recorded and recorded[key] != json.loads(json.dumps(value, default=str)):
            raise UsageError(f"swingbench {command}: --resume continues the run in {path.parent}, made with "
                             f"{key} {recorded[key]!r}, not {value!r}: run it with the same options, or "
                             "without --resume")


def interrupted_message(store: RowStore, argv: list[str]) -> str:
    """The one line printed on Ctrl-C: what was kept (completed units, and the rows so far of units
    stopped part-way) and the command that continues."""
    kept = len(store.read().completed)
    argv = [arg for arg in argv if arg != "--overwrite"]  # what it moved aside is the earlier run, not this one
    again = shlex.join(["swingbench", *argv, *([] if "--resume" in argv else ["--resume"])])
    partial = len(list(store.partial_dir.glob("*.json"))) if store.partial_dir.is_dir() else 0
    part = (f" and the rows so far of {partial} unit(s) stopped part-way in {store.partial_dir}, which --resume "
            "records" if partial else "")
    return f"[swingbench] interrupted: {kept} completed unit(s) of work kept in {store.path}{part}; continue with: {again}"
