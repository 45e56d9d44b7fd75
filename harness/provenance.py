"""Where and with what a run was made: machine, CPU, threads, library versions, commit and date
(`metadata`, the run's `metadata.json`)."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from collections.abc import Sequence
from pathlib import Path

from harness.versions import library_versions
from solvers import SOLVERS, plugin_distribution

__all__ = ["LIBRARIES", "git_commit", "metadata"]

LIBRARIES = ("numpy", "scipy", "pandas", "casadi", "torch", "jax", "jaxlib", "optax", "numba", "diffrax")


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def git_commit(repo: Path, outputs: Sequence[Path] = ()) -> str:
    """The short commit of `repo`, with "+dirty" when a tracked file differs from it, not counting
    `outputs` (what the run itself writes: its results folder, the README it updates); "unknown"
    outside a git checkout."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=repo, check=True).stdout.strip()
        top = Path(subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True,
                                  cwd=repo, check=True).stdout.strip())
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    excluded = []
    for path in outputs:
        try:
            excluded.append(f":(exclude){Path(path).resolve().relative_to(top.resolve()).as_posix()}")
        except ValueError:  # outside the checkout: git does not see it anyway
            continue
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *excluded],
                           capture_output=True, text=True, cwd=top, check=False).stdout.strip()
    return commit + ("+dirty" if dirty else "")


def metadata(threads: int, outputs: Sequence[Path] = ()) -> dict:
    """Machine, CPU, threads, library versions (the distributions of adapters from outside the
    repository too), commit (see `git_commit`) and date of a run."""
    plugins = tuple(dict.fromkeys(dist for name in SOLVERS if (dist := plugin_distribution(name))))
    versions = library_versions(LIBRARIES + plugins)
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": platform.node(), "platform": platform.platform(), "cpu": _cpu(),
        "cpu_count": os.cpu_count(), "threads": threads, "python": platform.python_version(),
        "commit": git_commit(Path(__file__).parent, outputs),
        **{f"version_{k}": v for k, v in versions.items()},
    }
