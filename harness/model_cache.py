"""Trained models on disk, keyed by adapter, config, options, seed, case and code version, with
the training cost measured when they were trained (so a cached run still reports it)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from harness.store import atomic_write
from harness.versions import library_versions
from solvers.base import AbstractSolver, FitReport

__all__ = ["QUERY_ONLY_OPTIONS", "TRAINING_LIBRARIES", "Persistable", "cache_key", "code_version", "load_cached",
           "store_cached"]

_ROOT = Path(__file__).resolve().parents[1]


# Options that change how a trained model is used, never the model itself.
QUERY_ONLY_OPTIONS = frozenset({"threads", "progress", "query"})
# Libraries whose arithmetic makes the training data (scipy's DOP853 reference) or the model.
TRAINING_LIBRARIES = ("numpy", "scipy", "torch", "jax", "jaxlib")


def code_version() -> str:
    """Hash of the sources that determine a trained model: the model, cases, the reference that
    makes its training data, and the solver packages."""
    digest = hashlib.sha256()
    for path in sorted([*(_ROOT / "solvers").rglob("*.py"), _ROOT / "harness" / "model.py",
                        _ROOT / "harness" / "cases.py", _ROOT / "harness" / "reference.py"]):
        digest.update(path.relative_to(_ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def Persistable(solver: AbstractSolver) -> bool:
    """Whether the adapter can save and load trained models."""
    return callable(getattr(solver, "save", None)) and callable(getattr(solver, "load", None))


def cache_key(solver: AbstractSolver) -> str:
    """The file stem of `solver`'s trained model: adapter, config, every option that changes
    training (not `QUERY_ONLY_OPTIONS`: threads change the speed of training, and its result only
    by floating-point summation order), case, code and library versions."""
    options = {k: v for k, v in solver.options.items() if k not in QUERY_ONLY_OPTIONS}
    payload = json.dumps({"solver": solver.name, "config": solver.config, "options": options,
                          "case": solver.case.__dict__, "code": code_version(),
                          "libraries": library_versions(TRAINING_LIBRARIES)},
                         sort_keys=True, default=str)
    return f"{solver.name}-{solver.config}-{hashlib.sha256(payload.encode()).hexdigest()[:16]}"


def load_cached(solver: AbstractSolver, cache_dir: Path) -> FitReport | None:
    """Load the trained model into `solver` and return its recorded FitReport, or None on a miss."""
    base = Path(cache_dir) / cache_key(solver)
    meta = base.with_suffix(".fit.json")
    if not meta.exists():
        return None
    solver.load(base)
    solver.fitted = True
    return FitReport(**json.loads(meta.read_text()))


def store_cached(solver: AbstractSolver, report: FitReport, cache_dir: Path) -> None:
    base = Path(cache_dir) / cache_key(solver)
    base.parent.mkdir(parents=True, exist_ok=True)
    solver.save(base)
    atomic_write(base.with_suffix(".fit.json"), json.dumps(report._asdict()))
