"""harness.run.isolation: a call in a fresh process, its result, its exception, its limits."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.run.isolation import OverLimit, call_isolated
from harness.settings import Limits


def _pid_and_sum(a: int, b: int) -> tuple[int, int]:
    return os.getpid(), a + b


def _allocate(mb: int) -> int:
    block = bytearray(mb * 2**20)
    block[::4096] = b"x" * len(block[::4096])  # touch every page: resident, not only reserved
    time.sleep(5.0)
    return len(block)


def _raise() -> None:
    raise ValueError("bad input named here")


def test_result_and_peak_memory_come_back_from_another_process():
    (pid, total), peak_mb = call_isolated(_pid_and_sum, 2, 3)
    assert total == 5 and pid != os.getpid()
    assert 5 < peak_mb < 2000  # a bare interpreter with numpy-free imports: tens of MiB


def _bare() -> int:
    return 0


def test_the_peak_memory_is_the_child_s_own_not_its_parent_s():
    ballast = bytearray(600 * 2**20)  # this process: 600 MiB more resident than the child will be
    ballast[::4096] = b"x" * len(ballast[::4096])
    _, peak_mb = call_isolated(_bare)
    del ballast
    assert peak_mb < 400  # the bare child only; ru_maxrss would report this process's size


def test_the_child_s_exception_is_raised_here():
    with pytest.raises(ValueError, match="bad input named here"):
        call_isolated(_raise)


def test_a_call_past_its_time_is_killed_with_a_message():
    start = time.perf_counter()
    with pytest.raises(OverLimit, match="out of time: still running after 0.5 s"):
        call_isolated(time.sleep, 30.0, limits=Limits(seconds=0.5))
    assert time.perf_counter() - start < 10.0


def test_a_call_past_its_memory_is_killed_with_a_message():
    with pytest.raises(OverLimit, match=r"out of memory: \d+ MiB resident > the limit 150 MiB"):
        call_isolated(_allocate, 300, limits=Limits(rss_mb=150.0))


def _running(pid: int) -> bool:
    """Not ended and not a zombie (an ended process its new parent has not reaped)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


# A child in a session of its own (as `call_isolated` starts one) with only the polling fallback, and
# a process it started; the child prints both pids, and its parent waits for it (until killed).
CHILD = """import os, subprocess, sys, threading, time
from harness.run.isolation import _kill_group_when_orphaned
grandchild = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
threading.Thread(target=_kill_group_when_orphaned, args=(os.getppid(), 0.05), daemon=True).start()
print(os.getpid(), grandchild.pid, flush=True)
time.sleep(60)
"""
PARENT = f"""import subprocess, sys
subprocess.Popen([sys.executable, "-c", {CHILD!r}], start_new_session=True).wait()
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads processes from /proc")
def test_without_the_kernel_s_signal_an_orphaned_child_kills_its_group():
    with subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True,
                          cwd=Path(__file__).parents[1]) as parent:
        pids = [int(pid) for pid in parent.stdout.readline().split()]
        try:
            assert len(pids) == 2 and all(map(_running, pids))
            parent.kill()
            parent.wait()
            deadline = time.monotonic() + 5
            while any(map(_running, pids)) and time.monotonic() < deadline:
                time.sleep(0.02)
            assert not any(map(_running, pids))
        finally:
            parent.kill()
            for pid in filter(_running, pids):
                os.kill(pid, signal.SIGKILL)
