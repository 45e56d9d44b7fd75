"""Ctrl-C during a run is answered at once, even inside a long compiled call (`harness.cli.interrupts`)."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

from harness.cli.interrupts import ACKNOWLEDGED, EXIT_INTERRUPTED

ROOT = Path(__file__).resolve().parents[1]

# A call of minutes in C that releases the GIL and never looks for signals, as an XLA call does.
SCRIPT = """
import hashlib
import signal
import subprocess
from harness.cli.interrupts import answered_at_once

signal.signal(signal.SIGINT, signal.default_int_handler)  # a terminal's Ctrl-C, whatever the test worker ignores

worker = subprocess.Popen(["sleep", "300"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # a run's worker
with answered_at_once(lambda: "kept: what the store holds"):
    print(worker.pid, flush=True)
    hashlib.pbkdf2_hmac("sha256", b"x", b"y", 2 ** 31 - 1)
"""


def _line(stream, seconds: float) -> str:
    ready, _, _ = select.select([stream], [], [], seconds)
    return stream.readline() if ready else ""


def test_ctrl_c_inside_a_compiled_call_is_acknowledged_at_once_and_a_second_one_stops_the_run():
    """The first Ctrl-C inside a call that releases the GIL is acknowledged while the call runs on;
    the second ends the process with the kept line and exit 130, and its worker processes with it."""
    import psutil

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        worker = int(_line(proc.stdout, 60.0))
        time.sleep(0.2)  # inside the call
        proc.send_signal(signal.SIGINT)
        assert _line(proc.stderr, 10.0) == ACKNOWLEDGED + "\n"
        assert proc.poll() is None  # still in the call: Python's own handler waits for it to return
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10.0) == EXIT_INTERRUPTED
        assert proc.stderr.read() == "kept: what the store holds\n"
        time.sleep(0.5)
        assert not psutil.pid_exists(worker) or psutil.Process(worker).status() == psutil.STATUS_ZOMBIE
    finally:
        proc.kill()
        proc.wait()
