"""The output folder of `swingbench run` and `swingbench sweep`: opened and checked before any
work (`open_results`), continued by `--resume`, and the line that says, on Ctrl-C, what was kept
and how to continue (`interrupted_message`)."""

from __future__ import annotations

import json
import shlex
import sys
import tempfile
from pathlib import Path
from typing import Any

from harness.store import RowStore, StoreContents
from harness.usage import UsageError

__all__ = ["interrupted_message", "open_results"]


def open_results(out: Path, resume: bool, command: str, same: dict[str, Any] | None = None,
                 ) -> tuple[RowStore, StoreContents | None]:
    """The RowStore of the output folder `out`, checked before any work: a usable folder (made if
    missing), writable. Without `resume` earlier rows are removed; with it, the run being continued
    must have recorded the values `same` in `out/metadata.json` (rows of other settings would mix),
    and an interrupted unit is set aside (`RowStore.prepare_resume`). Problems exit with one line
    (`UsageError`)."""
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
        store.clear()
        return store, None
    try:
        contents = store.prepare_resume()
    except ValueError as exc:
        raise UsageError(f"swingbench {command}: {exc}") from None
    if contents.incomplete_rows or contents.bad_lines:
        print(f"[swingbench] {store.path}: set aside what an interrupted run left unfinished in "
              f"{store.set_aside_path.name}; its units run again", file=sys.stderr)
    return store, contents


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
    """The one line printed on Ctrl-C: what was kept and the command that continues."""
    kept = len(store.read().completed)
    again = shlex.join(["swingbench", *argv, *([] if "--resume" in argv else ["--resume"])])
    return f"[swingbench] interrupted: {kept} completed unit(s) of work kept in {store.path}; continue with: {again}"
