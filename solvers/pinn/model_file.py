"""The PINN model file: `save_model` writes <path>.npz, the flat parameter vector(s) (float64; a
time-marching model's "theta" has one row per window), and <path>.json, the rest; `load_model`
reads them back.

A model may come from a cache another process writes or a file a user copied: load checks it all
(format version, shapes, the weights' and the record's sha256, finite weights, and, with
`check_model_case`, that its networks are those of its config for its case).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from solvers.atomic import write_atomically
from solvers.pinn.architecture import Architecture
from solvers.pinn.config import PinnConfig
from solvers.pinn.problems import PhaseEdges
from systems.cases import Case, Fault, case_record

__all__ = ["FORMAT_VERSION", "CorruptModelError", "check_model_case", "load_model", "save_model",
           "weights_sha256"]

# 2: the .json records the weights' sha256 (version 1 files, without it, still load);
# 3: N machines (tuples in case and architecture, per-machine m, d of an identification) and
#    time-marching models ("windows": the window edges, "theta" one row per window); a fault case's
#    switched model records its case's fault and "windows" {"on": [...], "post": [...]}
FORMAT_VERSION = 3


def _paths(path) -> tuple[Path, Path]:
    path = Path(path)
    if path.suffix in (".npz", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".npz"), path.with_name(path.name + ".json")


class CorruptModelError(ValueError):
    """A saved model that cannot be used as it is: unreadable, incomplete, of another format
    version, inconsistent with itself (its networks not those of its config for its case: see
    `check_model_case`) or with non-finite weights. The message starts with the file."""


def weights_sha256(arrays: Mapping[str, np.ndarray]) -> str:
    """sha256 of named weight arrays: each name, dtype, shape and C-order bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape};".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


_RECORD_FIELDS = ("config", "case", "architecture", "windows", "identification")


