"""A call in a fresh Python process, under a wall-clock and a memory limit, with its peak memory.

`call_isolated(fn, *args, limits=...)` pickles (fn, args) to a file, starts
`python -m harness.isolation IN OUT` in a session of its own, and polls it: past
`limits.seconds` of wall-clock time, or once the resident memory of the child and its own
children exceeds `limits.rss_mb`, the whole session is killed and `OverLimit` raised, saying
which limit and what was reached. Otherwise the child's result (or its exception, raised here)
comes back with the child's peak resident set size (VmHWM, MiB), which is the peak of everything
it did: imports, building, training, queries.

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
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

__all__ = ["NO_LIMITS", "Limits", "OverLimit", "call_isolated"]


class Limits(NamedTuple):
    """Wall-clock seconds and resident memory (MiB) a call may use; None: no limit."""

    seconds: float | None = None
    rss_mb: float | None = None


NO_LIMITS = Limits()


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
    with tempfile.TemporaryDirectory(prefix="swingbench-isolated-") as tmp:
        inp, out = Path(tmp, "call.pkl"), Path(tmp, "result.pkl")
        # this process's sys.path first: the child unpickles `fn` from the same modules
        inp.write_bytes(pickle.dumps(list(sys.path)) + pickle.dumps((fn, args)))
        proc = subprocess.Popen([sys.executable, "-m", "harness.isolation", str(inp), str(out)],
                                start_new_session=True)
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
        if not out.exists():
            raise RuntimeError(f"the isolated process ended with exit code {proc.returncode} and no result")
        ok, value, peak_mb = pickle.loads(out.read_bytes())
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


def _child(inp: str, out: str) -> None:
    with open(inp, "rb") as f:
        sys.path[:] = pickle.load(f)
        fn, args = pickle.load(f)
    try:
        result = (True, fn(*args))
    except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
        result = (False, exc)
    peak_mb = _peak_rss_mib()
    try:
        payload = pickle.dumps((*result, peak_mb))
    except Exception:  # noqa: BLE001 - an unpicklable exception: its text instead
        payload = pickle.dumps((False, RuntimeError(f"{type(result[1]).__name__}: {result[1]}"), peak_mb))
    Path(out).write_bytes(payload)


if __name__ == "__main__":
    _child(*sys.argv[1:3])
