"""Suites: each a function (solver, case, settings) -> list of row dicts, no I/O.

A row holds the measurement's own columns; the runner adds suite, case, solver, config, variant
and status, so every suite's rows form one tidy DataFrame.
"""

from harness.suites.accuracy import accuracy
from harness.suites.latency import latency

SUITES = {"accuracy": accuracy, "latency": latency}

__all__ = ["SUITES", "accuracy", "latency"]
