"""harness.isolation: a call in a fresh process, its result, its exception, its limits."""

from __future__ import annotations

import os
import time

import pytest

from harness.isolation import Limits, OverLimit, call_isolated


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