def record_sha256(info: Mapping) -> str:
    """sha256 of what a model's .json says it is (config, case, architecture, windows, the
    identification's m, d and architecture), as canonical JSON: `save_model` stores it among the
    weights, so a .json edited after saving (another case's name and data over these weights) no
    longer matches them."""
    text = json.dumps({key: info.get(key) for key in _RECORD_FIELDS}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def save_model(path, *, solver: str, config: PinnConfig, case: Case, arch: Architecture,
               theta: np.ndarray, identification: dict | None = None,
               windows: np.ndarray | PhaseEdges | None = None) -> tuple[Path, Path]:
    """Write the weights to `<path>.npz` (key "theta": the flat float64 vector in
    `Architecture.shapes` order, or for a time-marching model with window edges `windows` (W + 1,)
    s one such row per window, (W, n_params)) and config, case, architecture, the window edges, the
    saving backend, the last identification (m, d (n,), its architecture and parameters in the .npz
    as "id_theta") and the `weights_sha256` of all the .npz arrays (every window's included) to
    `<path>.json`, each file atomically. Returns the two paths."""
    npz, meta = _paths(path)
    arrays = {"theta": np.asarray(theta, np.float64)}
    info = None
    if identification is not None:
        arrays["id_theta"] = np.asarray(identification["theta"], np.float64)
        info = {"m": np.atleast_1d(np.asarray(identification["m"], np.float64)).tolist(),
                "d": np.atleast_1d(np.asarray(identification["d"], np.float64)).tolist(),
                "architecture": identification["arch"].to_json()}
    record = {"config": config.to_json(), "case": case_record(case), "architecture": arch.to_json(),
              "windows": _windows_json(windows),
              "identification": info}
    arrays["record_sha256"] = np.frombuffer(record_sha256(record).encode(), np.uint8)
    text = json.dumps({
        "format": "swingbench-pinn", "version": FORMAT_VERSION, "saved_by": solver, **record,
        "weights_sha256": weights_sha256(arrays),
    }, indent=2)
    write_atomically(npz, lambda fh: np.savez(fh, **arrays))
    write_atomically(meta, lambda fh: fh.write(text.encode()))
    return npz, meta


def _windows_json(windows: np.ndarray | PhaseEdges | None) -> list | dict | None:
    """The window edges as JSON: a list (s), {"on": [...], "post": [...], "pieces": [...]} for
    `PhaseEdges`, or None."""
    if isinstance(windows, PhaseEdges):
        return {"on": windows.on.tolist(), "post": windows.post.tolist(), "pieces": windows.pieces.tolist()}
    return None if windows is None else np.asarray(windows, np.float64).tolist()


def _case_from_json(data: dict) -> Case:
    """The `Case` of a `case_record` read back from JSON (its fault, when it has one, a dict)."""
    fault = data.get("fault")
    return Case(**{**data, **({} if fault is None else {"fault": Fault(**fault)})})


def _arch_from_json(data: dict) -> Architecture:
    return Architecture(**{**data, "sizes": tuple(data["sizes"])})


def _read_info(meta: Path) -> dict:
    if not meta.is_file():
        raise FileNotFoundError(f"{meta}: no such model file")
    try:
        info = json.loads(meta.read_bytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CorruptModelError(f"{meta}: not valid JSON (truncated or overwritten?): {exc}") from exc
    if not isinstance(info, dict) or info.get("format") != "swingbench-pinn":
        raise CorruptModelError(f"{meta}: not a swingbench PINN model")
    if info.get("version") not in range(1, FORMAT_VERSION + 1):
        raise CorruptModelError(f"{meta}: format version {info.get('version')!r}, this code reads 1 to "
                                f"{FORMAT_VERSION}")
    if info["version"] >= 2 and not isinstance(info.get("weights_sha256"), str):
        raise CorruptModelError(f"{meta}: no weights_sha256 (format version {info['version']} records one)")
    return info


def _read_arrays(npz: Path) -> dict[str, np.ndarray]:
    if not npz.is_file():
        raise FileNotFoundError(f"{npz}: no such model file")
    try:
        data = np.load(npz)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise CorruptModelError(f"{npz}: not an .npz archive")
        with data:
            return {name: data[name].copy() for name in data.files}
    except CorruptModelError:
        raise
    except Exception as exc:  # zipfile, zlib and numpy each raise their own on a damaged file
        raise CorruptModelError(f"{npz}: unreadable (truncated or overwritten?): "
                                f"{type(exc).__name__}: {exc}") from exc


def _check_weights(npz: Path, name: str, array: np.ndarray | None, arch: Architecture,
                   rows: int | None = None) -> np.ndarray:
    """`array` if it is float64 of shape (n_params,), or (rows, n_params) for `rows` windows."""
    if array is None:
        raise CorruptModelError(f"{npz}: no array {name!r}")
    shape = (arch.n_params,) if rows is None else (rows, arch.n_params)
    if array.dtype != np.float64 or array.shape != shape:
        raise CorruptModelError(f"{npz}: {name!r} is {array.dtype} of shape {array.shape}, the "
                                f"architecture needs float64 of shape {shape}")
    return array


def _edges(meta: Path, value, case: Case) -> np.ndarray | PhaseEdges | None:
    """The window edges of a time-marching model, checked: increasing from 0 to t_final; for a
    fault case's switched model (a dict) the `PhaseEdges`, from 0 to p1_max, from 0 to
    t_final - p1_min and the pieces from p1_min to p1_max."""
    if value is None:
        return None
    if isinstance(value, dict):
        if set(value) != {"on", "post", "pieces"}:
            raise CorruptModelError(f"{meta}: windows {value!r} are neither edges nor the phases 'on', 'post' "
                                    "and 'pieces'")
        return PhaseEdges(_span(meta, value["on"], 0.0, case.p1_max, "fault-on windows"),
                          _span(meta, value["post"], 0.0, case.t_final - case.p1_min, "post-fault windows"),
                          _span(meta, value["pieces"], case.p1_min, case.p1_max, "pieces of clearing times"))
    return _span(meta, value, 0.0, case.t_final, "windows")


def _span(meta: Path, value, start: float, end: float, what: str) -> np.ndarray:
    """`value` as edges, checked: increasing from `start` to `end` (s)."""
    edges = np.asarray(value, np.float64)
    ok = (edges.ndim == 1 and edges.size >= 2 and np.isfinite(edges).all() and edges[0] == start
          and edges[-1] == end and (np.diff(edges) > 0).all())
    if not ok:
        raise CorruptModelError(f"{meta}: {what} {value!r} are not edges from {start} to {end} s")
    return edges


def _machine_values(meta: Path, ident: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The identified m and d (n,) of the .json (numbers of format versions 1 and 2: one machine)."""
    values = []
    for name in ("m", "d"):
        value = ident.get(name)
        items = value if isinstance(value, list) else [value]
        if len(items) != n or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                      and np.isfinite(v) for v in items):
            raise CorruptModelError(f"{meta}: identification m = {ident.get('m')!r}, d = {ident.get('d')!r}, "
                                    f"not {n} finite numbers each")
        values.append(np.array(items, np.float64))
    return values[0], values[1]


def _short(values) -> str:
    """A tuple or number for a one-line message (floats in full: they differ in any digit), at most
    6 entries of a long tuple."""
    if isinstance(values, tuple):
        text = ", ".join(map(repr, values[:6]))
        return f"({text}{', ...' if len(values) > 6 else ''}{',' if len(values) == 1 else ''})"
    return repr(values)


# The fields of an architecture a message names, under its label (the machine count is checked first)
_ARCH_FIELDS = (("layer sizes", ("sizes",)), ("t range (s)", ("t_lo", "t_hi")),
                ("P1 range (p.u.)", ("p_lo", "p_hi")), ("hard_ic", ("hard_ic",)),
                ("initial angles delta0 (rad)", ("delta0",)), ("initial speeds omega0 (rad/s)", ("omega0",)),
                ("extra parameters", ("n_extra",)))


def _arch_differences(arch: Architecture, expected: Architecture) -> list[str]:
    """'label got, expected want' for each field of `arch` that differs from `expected`."""
    out = []
    for label, fields in _ARCH_FIELDS:
        got, want = ([getattr(a, name) for name in fields] for a in (arch, expected))
        if got != want:
            got, want = (values[0] if len(fields) == 1 else tuple(values) for values in (got, want))
            out.append(f"{label} {_short(got)}, expected {_short(want)}")
    return out


def check_model_case(record: Mapping, case: Case, file) -> None:
    """Raise `CorruptModelError` starting with `file` unless the networks of `record` (what
    `load_model` returns) are those its config makes for `case`: the forward architecture equal to
    `Architecture.of(config, case)` (machines, layers, the t and P1 ranges it normalises over, the
    initial state built into its output), time-marching windows no longer than the window network's
    t range, and an identification network for case.n machines (its m, d of that length), of the
    config's layers and identification horizon, starting from the case's initial state, over a P1
    range that covers the case's. The weights' shapes are checked against the architecture by
    `load_model`. A few comparisons of short tuples: cheap."""
    config, arch, windows = record["config"], record["arch"], record["windows"]
    if arch.machines != case.n:
        raise CorruptModelError(f"{file}: trained for {arch.machines} machine{'s' * (arch.machines != 1)}, "
                                f"case {case.name} has {case.n}")
    problems = _arch_differences(arch, Architecture.of(config, case))
    spans = [] if windows is None else [windows.on, windows.post] if isinstance(windows, PhaseEdges) else [windows]
    longest = max((float(np.diff(edges).max()) for edges in spans), default=None)
    if longest is not None and longest > arch.t_hi * (1 + 1e-9):  # `window_edges`' last window may overrun by less
        problems.append(f"windows up to {longest!r} s long, the window network covers {arch.t_hi!r} s")
    ident = record["identification"]
    if ident is not None:
        id_arch = ident["arch"]
        if id_arch.machines != case.n or ident["m"].shape != (case.n,) or ident["d"].shape != (case.n,):
            raise CorruptModelError(f"{file}: identification of {ident['m'].size} machine"
                                    f"{'s' * (ident['m'].size != 1)} (m and d), case {case.name} has {case.n}")
        # its P1 range is the case's and the observations' together (`identification_p_range`)
        expected = Architecture.of(config, case, identification=True, p_range=(id_arch.p_lo, id_arch.p_hi))
        problems += [f"identification {text}" for text in _arch_differences(id_arch, expected)]
        if id_arch.p_lo > case.p1_min or id_arch.p_hi < case.p1_max:
            problems.append(f"identification P1 range ({id_arch.p_lo!r}, {id_arch.p_hi!r}) p.u. does not "
                            f"cover the case's ({case.p1_min!r}, {case.p1_max!r})")
    if problems:
        raise CorruptModelError(f"{file}: not the network of its config for case {case.name}: "
                                + "; ".join(problems))


def load_model(path) -> dict:
    """Read what `save_model` wrote: a dict with config (PinnConfig), case (Case), arch
    (Architecture), theta (float64 (n_params,), or (W, n_params) for a time-marching model),
    windows (None, the window edges (W + 1,) s, or a switched model's `PhaseEdges`), identification (None or dict m, d (n,), arch,
    theta), saved_by. Raises FileNotFoundError for a missing file and `CorruptModelError` for one
    that is unreadable, of another format version, incomplete, of the wrong shapes, not the weights
    its .json records (`weights_sha256`, format versions 2 and 3: every array, each window's
    included), non-finite, or whose networks are not those of its config for the case it records
    (`check_model_case`), or whose .json differs from the record saved among the weights
    (`record_sha256`; files saved before it was stored are checked by `check_model_case` alone);
    each message starts with the file."""
    npz, meta = _paths(path)
    info = _read_info(meta)
    arrays = _read_arrays(npz)
    try:
        arch = _arch_from_json(info["architecture"])
        config, case = PinnConfig(**info["config"]), _case_from_json(info["case"])
        ident = info.get("identification")
        id_arch = None if ident is None else _arch_from_json(ident["architecture"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptModelError(f"{meta}: missing or bad field: {type(exc).__name__}: {exc}") from exc
    windows = _edges(meta, info.get("windows"), case)
    if (windows is None) != (config.window is None) or isinstance(windows, PhaseEdges) != config.phases:
        raise CorruptModelError(f"{meta}: config window = {config.window!r}, phases = {config.phases!r} but "
                                f"windows = {info.get('windows')!r}")
    rows = None if windows is None else windows.count if isinstance(windows, PhaseEdges) else windows.size - 1
    theta = _check_weights(npz, "theta", arrays.get("theta"), arch, rows)
    identification = None
    if ident is not None:
        m, d = _machine_values(meta, ident, id_arch.machines)
        identification = {"m": m, "d": d, "arch": id_arch,
                          "theta": _check_weights(npz, "id_theta", arrays.get("id_theta"), id_arch)}
    if "weights_sha256" in info and weights_sha256(arrays) != info["weights_sha256"]:
        raise CorruptModelError(f"{npz}: the weights' sha256 is not the one {meta.name} records "
                                "(another model's file, or a damaged one)")
    for name, array in [("theta", theta), *([("id_theta", identification["theta"])] if identification else [])]:
        if not np.isfinite(array).all():
            raise CorruptModelError(f"{npz}: {name!r} has {int(array.size - np.isfinite(array).sum())} "
                                    "non-finite weights")
    record = {"config": config, "case": case, "arch": arch, "theta": theta, "windows": windows,
              "identification": identification, "saved_by": info.get("saved_by")}
    check_model_case(record, case, meta)  # first: its message names what differs
    saved = arrays.get("record_sha256")  # files saved before it was stored have none
    if saved is not None and saved.tobytes().decode(errors="replace") != record_sha256(info):
        raise CorruptModelError(f"{meta}: its config, case or architecture is not what was saved with "
                                f"{npz.name} (the .json was edited after saving)")
    return record
