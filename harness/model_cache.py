"""Trained models on disk, keyed by adapter, config, options, seed, case and code version, with
the training cost measured when they were trained (so a cached run still reports it).

An entry is the adapter's own files (`save(<key>)`) and `<key>.fit.json`, written last: the
FitReport, the key and the sha256 of each model file. An entry that fails any check on load is
moved to `<cache_dir>/corrupt/` with one line on stderr, and is a miss: it is retrained."""

from __future__ import annotations

import glob
import hashlib
import json
import math
import os
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

from harness.usage import raise_if_interrupted
from harness.versions import library_versions
from solvers import plugin_distribution
from solvers.atomic import atomic_write
from solvers.base import AbstractSolver, FitReport
from systems.cases import case_record

__all__ = [
    "CACHE_FORMAT",
    "TRAINING_LIBRARIES",
    "Persistable",
    "cache_key",
    "code_version",
    "fit_or_load",
    "load_cached",
    "store_cached",
]

_ROOT = Path(__file__).resolve().parents[1]


# Libraries whose arithmetic makes the training data (scipy's DOP853 reference) or the model.
TRAINING_LIBRARIES = ("numpy", "scipy", "torch", "jax", "jaxlib")
# The layout of an entry (part of the key: entries of another layout are never read).
# 2: .fit.json records the key and the model files' sha256 and is written last.
CACHE_FORMAT = 2


