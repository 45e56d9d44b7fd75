"""The Python steps of scripts/gpu_check.sh: where JAX computes, that device in a run's metadata,
and the check's one-line summary from the runs' rows.

  python scripts/gpu_check_rows.py probe --want gpu        # JSON on stdout; exit 3 if JAX has no such backend
  python scripts/gpu_check_rows.py stamp DIR PROBE.json    # DIR/metadata.json gets "accelerator": PROBE
  python scripts/gpu_check_rows.py summary DIR ... [--seconds S]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path


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


def _fit(rows: list[dict]) -> str:
    fits = [r for r in rows if r["suite"] == "fit"]
    if not fits:
        return "no fit row"
    fit = fits[0]
    if not str(fit.get("status", "ok")).startswith("ok"):
        return f"fit {fit.get('status')}"
    return f"fit {_g(fit.get('fit_s'), ' s')} ({fit.get('iterations', '?')} iterations)"


def _first(rows: list[dict], suite: str, **match) -> dict | None:
    return next((r for r in rows if r["suite"] == suite and all(r.get(k) == v for k, v in match.items())), None)


def _run_summary(folder: Path) -> str:
    """A run's part of the summary: its adapter, config and case, the fit's seconds and iterations,
    then for its first variant (the adapter's own query path) the COI rel. L2 of the angles and the
    median query times: the scaling grid (4 P1 x 101 times) and single point, or the accuracy suite's
    100 x 201 grid, the latency suite's grid and single point at t1 = 10 s; and the rows not ok."""
    from harness.store import RowStore
    from harness.suites.accuracy import COI_DELTA

    rows = RowStore(folder, create=False).read().rows if (folder / "rows.jsonl").is_file() else []
    if not rows:
        return f"{folder.name}: no rows"
    first = rows[0]
    own = [r for r in rows if r.get("variant") == first.get("variant")]
    text = [f"{first.get('solver')} [{first.get('config')}] on {first.get('case')}: {_fit(own)}"]
    if (row := _first(own, "scaling")) is not None and "rel_l2" in row:
        text.append(f"rel. L2 {_g(row['rel_l2'])}, grid {_g(1e3 * row['grid_median_s'], ' ms')}, "
                    f"point {_g(1e3 * row['point_median_s'], ' ms')}")
    if (row := _first(own, "accuracy", quantity=COI_DELTA, against="reference")) is not None:
        text.append(f"rel. L2 {_g(row['rel_l2'])}")
    for kind, label in (("grid", "grid"), ("single point", "point")):
        found = [r for r in own if r["suite"] == "latency" and r.get("kind") == kind and "median_s" in r]
        if kind == "single point":
            found = [r for r in found if r.get("t1_s") == 10.0]
        if found:
            text.append(f"{label} {_g(1e3 * found[0]['median_s'], ' ms')} ({found[0].get('query')})")
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
    args = parser.parse_args(argv)
    if args.command == "probe":
        print(json.dumps(probe(args.want)))
    elif args.command == "stamp":
        stamp(args.folder, args.probe_file)
    else:
        print(summary(args.folders, args.seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
