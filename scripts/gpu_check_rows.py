"""The Python steps of scripts/gpu_check.sh: where JAX computes, that device in a run's metadata,
and the check's one-line summary from the runs' rows.

  python scripts/gpu_check_rows.py probe --want gpu        # JSON on stdout; exit 3 if JAX has no such backend
  python scripts/gpu_check_rows.py stamp DIR PROBE.json    # DIR/metadata.json gets "accelerator": PROBE
  python scripts/gpu_check_rows.py summary DIR ... [--seconds S]
  python scripts/gpu_check_rows.py table GPU_DIR ... --cpu CPU_DIR ... [--update PAGE.md]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

GPU_START, GPU_END = "<!-- swingbench:gpu:start -->", "<!-- swingbench:gpu:end -->"


def probe(want: str) -> dict:
    """JAX's default backend and its first device, and a float64 sum computed there (the PINNs train
    in float64 under `jax.enable_x64`, as here); the GPU's name and driver from nvidia-smi where
    there is one. SystemExit(3) when the default backend is not `want` ("gpu" or "cpu")."""
    import jax
    import jax.numpy as jnp
    import jaxlib

    device = jax.devices()[0]
    with jax.enable_x64(True):
        total = jnp.arange(4, dtype=jnp.float64).sum()
    info = {"jax_backend": jax.default_backend(), "device_kind": device.device_kind,
            "device_count": jax.device_count(), "float64": str(total.dtype), "jax": jax.__version__,
            "jaxlib": jaxlib.__version__}
    try:
        smi = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=30, check=True).stdout.strip()
        info["nvidia_smi"] = smi.splitlines()[0] if smi else ""
    except (OSError, subprocess.SubprocessError):
        pass
    if info["jax_backend"] != want:
        print(f"gpu_check: JAX {jax.__version__} computes on {info['jax_backend']} ({info['device_kind']}), "
              f"not on a {want}: {json.dumps(info)}", file=sys.stderr)
        raise SystemExit(3)
    if info["float64"] != "float64":
        print(f"gpu_check: float64 is not available on {info['device_kind']}: {json.dumps(info)}", file=sys.stderr)
        raise SystemExit(3)
    return info


def stamp(folder: Path, probe_file: Path) -> None:
    """Add the probe's record to `folder`/metadata.json as "accelerator" (a run that was refused
    before it wrote one is left alone, with a line on stderr)."""
    path = folder / "metadata.json"
    if not path.is_file():
        print(f"gpu_check: no {path} to record the device in", file=sys.stderr)
        return
    meta = json.loads(path.read_text(encoding="utf-8"))
    meta["accelerator"] = json.loads(probe_file.read_text(encoding="utf-8"))
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(meta, indent=2, default=str), encoding="utf-8")
    tmp.replace(path)


def _g(value: float | None, unit: str = "") -> str:
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.3g}{unit}"


def _first(rows: list[dict], suite: str, **match) -> dict | None:
    return next((r for r in rows if r["suite"] == suite and all(r.get(k) == v for k, v in match.items())), None)


def measures(rows: list[dict]) -> dict:
    """One variant's figures from its rows: the fit's status, seconds and iterations; the COI rel.
    L2 of the angles (the scaling suite's, or the accuracy suite's against the reference) and the
    median query times: the scaling suite's grid (4 P1 x 101 times) and single point, or the latency
    suite's first grid and its single point at t1 = 10 s, each with its query's name. Absent: None."""
    from harness.suites.accuracy import COI_DELTA

    fit = _first(rows, "fit") or {}
    out = {"fit_status": fit.get("status", "no fit row"), "fit_s": fit.get("fit_s"),
           "iterations": fit.get("iterations"), "rel_l2": None,
           "grid_s": None, "grid_query": None, "point_s": None, "point_query": None}
    if (row := _first(rows, "scaling")) is not None and "rel_l2" in row:
        out.update(rel_l2=row["rel_l2"], grid_s=row.get("grid_median_s"), point_s=row.get("point_median_s"),
                   grid_query=f"grid {row.get('n_trajectories')}x{row.get('n_times')}",
                   point_query="single point")
    if (row := _first(rows, "accuracy", quantity=COI_DELTA, against="reference")) is not None:
        out["rel_l2"] = row["rel_l2"]
    for kind, key in (("grid", "grid"), ("single point", "point")):
        found = [r for r in rows if r["suite"] == "latency" and r.get("kind") == kind and "median_s" in r]
        if kind == "single point":
            found = [r for r in found if r.get("t1_s") == 10.0]
        if found:
            out[f"{key}_s"], out[f"{key}_query"] = found[0]["median_s"], found[0].get("query")
    return out


def _read(folder: Path) -> list[dict]:
    from harness.store import RowStore

    return RowStore(folder, create=False).read().rows if (folder / "rows.jsonl").is_file() else []


def _run_summary(folder: Path) -> str:
    """A run's part of the summary: its adapter, config and case, the fit's seconds and iterations,
    then for its first variant (the adapter's own query path) the figures of `measures`, and the
    rows not ok."""
    rows = _read(folder)
    if not rows:
        return f"{folder.name}: no rows"
    first = rows[0]
    m = measures([r for r in rows if r.get("variant") == first.get("variant")])
    fit = (f"fit {_g(m['fit_s'], ' s')} ({m['iterations'] if m['iterations'] is not None else '?'} iterations)"
           if str(m["fit_status"]).startswith("ok") else f"fit {m['fit_status']}")
    text = [f"{first.get('solver')} [{first.get('config')}] on {first.get('case')}: {fit}"]
    if m["rel_l2"] is not None:
        text.append(f"rel. L2 {_g(m['rel_l2'])}")
    for key in ("grid", "point"):
        if m[f"{key}_s"] is not None:
            text.append(f"{key} {_g(1e3 * m[f'{key}_s'], ' ms')} ({m[f'{key}_query']})")
    bad = [r for r in rows if not str(r.get("status", "ok")).startswith("ok")]
    if bad:
        text.append(f"{len(bad)} rows not ok ({bad[0].get('status')})")
    return ", ".join(text)


def summary(folders: list[Path], seconds: float | None) -> str:
    """One line: the device the runs computed on, the seconds the check took, and each run's part
    (`_run_summary`)."""
    device = "?"
    for folder in folders:
        meta = folder / "metadata.json"
        if meta.is_file():
            acc = json.loads(meta.read_text(encoding="utf-8")).get("accelerator", {})
            device = f"{acc.get('device_kind', '?')} (jax {acc.get('jax', '?')}, {acc.get('jax_backend', '?')})"
            break
    took = "" if seconds is None else f" in {seconds:.0f} s"
    return f"gpu_check on {device}{took}: " + "; ".join(_run_summary(folder) for folder in folders)


def _where(folder: Path) -> str:
    """Where a run computed: the accelerator's kind where its metadata records one, else the CPU's
    model; with the threads it was given."""
    meta = json.loads((folder / "metadata.json").read_text(encoding="utf-8"))
    acc = meta.get("accelerator")
    device = f"{acc['device_kind']} (JAX {acc['jax']})" if acc else f"CPU: {meta.get('cpu', '?')} (JAX {meta.get('version_jax', '?')})"
    return f"{device}, {meta.get('threads', '?')} threads, at {meta.get('commit', '?')}"


def table(gpu_folders: list[Path], cpu_folders: list[Path]) -> str:
    """A Markdown table: for each GPU run (its seed 0, each query path) the rows of the same adapter,
    config and case in the CPU runs beside it, with `measures`' figures and the fit's seconds per
    optimizer iteration (snapshots and basis included where the fit makes them)."""
    head = ("| case | PINN | query path | where | variant | fit (s) | iterations | s / iteration "
            "| COI rel. L2 | grid (ms) | single point (ms) |\n" + "|---" * 11 + "|\n")
    lines = []
    runs = [(folder, [r for r in _read(folder) if r.get("seed", 0) == 0]) for folder in gpu_folders]
    runs = [(folder, rows) for folder, rows in runs if rows]
    cpu_runs = [(folder, _read(folder)) for folder in cpu_folders]
    keys = list(dict.fromkeys(tuple(rows[0].get(k) for k in ("solver", "config", "case")) for _, rows in runs))
    for solver, config, case in keys:
        key = {"solver": solver, "config": config, "case": case}
        gpu_runs = [(f, rows) for f, rows in runs if all(rows[0].get(k) == v for k, v in key.items())]
        paths = list(dict.fromkeys("query=numba" in str(r.get("variant")) for _, rows in gpu_runs for r in rows))
        for numba in paths:
            for folder, source in gpu_runs + cpu_runs:
                mine = [r for r in source if r.get("seed", 0) == 0 and all(r.get(k) == v for k, v in key.items())
                        and ("query=numba" in str(r.get("variant"))) == numba]
                for variant in dict.fromkeys(r.get("variant") for r in mine):
                    m = measures([r for r in mine if r.get("variant") == variant])
                    per = (m["fit_s"] / m["iterations"] if m["fit_s"] is not None and m["iterations"] else None)
                    shown = ",".join(v for v in str(variant).split(",") if v not in ("query=numba", "device=gpu"))
                    lines.append(
                        f"| {case} | {solver} `{config}` | {'numba' if numba else 'own'} "
                        f"| {_where(folder)} | `{shown}` | {_g(m['fit_s'])} | {m['iterations'] or 'n/a'} | {_g(per)} "
                        f"| {_g(m['rel_l2'])} | {_g(None if m['grid_s'] is None else 1e3 * m['grid_s'])} "
                        f"| {_g(None if m['point_s'] is None else 1e3 * m['point_s'])} |")
    return head + "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="gpu_check_rows.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("probe")
    p.add_argument("--want", choices=["gpu", "cpu"], default="gpu")
    s = sub.add_parser("stamp")
    s.add_argument("folder", type=Path)
    s.add_argument("probe_file", type=Path)
    m = sub.add_parser("summary")
    m.add_argument("folders", type=Path, nargs="+")
    m.add_argument("--seconds", type=float, default=None)
    t = sub.add_parser("table", help="GPU rows beside the CPU rows of the same PINN")
    t.add_argument("folders", type=Path, nargs="+", help="the GPU runs (results/gpu/<run>)")
    t.add_argument("--cpu", type=Path, nargs="+", required=True, help="CPU runs with the same adapter, config, case")
    t.add_argument("--update", type=Path, default=None,
                   help=f"also replace the section of this page between {GPU_START} and {GPU_END}")
    args = parser.parse_args(argv)
    if args.command == "probe":
        print(json.dumps(probe(args.want)))
    elif args.command == "stamp":
        stamp(args.folder, args.probe_file)
    elif args.command == "table":
        block = table(args.folders, args.cpu)
        print(block, end="")
        if args.update is not None:
            from harness.cli.readme import replace_section

            replace_section(args.update, GPU_START, GPU_END, "\n" + block, "gpu_check_rows.py table")
    else:
        print(summary(args.folders, args.seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
