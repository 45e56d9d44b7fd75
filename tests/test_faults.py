"""Fault injection: a real `swingbench run` in a subprocess, killed (SIGKILL) and interrupted (SIGINT,
Ctrl-C) at random moments, each time continued with `--resume`: it must end with exactly the rows of
an uninterrupted run, and a second `--resume` must change nothing."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.store import RowStore

ARGV = ["run", "--quick", "--case", "smib-inference", "--solver", "scipy-odeint", "--suite", "latency", "--threads", "1", "--progress", "off"]
# Columns whose values are measurements (times, repeat counts, where it ran), not what was measured.
MEASURED = {"repeats", "worker", "point_repeats"}


def _swingbench(out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "harness.cli", *ARGV, "--out", str(out), *extra],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _identity(rows: list[dict]) -> list[tuple]:
    """What each row says was measured, in a stable order: every column but floats and `MEASURED`,
    and not the status, which says whether a call was fast enough to time ("skipped: estimated
    0.6 s per call" on a loaded machine); a failure is caught apart."""
    assert not [row for row in rows if str(row.get("status")).startswith("failed")]
    return sorted(tuple(sorted((k, str(v)) for k, v in row.items()
                               if not isinstance(v, float) and k not in MEASURED and k != "status"))
                  for row in rows)


def _completed(out: Path) -> int:
    path = out / "rows.jsonl"
    return path.read_bytes().count(b'"_complete"') if path.exists() else 0


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> list[tuple]:
    out = tmp_path_factory.mktemp("whole")
    proc = _swingbench(out)
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    return _identity(RowStore(out).rows())


# Three interruptions of one run, each at a random moment of what is left (seeds 0, 1, 2): two
# SIGKILLs, then Ctrl-C, each continued with --resume; the last --resume finishes the run.
INTERRUPTIONS = ((signal.SIGKILL, 0), (signal.SIGKILL, 1), (signal.SIGINT, 2))


def test_resume_after_kills_ends_with_the_rows_of_an_uninterrupted_run(uninterrupted, tmp_path):
    for sig, seed in INTERRUPTIONS:
        rng = random.Random(seed)
        start = _completed(tmp_path)
        proc = _swingbench(tmp_path, *(["--resume"] if start else []))
        # after a random number of newly recorded units of work (0: possibly still importing; Ctrl-C
        # is sent once the run has started, Python's own start-up is not swingbench's to handle)
        wait_for = start + rng.randrange(0 if sig == signal.SIGKILL else 1, 3)
        deadline = time.monotonic() + 120
        while _completed(tmp_path) < wait_for and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.3))
        finished = proc.poll() is not None
        proc.send_signal(sig)
        code = proc.wait(timeout=120)
        err = proc.stderr.read()
        if code == 0 and err.strip().splitlines()[-1].startswith("[swingbench] wrote"):
            continue  # the run ended between the poll and the signal: nothing was interrupted
        if not finished and sig == signal.SIGKILL:
            assert code == -signal.SIGKILL
        elif not finished:
            assert code == 130, err
            assert err.strip().splitlines()[-1].startswith("[swingbench] interrupted"), err

    resumed = _swingbench(tmp_path, "--resume")
    assert resumed.wait(timeout=300) == 0, resumed.stderr.read()
    assert _identity(RowStore(tmp_path).rows()) == uninterrupted

    before = (tmp_path / "rows.jsonl").read_bytes()  # a second resume of the finished run changes nothing
    again = _swingbench(tmp_path, "--resume")
    assert again.wait(timeout=300) == 0, again.stderr.read()
    assert (tmp_path / "rows.jsonl").read_bytes() == before
