"""A call in a fresh Python process, under a wall-clock and a memory limit, with its peak memory.

`call_isolated(fn, *args, limits=...)` pickles (fn, args) to a file, starts
`python -m harness.run.isolation PARENT IN OUT` in a session of its own (so that a limit kills the
child's whole process group, whatever it started), and polls it: past `limits.seconds` of
wall-clock time, or once the resident memory of the child and its own children exceeds
`limits.rss_mb`, the whole session is killed and `OverLimit` raised, saying which limit and what was
reached. Otherwise the child's result (or its exception, raised here) comes back with the child's
peak resident set size (VmHWM, MiB), which is the peak of everything it did: imports, building,
training, queries.

The child dies with this process, however this one ends: its own session keeps it out of a kill
of this process's group and out of a terminal's Ctrl-C, so on Linux it asks the kernel for SIGKILL
when its parent dies (`prctl(PR_SET_PDEATHSIG)`; elsewhere a thread polls for a new parent and
kills the child's group; the kernel's signal ends the child alone, not processes it started itself,
which no adapter does), and it ends at once if its parent died before it could ask. The call and
the result travel in unnamed temporary files (descriptors passed to the child), which the kernel
frees once both processes have closed them: a run killed with SIGKILL leaves no file behind.

It starts with `subprocess`, not `multiprocessing`, so it also works inside a daemonic worker
process (joblib's, Dask's). `fn` must be importable (a module-level function) and its arguments
picklable. Memory is polled every `poll_s` seconds through psutil: a spike shorter than that can
pass unseen, but it still shows in the peak.
"""

from __future__ import annotations

import os
import pickle
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from typing import Any

from harness.settings import NO_LIMITS, Limits

__all__ = ["OverLimit", "call_isolated"]


class OverLimit(RuntimeError):
    """The isolated call ran past a limit of `Limits` and was killed; the message says which."""


def _rss_mb(pid: int) -> float:
    """Resident memory (MiB) of process `pid` and all its descendants (0 once it is gone)."""
    import psutil

    try:
        proc = psutil.Process(pid)
        procs = [proc, *proc.children(recursive=True)]
    except psutil.Error:
        return 0.0
    total = 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total / 2**20


def _kill(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()


def call_isolated(fn: Callable[..., Any], *args: Any, limits: Limits = NO_LIMITS, poll_s: float = 0.05,
                  ) -> tuple[Any, float]:
    """`fn(*args)` in a fresh process under `limits`: returns (its result, the child's peak RSS in
    MiB); re-raises the child's exception; raises `OverLimit` when a limit is passed (the child and
    its children are killed) and RuntimeError if the child dies without a result."""
    # unnamed files (O_TMPFILE, or unlinked at once): nothing on disk outlives both processes
    with tempfile.TemporaryFile() as inp, tempfile.TemporaryFile() as out:
        # this process's sys.path first: the child unpickles `fn` from the same modules
        inp.write(pickle.dumps(list(sys.path)) + pickle.dumps((fn, args)))
        inp.flush()
        fds = (inp.fileno(), out.fileno())
        proc = subprocess.Popen([sys.executable, "-m", __name__, str(os.getpid()), *map(str, fds)],
                                start_new_session=True, pass_fds=fds)
        start, peak_seen = time.perf_counter(), 0.0
        try:
            while proc.poll() is None:
                elapsed = time.perf_counter() - start
                if limits.seconds is not None and elapsed > limits.seconds:
                    _kill(proc)
                    raise OverLimit(f"out of time: still running after {limits.seconds:g} s (killed)")
                if limits.rss_mb is not None:
                    peak_seen = max(peak_seen, _rss_mb(proc.pid))
                    if peak_seen > limits.rss_mb:
                        _kill(proc)
                        raise OverLimit(f"out of memory: {peak_seen:.0f} MiB resident > the limit "
                                        f"{limits.rss_mb:g} MiB (killed)")
                time.sleep(poll_s)
        except BaseException:  # Ctrl-C here must not leave the child running
            if proc.poll() is None:
                _kill(proc)
            raise
        out.seek(0)  # the child wrote from offset 0 of the description both share
        payload = out.read()
    try:
        ok, value, peak_mb = pickle.loads(payload)
    except (EOFError, pickle.UnpicklingError):  # none, or cut short by the child's death
        raise RuntimeError(f"the isolated process ended with exit code {proc.returncode} and no result") from None
    if not ok:
        raise value
    return value, peak_mb


def _peak_rss_mib() -> float:
    """This process's peak resident memory (MiB): VmHWM of /proc/self/status, the high-water mark of
    this process's own memory since its exec. Not `ru_maxrss`: on Linux that survives exec and
    starts at the parent's resident size at fork (measured: every child of a 498 MiB parent
    reported 498 MiB). Elsewhere `ru_maxrss` (KiB on Linux, bytes on macOS), an upper bound."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return maxrss / 2**20 if sys.platform == "darwin" else maxrss / 1024


# prctl(2) option: the signal this process gets when the thread that started it ends (the thread in
# `call_isolated`, which waits for the child: its end is the parent's)
PR_SET_PDEATHSIG = 1


def _signal_on_parent_death(sig: int) -> bool:
    """Ask the kernel for `sig` when this process's parent ends (Linux); False where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _kill_group_when_orphaned(parent: int, poll_s: float = 0.5) -> None:
    """Poll for a parent other than `parent` (it died; this process was adopted), then kill this
    process's group: this process and what it started."""
    while os.getppid() == parent:
        time.sleep(poll_s)
    os.killpg(os.getpgrp(), signal.SIGKILL)


def _die_with(parent: int) -> None:
    """End this process when `parent` ends; at once if it already has (before the kernel was asked,
    the death went unseen). The kernel's signal comes even while Python is busy in C code; the
    polling thread is the fallback where there is none."""
    if not _signal_on_parent_death(signal.SIGKILL):
        threading.Thread(target=_kill_group_when_orphaned, args=(parent,), daemon=True).start()
    if os.getppid() != parent:
        os._exit(1)


def _child(parent: int, inp_fd: int, out_fd: int) -> None:
    _die_with(parent)
    with os.fdopen(inp_fd, "rb") as f:
        f.seek(0)
        sys.path[:] = pickle.load(f)
        fn, args = pickle.load(f)
    os.set_inheritable(out_fd, False)  # not for what `fn` starts
    try:
        result = (True, fn(*args))
    except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
        result = (False, exc)
    peak_mb = _peak_rss_mib()
    try:
        payload = pickle.dumps((*result, peak_mb))
    except Exception:  # noqa: BLE001 - an unpicklable exception: its text instead
        payload = pickle.dumps((False, RuntimeError(f"{type(result[1]).__name__}: {result[1]}"), peak_mb))
    with os.fdopen(out_fd, "wb") as f:
        f.write(payload)


if __name__ == "__main__":
    _child(*map(int, sys.argv[1:4]))