def code_version() -> str:
    """Hash of the sources that determine a trained model: the model, cases, the reference that
    makes its training data, and the solver packages."""
    digest = hashlib.sha256()
    for path in sorted([*(_ROOT / "solvers").rglob("*.py"), *(_ROOT / "systems").rglob("*.py")]):
        digest.update(path.relative_to(_ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def Persistable(solver: AbstractSolver) -> bool:
    """Whether the adapter can save and load trained models (it declares `can_save`)."""
    return type(solver).can_save


def _plugin(name: str) -> tuple[str, ...]:
    """The distribution of an adapter from outside the repository, whose code `code_version` does
    not hash: its version is in the key instead. () for a built-in adapter."""
    dist = plugin_distribution(name)
    return (dist,) if dist else ()


def cache_key(solver: AbstractSolver) -> str:
    """The file stem of `solver`'s trained model: adapter, config, every option that changes
    training (not the adapter's `QUERY_OPTIONS`: e.g. threads change the speed of training, and its
    result only by floating-point summation order), case, code and library versions (and an outside
    adapter's distribution's), the cache's format."""
    options = {k: v for k, v in solver.options.items() if k not in type(solver).QUERY_OPTIONS}
    payload = json.dumps({"solver": solver.name, "config": solver.config, "options": options,
                          "case": case_record(solver.case), "code": code_version(),
                          "libraries": library_versions(TRAINING_LIBRARIES + _plugin(solver.name)),
                          "cache_format": CACHE_FORMAT},
                         sort_keys=True, default=str)
    return f"{solver.name}-{solver.config}-{hashlib.sha256(payload.encode()).hexdigest()[:16]}"


class _BadEntry(Exception):
    """An entry failed a check: `file` and what is wrong with it."""

    def __init__(self, file: Path, what: str) -> None:
        super().__init__(f"{file}: {what}")


def _fit_path(base: Path) -> Path:
    return base.with_name(base.name + ".fit.json")


def _entry_files(base: Path) -> list[Path]:
    """Every file of the entry at `base` (the adapter's and the .fit.json), sorted."""
    return sorted(base.parent.glob(glob.escape(base.name) + ".*"))


def _model_files(base: Path) -> list[Path]:
    fit = _fit_path(base)
    return [p for p in _entry_files(base) if p != fit]


def _sha256(path: Path) -> str:
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def _verified_report(base: Path, key: str) -> FitReport:
    """The FitReport of the entry at `base`, after checking its .fit.json (format, key, report
    fields) and that each model file it records is there with the recorded sha256."""
    fit = _fit_path(base)
    try:
        record = json.loads(fit.read_bytes().decode())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _BadEntry(fit, f"unreadable (truncated or overwritten?): {exc}") from exc
    if not isinstance(record, dict) or record.get("cache_format") != CACHE_FORMAT:
        raise _BadEntry(fit, f"not a model cache record of format {CACHE_FORMAT}")
    if record.get("key") != key:
        raise _BadEntry(fit, f"records the entry {record.get('key')!r}, not this one")
    files = record.get("files")
    if not isinstance(files, dict) or not files:
        raise _BadEntry(fit, "records no model files")
    for name, digest in sorted(files.items()):
        path = base.parent / name
        if not path.is_file():
            raise _BadEntry(path, f"missing (recorded in {fit.name})")
        if _sha256(path) != digest:
            raise _BadEntry(path, f"sha256 differs from the one recorded in {fit.name} (changed since it was stored)")
    report = record.get("report")
    try:
        report = FitReport(**report)
    except TypeError as exc:
        raise _BadEntry(fit, f"bad report {report!r}") from exc
    valid = (isinstance(report.seconds, (int, float)) and math.isfinite(report.seconds) and report.seconds >= 0
             and isinstance(report.iterations, int) and isinstance(report.loss, (int, float))
             and isinstance(report.message, str))
    if not valid:
        raise _BadEntry(fit, f"bad report {report!r}")
    return report


def _move_aside(cache_dir: Path, base: Path, problem: str) -> None:
    """Move the entry's files to `<cache_dir>/corrupt/` under timestamped names and say so on
    stderr, in one line. A file another process moved already is skipped."""
    corrupt = cache_dir / "corrupt"
    corrupt.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now().strftime("%Y%m%dT%H%M%S.%f")
    for path in _entry_files(base):
        target, n = corrupt / f"{stamp}-{path.name}", 0
        while target.exists():
            n += 1
            target = corrupt / f"{stamp}-{n}-{path.name}"
        try:
            os.replace(path, target)
        except FileNotFoundError:
            continue
    problem = " ".join(problem.splitlines())
    print(f"[swingbench] model cache: {problem}; moved aside to {corrupt}, retraining", file=sys.stderr, flush=True)


def load_cached(solver: AbstractSolver, cache_dir: Path) -> FitReport | None:
    """Load the trained model into `solver` and return its recorded FitReport, or None on a miss.
    An entry that is incomplete (no .fit.json), damaged, changed since it was stored, or that
    `solver.load` refuses is moved aside (see `_move_aside`) and is a miss."""
    cache_dir = Path(cache_dir)
    key = cache_key(solver)
    base = cache_dir / key
    if not _fit_path(base).exists():
        if _model_files(base):
            _move_aside(cache_dir, base, f"{_fit_path(base)}: missing, the entry is incomplete (an interrupted store?)")
        return None
    options = dict(solver.options)
    try:
        report = _verified_report(base, key)
        solver.load(base)
    except _BadEntry as exc:
        problem = str(exc)
    except Exception as exc:  # noqa: BLE001 - whatever the adapter's load raises, the entry is not usable
        raise_if_interrupted(exc)  # a Ctrl-C inside compiled code: the entry is not to blame
        problem = str(exc) if str(exc).startswith(str(base)) else f"{base}: {type(exc).__name__}: {exc}"
    else:
        solver.fitted = True
        return report
    if solver.options != options:  # a load that failed half way: the solver trains with its own options
        solver.options.clear()
        solver.options.update(options)
        solver._check_options()
    solver.fitted = False
    _move_aside(cache_dir, base, problem)
    return None


def store_cached(solver: AbstractSolver, report: FitReport, cache_dir: Path) -> None:
    """Save `solver`'s model and then, last, the .fit.json that makes the entry complete."""
    key = cache_key(solver)
    base = Path(cache_dir) / key
    base.parent.mkdir(parents=True, exist_ok=True)
    fit = _fit_path(base)
    fit.unlink(missing_ok=True)  # the entry is incomplete while its model files are rewritten
    solver.save(base)
    record = {"cache_format": CACHE_FORMAT, "key": key,
              "files": {path.name: _sha256(path) for path in _model_files(base)},
              "report": report._asdict()}
    atomic_write(fit, json.dumps(record, indent=1))


def fit_or_load(solver: AbstractSolver, settings: Any) -> FitReport:
    """`fit()`, or load the trained model from the cache (with the training cost it had; a cache
    entry that fails its checks is moved aside and the model trained again, see
    `harness.model_cache.load_cached`)."""
    cacheable = Persistable(solver) and settings.cache_dir is not None
    if cacheable and not settings.retrain:
        report = load_cached(solver, settings.cache_dir)
        if report is not None:
            solver.fit_report = report._replace(message=f"{report.message} (cached model)".strip())
            return solver.fit_report
    report = solver.fit()
    if cacheable and math.isfinite(report.loss):  # a diverged model is not kept for the next run
        try:
            store_cached(solver, report, settings.cache_dir)
        except OSError as exc:  # a full or read-only disk costs the cache, not the measurement
            print(f"[swingbench] model cache: cannot store in {settings.cache_dir}: {exc}", file=sys.stderr)
    return report
