"""Fault injection: a real `swingbench run` in a subprocess, killed (SIGKILL) and interrupted (SIGINT,
Ctrl-C) at random moments, each time continued with `--resume`: it must end with exactly the rows of
an uninterrupted run, and a second `--resume` must change nothing. A run with `--unit-seconds`, killed
while a unit's worker process runs, must take that worker down with it and leave no temporary files."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.run import isolation
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


@pytest.mark.slow
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


def _started(pid: int) -> tuple[int, str] | None:
    """(pid, start time in clock ticks) of a live process; None once it is gone or a zombie (a pid
    reused by a later process has another start time)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()  # after the command name, which may hold spaces
    except OSError:
        return None
    return None if fields[0] == "Z" else (pid, fields[19])


def _alive(started: tuple[int, str]) -> bool:
    return _started(started[0]) == started


def _children() -> dict[int, list[int]]:
    """ppid -> pids of every process on the machine."""
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/stat") as f:
                tree.setdefault(int(f.read().rsplit(")", 1)[1].split()[1]), []).append(int(entry))
        except (OSError, ValueError, IndexError):
            pass
    return tree


def _descendants(pid: int) -> list[int]:
    tree, found, todo = _children(), [], [pid]
    while todo:
        children = tree.get(todo.pop(), [])
        found += children
        todo += children
    return found


def _workers(pid: int) -> list[int]:
    """The unit worker processes among `pid`'s children."""
    found = []
    for child in _children().get(pid, []):
        try:
            with open(f"/proc/{child}/cmdline", "rb") as f:
                if isolation.__name__.encode() in f.read():
                    found.append(child)
        except OSError:
            pass
    return found


# One unit in a worker process that runs for seconds (6.5 s on an idle machine), after ~2 s of start-up.
SLOW_UNIT = ["run", "--quick", "--case", "smib-identification", "--solver", "scipy-odeint", "--config", "tight",
             "--suite", "identification", "--threads", "1", "--progress", "off", "--unit-seconds", "60"]
# How a run is stopped: kill -9 of its process group, of its process alone, and Ctrl-C in its terminal.
KILLS = {"kill -9 of the group": lambda pid: os.killpg(pid, signal.SIGKILL),
         "kill -9 of the process": lambda pid: os.kill(pid, signal.SIGKILL),
         "Ctrl-C": lambda pid: os.killpg(pid, signal.SIGINT)}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads processes from /proc")
@pytest.mark.parametrize("kill", KILLS)
def test_a_killed_run_leaves_no_unit_worker_and_no_temporary_files(tmp_path, kill):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    with subprocess.Popen([sys.executable, "-m", "harness.cli", *SLOW_UNIT, "--out", str(tmp_path / "out")],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env={**os.environ, "TMPDIR": str(tmp)}, start_new_session=True) as run:
        processes: list[tuple[int, str]] = []
        try:
            deadline = time.monotonic() + 60
            while not _workers(run.pid) and run.poll() is None and time.monotonic() < deadline:
                time.sleep(0.02)
            assert _workers(run.pid), f"no unit worker started; the run: {run.poll()=}, " + (
                run.stderr.read() if run.poll() is not None else "still running")
            time.sleep(0.5)  # into its unit
            processes = [p for p in map(_started, [run.pid, *_descendants(run.pid)]) if p]
            assert len(processes) >= 2
            KILLS[kill](run.pid)
            run.wait(timeout=30)
            deadline = time.monotonic() + 3  # well before the unit would have ended by itself
            while any(map(_alive, processes)) and time.monotonic() < deadline:
                time.sleep(0.02)
            assert not [p for p in processes if _alive(p)], f"processes of the killed run still run ({kill})"
            assert not list(tmp.iterdir()), f"temporary files left behind ({kill})"
        finally:  # whatever this test started and left running
            for started in [p for p in processes if _alive(p)]:
                os.kill(started[0], signal.SIGKILL)
            if run.poll() is None:
                os.killpg(run.pid, signal.SIGKILL)
            run.wait(timeout=30)
