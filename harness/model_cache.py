"""Trained models on disk, keyed by adapter, config, options, seed, case and code version, with
the training cost measured when they were trained (so a cached run still reports it)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from harness.store import atomic_write
from solvers.base import AbstractSolver, FitReport

__all__ = ["Persistable", "cache_key", "code_version", "load_cached", "store_cached"]

_ROOT = Path(__file__).resolve().parents[1]


def code_version() -> str:
    """Hash of the sources that determine a trained model: the model, cases and solver packages."""
    digest = hashlib.sha256()
    for path in sorted([*(_ROOT / "solvers").rglob("*.py"), _ROOT / "harness" / "model.py",
                        _ROOT / "harness" / "cases.py"]):
        digest.update(path.relative_to(_ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def Persistable(solver: AbstractSolver) -> bool:
    """Whether the adapter can save and load trained models."""
    return callable(getattr(solver, "save", None)) and callable(getattr(solver, "load", None))


def cache_key(solver: AbstractSolver, threads: int) -> str:
    payload = json.dumps({"solver": solver.name, "config": solver.config, "options": solver.options,
                          "case": solver.case.__dict__, "threads": threads, "code": code_version()},
                         sort_keys=True, default=str)
    return f"{solver.name}-{solver.config}-{hashlib.sha256(payload.encode()).hexdigest()[:16]}"


def load_cached(solver: AbstractSolver, cache_dir: Path, threads: int) -> FitReport | None:
    """Load the trained model into `solver` and return its recorded FitReport, or None on a miss."""
    base = Path(cache_dir) / cache_key(solver, threads)
    meta = base.with_suffix(".fit.json")
    if not meta.exists():
        return None
    solver.load(base)
    solver.fitted = True
    return FitReport(**json.loads(meta.read_text()))


def store_cached(solver: AbstractSolver, report: FitReport, cache_dir: Path, threads: int) -> None:
    base = Path(cache_dir) / cache_key(solver, threads)
    base.parent.mkdir(parents=True, exist_ok=True)
    solver.save(base)
    atomic_write(base.with_suffix(".fit.json"), json.dumps(report._asdict()))
