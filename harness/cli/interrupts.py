"""Ctrl-C answered at once while `run` or `sweep` measures (`answered_at_once`).

Python runs its SIGINT handler, which raises KeyboardInterrupt, only between bytecodes of the main
thread: while that thread is inside compiled code (a numba kernel over 10,000 trajectories, an XLA
call, a BLAS factorisation) a Ctrl-C waits, unanswered, until the call returns. The C-level handler
does write the signal's number to the wakeup file descriptor at once (`signal.set_wakeup_fd`), and
a thread blocked on that descriptor runs then: it says on stderr that the interrupt was received,
and on a second Ctrl-C ends the process. Every row written before is on disk (the row store fsyncs
each), so what is lost is the unit of work in progress, which `--resume` measures again.

This module imports only the standard library: the CLI imports it to build its parser."""

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


@contextlib.contextmanager
def answered_at_once(on_exit: Callable[[], str]) -> Iterator[None]:
    """While entered, in the main thread: the first Ctrl-C prints `ACKNOWLEDGED` on stderr the
    moment it arrives, and the KeyboardInterrupt still comes, as without this, when the main thread
    is back in Python; a second Ctrl-C prints `on_exit()` (what was kept, how to continue) and ends
    the process at once with `EXIT_INTERRUPTED`. Elsewhere than the main thread, or where another
    wakeup descriptor is set (an event loop's), it changes nothing."""
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
                print(ACKNOWLEDGED, file=sys.stderr, flush=True)
            elif seen > 1:
                try:
                    print(on_exit(), file=sys.stderr, flush=True)
                finally:
                    os._exit(EXIT_INTERRUPTED)

    thread = threading.Thread(target=watch, name="swingbench-ctrl-c", daemon=True)
    thread.start()
    try:
        yield
    finally:
        signal.set_wakeup_fd(-1)
        done.set()
        writer.send(b"\0")  # wakes the thread to see `done`
        thread.join(timeout=1.0)
        reader.close()
        writer.close()
