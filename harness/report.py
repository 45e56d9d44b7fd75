"""Rows -> tidy CSV per suite, Markdown tables, run metadata. Nothing here measures anything."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import subprocess
from pathlib import Path

import pandas as pd

from harness.store import atomic_write

__all__ = ["markdown_tables", "metadata", "write_report"]

LIBRARIES = ("numpy", "scipy", "pandas", "casadi", "torch", "jax", "jaxlib", "optax")


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def metadata(threads: int) -> dict:
    """Machine, CPU, threads, library versions, commit and date of a run."""
    versions = {}
    for lib in LIBRARIES:
        try:
            versions[lib] = importlib.metadata.version(lib)
        except importlib.metadata.PackageNotFoundError:
            versions[lib] = "not installed"
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, cwd=Path(__file__).parent, check=False).stdout.strip()
        commit += "+dirty" if dirty else ""
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": platform.node(), "platform": platform.platform(), "cpu": _cpu(),
        "cpu_count": os.cpu_count(), "threads": threads, "python": platform.python_version(),
        "commit": commit, **{f"version_{k}": v for k, v in versions.items()},
    }


def _label(df: pd.DataFrame) -> pd.Series:
    variant = df["variant"].fillna("").map(lambda v: f", {v}" if v else "")
    return df["solver"] + " [" + df["config"] + variant + "]"


def _status_table(df: pd.DataFrame) -> pd.DataFrame:
    bad = df[df["status"] != "ok"]
    return bad.assign(solver=_label(bad))[["case", "solver", "status"]].drop_duplicates()


def _fit_table(df: pd.DataFrame) -> pd.DataFrame:
    ok = df[df["status"] == "ok"]
    return ok.assign(solver=_label(ok)).reindex(columns=["case", "solver", "fit_s", "iterations", "loss"]).rename(
        columns={"fit_s": "fit / build (s)", "iterations": "iterations", "loss": "final loss"})


def _accuracy_table(df: pd.DataFrame) -> pd.DataFrame:
    ok = df[df["status"] == "ok"].assign(solver=_label(df[df["status"] == "ok"]))
    ok = ok.assign(column=ok["quantity"] + " vs " + ok["against"])
    wide = ok.pivot_table(index=["case", "solver"], columns="column", values=["rel_l2", "max_abs"],
                          aggfunc="first", sort=False)
    wide.columns = [f"{col} {'rel. L2' if stat == 'rel_l2' else 'max abs'}" for stat, col in wide.columns]
    order = sorted(wide.columns, key=lambda c: ("omega" in c, "paper" in c, "max" in c))
    return wide[order].reset_index()


def _latency_table(df: pd.DataFrame) -> pd.DataFrame:
    ok = df[df["status"] == "ok"].assign(solver=_label(df[df["status"] == "ok"]))
    ok = ok.assign(cell=ok.apply(lambda r: f"{r.median_s * 1e3:.3g} [{r.q25_s * 1e3:.3g}, {r.q75_s * 1e3:.3g}]",
                                 axis=1))
    wide = ok.pivot_table(index=["case", "solver"], columns="query", values="cell", aggfunc="first", sort=False)
    wide.columns = [f"{c} (ms)" for c in wide.columns]
    return wide.reset_index()


TABLES = {
    "fit": ("Preparation cost (untimed in queries): build, JIT, training", _fit_table),
    "accuracy": ("Accuracy on the 100 x 201 grid (delta in rad, omega in rad/s)", _accuracy_table),
    "latency": ("Warm query latency, median [25th, 75th percentile] of repeats, delta and omega", _latency_table),
}


def markdown_tables(frames: dict[str, pd.DataFrame]) -> str:
    """The Markdown of every known suite present in `frames`, plus any skipped/failed rows."""
    parts = []
    for suite, (title, build) in TABLES.items():
        df = frames.get(suite)
        if df is None or df.empty or not (df["status"] == "ok").any():
            continue
        parts.append(f"### {title}\n\n{build(df).to_markdown(index=False, floatfmt='.3g')}\n")
    everything = pd.concat(list(frames.values()), ignore_index=True) if frames else pd.DataFrame()
    if not everything.empty:
        bad = _status_table(everything)
        if not bad.empty:
            parts.append(f"### Skipped or failed\n\n{bad.to_markdown(index=False)}\n")
    return "\n".join(parts)


def write_report(rows: list[dict], out_dir: Path, meta: dict) -> str:
    """Write `<suite>.csv` (tidy, one row per measurement), `tables.md` and `metadata.json` to
    `out_dir`, each atomically; return the Markdown."""
    out_dir = Path(out_dir)
    frame = pd.DataFrame(rows)
    frames = {suite: group.dropna(axis=1, how="all").reset_index(drop=True)
              for suite, group in frame.groupby("suite", sort=False)} if not frame.empty else {}
    for suite, df in frames.items():
        atomic_write(out_dir / f"{suite}.csv", df.to_csv(index=False))
    get = lambda key: meta.get(key, "?")
    header = (f"Run of {get('date')} on {get('cpu')} ({get('threads')} threads), commit {get('commit')}; "
              f"numpy {get('version_numpy')}, scipy {get('version_scipy')}, casadi {get('version_casadi')}, "
              f"torch {get('version_torch')}, jax {get('version_jax')}.\n\n")
    markdown = header + markdown_tables(frames)
    atomic_write(out_dir / "tables.md", markdown)
    atomic_write(out_dir / "metadata.json", json.dumps(meta, indent=2))
    return markdown
