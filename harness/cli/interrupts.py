"""Ctrl-C answered at once while `run` or `sweep` measures (`answered_at_once`).

Python runs its SIGINT handler, which raises KeyboardInterrupt, only between bytecodes of the main
thread: while that thread is inside a long compiled call (an XLA computation, a torch or BLAS
kernel, a numba kernel) a Ctrl-C waits, unanswered, until the call returns. The C-level handler
does write the signal's number to the wakeup file descriptor at once (`signal.set_wakeup_fd`), and
a thread blocked on that descriptor can run then, provided the call released the GIL (XLA, torch,
BLAS and the PINNs' numba query kernels do; the classical numba kernels do not, so there the answer
waits for the call, which for a verdict's rival the probe keeps within a few times `max_query_s`): it says on stderr that
the interrupt was received, and on a second Ctrl-C ends the process. Every row written before is
on disk (the row store fsyncs each, its completion record last), so what is lost is the unit of
work in progress, which `--resume` measures again, but for the rounds a checkpointing unit (the
verdict suite's) finished, which `--resume` records (`harness.run.runner`).

This module imports only the standard library (psutil only on the way out of a second Ctrl-C)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sys
import threading
from collections.abc import Callable, Iterator

__all__ = ["ACKNOWLEDGED", "EXIT_INTERRUPTED", "answered_at_once"]

EXIT_INTERRUPTED = 130  # a shell's status for a process ended by SIGINT
ACKNOWLEDGED = ("[swingbench] Ctrl-C received: stopping when the call in progress returns (compiled code cannot be "
                "interrupted); Ctrl-C again to stop now, losing only the unit of work in progress")


def _say(text: str) -> None:
    with contextlib.suppress(OSError, ValueError):  # a closed or broken stderr: nothing to tell
        print(text, file=sys.stderr, flush=True)


def _stop_now(on_exit: Callable[[], str]) -> None:
    """Print `on_exit()` (or, if it fails, that the run was stopped), end the worker processes the
    run started (a joblib worker inside a kernel would run on), and exit with `EXIT_INTERRUPTED`."""
    try:
        try:
            _say(on_exit())
        except Exception:  # noqa: BLE001 - the exit must happen whatever the message does
            _say("[swingbench] stopped by a second Ctrl-C")
        with contextlib.suppress(Exception):
            import psutil  # a dependency of Dask, which the runner's executors use

            for child in psutil.Process().children(recursive=True):
                with contextlib.suppress(psutil.Error):
                    child.kill()
    finally:
        os._exit(EXIT_INTERRUPTED)


@contextlib.contextmanager
def answered_at_once(on_exit: Callable[[], str]) -> Iterator[None]:
    """While entered, in the main thread: the first Ctrl-C prints `ACKNOWLEDGED` on stderr the
    moment it arrives (where the call in progress released the GIL), and the KeyboardInterrupt
    still comes, as without this, when the main thread is back in Python; a second Ctrl-C prints
    `on_exit()` (what was kept, how to continue) and ends the process at once with
    `EXIT_INTERRUPTED`, its worker processes with it. Elsewhere than the main thread, or where
    another wakeup descriptor is set (an event loop's), it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    reader, writer = socket.socketpair()
    writer.setblocking(False)
    previous = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
    if previous != -1:  # someone else's descriptor: leave it in place
        signal.set_wakeup_fd(previous)
        reader.close()
        writer.close()
        yield
        return
    done = threading.Event()

    def watch() -> None:
        seen = 0
        while not done.is_set():
            data = reader.recv(64)
            if done.is_set() or not data:
                return
            seen += data.count(bytes([signal.SIGINT]))
            if seen == 1:
                _say(ACKNOWLEDGED)
            elif seen > 1:
                _stop_now(on_exit)

    thread = threading.Thread(target=watch, name="swingbench-ctrl-c", daemon=True)
    thread.start()
    try:
        yield
    finally:
        current = signal.set_wakeup_fd(-1)
        if current not in (writer.fileno(), -1):  # set by the body since: put it back
            signal.set_wakeup_fd(current)
        done.set()
        writer.send(b"\0")  # wakes the thread to see `done`
        thread.join(timeout=1.0)
        reader.close()
        writer.close()
