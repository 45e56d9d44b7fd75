"""What the harness writes besides rows: whole files, with the mode the umask gives new files."""

from __future__ import annotations

import os
import stat

import pytest

from harness.store import RowStore
from solvers.atomic import atomic_write

KEY = {"suite": "s", "case": "c", "solver": "x", "config": "default", "variant": "", "seed": -1}


@pytest.fixture
def umask():
    """Set the process's umask for one test, then put back the one it had."""
    old = os.umask(0o022)
    try:
        yield os.umask
    finally:
        os.umask(old)


@pytest.mark.parametrize("mask,mode", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_written_files_get_the_mode_the_umask_gives_new_files(tmp_path, umask, mask, mode):
    umask(mask)
    atomic_write(tmp_path / "table.md", "a table")
    atomic_write(tmp_path / "table.md", "the table again")  # a replaced file too
    RowStore(tmp_path).record(KEY, [{**KEY, "v": 1}])
    assert {p.name: stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir()} == {
        "table.md": mode, "rows.jsonl": mode}


def test_atomic_write_replaces_whole_files(tmp_path):
    target = tmp_path / "a" / "table.md"
    atomic_write(target, "one")
    atomic_write(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["table.md"]
