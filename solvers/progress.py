"""Whether progress is shown: the one policy for the runner's bar of units of work and a PINN's
training bar."""

from __future__ import annotations

import os
import sys


def progress_enabled(setting: bool | None) -> bool:
    """`setting`, or with None (auto): on for an interactive terminal, off under pytest, CI or a
    pipe (a bar would only clutter a log or a captured stream)."""
    if setting is not None:
        return bool(setting)
    if "PYTEST_CURRENT_TEST" in os.environ or "pytest" in sys.modules or os.environ.get("CI"):
        return False
    return sys.stderr.isatty()
