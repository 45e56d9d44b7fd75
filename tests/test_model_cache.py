"""The model cache and the PINN model files: a hit is the model and training cost that were stored;
anything wrong with an entry is said in one line, moved aside and retrained, never used."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import THREE_MACHINES

import solvers
from harness import model_cache
from harness.model_cache import cache_key, fit_or_load, store_cached
from harness.settings import QUICK
from solvers import make_solver
from solvers.pinn.architecture import Architecture, init_theta
from solvers.pinn.config import PinnConfig
from solvers.pinn.model_file import CorruptModelError, load_model, save_model, weights_sha256
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE

# torch.func's first jvp registers decompositions through torch.jit.script, deprecated in torch 2.13
pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE = SMIB_INFERENCE
# torch: after the first, a fit of this network takes ~30 ms
TINY = {"hidden_layers": 1, "width": 4, "n_u": 10, "n_f": 50, "max_iterations": 3, "threads": 1, "progress": False}
GRID = (np.linspace(0.0, CASE.t_final, 11), np.linspace(CASE.p1_min, CASE.p1_max, 3))
PREFIX = "[swingbench] model cache: "


def _solver(**options):
    pytest.importorskip("torch")
    return make_solver("torch-pinn", CASE, **{**TINY, **options})


class Entry:
    """One stored cache entry: the solver that trained it, its report, settings and file stem."""

    def __init__(self, cache_dir: Path) -> None:
        self.settings = replace(QUICK, cache_dir=cache_dir, retrain=False)
        self.solver = _solver()
        self.report = fit_or_load(self.solver, self.settings)
        self.base = cache_dir / cache_key(self.solver)
        self.npz, self.json, self.fit = (self.base.with_name(self.base.name + s) for s in (".npz", ".json", ".fit.json"))
        self.names = sorted(p.name for p in cache_dir.iterdir())


@pytest.fixture
def entry(tmp_path, capsys):
    stored = Entry(tmp_path / "models")
    capsys.readouterr()
    return stored


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _other_weights(entry: Entry) -> None:
    with open(entry.npz, "wb") as fh:  # well-formed, another model's weights
        np.savez(fh, theta=entry.solver.theta + 1e-3)


def _other_weights_recorded(entry: Entry) -> None:
    """Other weights, and a .fit.json re-recorded over them: only the .json's weights hash is left."""
    _other_weights(entry)
    record = json.loads(entry.fit.read_text())
    record["files"][entry.npz.name] = model_cache._sha256(entry.npz)
    entry.fit.write_text(json.dumps(record))


def _nan_weights(entry: Entry) -> None:
    """Stored by store_cached from NaN weights: every hash matches, the weights are not finite."""
    entry.solver.theta = np.full_like(entry.solver.theta, np.nan)
    store_cached(entry.solver, entry.report, entry.settings.cache_dir)


def _renamed(entry: Entry) -> None:
    """A whole, consistent entry of other options (seed 1) under this entry's name."""
    other = _solver(seed=1)
    other.fit()
    store_cached(other, entry.report, entry.settings.cache_dir)
    key = cache_key(other)
    for path in entry.base.parent.glob(f"{key}.*"):
        path.replace(path.with_name(entry.base.name + path.name[len(key):]))


def _other_case_recorded(entry: Entry) -> None:
    """The network of another case's data (SMIB_IDENTIFICATION's P1 range, the same shapes) in the
    .json, the .fit.json re-recorded over it: only the model's own check is left."""
    info = json.loads(entry.json.read_text())
    other = Architecture.of(entry.solver.pinn_config, SMIB_IDENTIFICATION)
    entry.json.write_text(json.dumps({**info, "architecture": other.to_json()}))
    record = json.loads(entry.fit.read_text())
    record["files"][entry.json.name] = model_cache._sha256(entry.json)
    entry.fit.write_text(json.dumps(record))


GARBAGE = bytes(range(256)) * 4
# damage(entry) and (the file the line names, a word it says)
DAMAGES = {
    "truncated npz": (lambda e: _truncate(e.npz), "npz", "sha256"),
    "truncated json": (lambda e: _truncate(e.json), "json", "sha256"),
    "truncated fit.json": (lambda e: _truncate(e.fit), "fit", "unreadable"),
    "garbage npz": (lambda e: e.npz.write_bytes(GARBAGE), "npz", "sha256"),
    "garbage fit.json": (lambda e: e.fit.write_bytes(GARBAGE), "fit", "unreadable"),
    "other weights": (_other_weights, "npz", "sha256"),
    "other weights, fit.json re-recorded": (_other_weights_recorded, "npz", "sha256"),
    "NaN weights": (_nan_weights, "npz", "non-finite"),
    "missing fit.json": (lambda e: e.fit.unlink(), "fit", "missing"),
    "missing npz": (lambda e: e.npz.unlink(), "npz", "missing"),
    "entry of other options": (_renamed, "fit", "records the entry"),
    "network of another case, fit.json re-recorded": (_other_case_recorded, "json", "P1 range"),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_bad_entry_is_said_moved_aside_and_retrained(entry, damage, capsys):
    apply, file, word = DAMAGES[damage]
    apply(entry)
    present = sorted(p.name for p in entry.settings.cache_dir.iterdir())
    capsys.readouterr()
    solver = _solver()
    report = fit_or_load(solver, entry.settings)
    lines = capsys.readouterr().err.splitlines()
    corrupt = entry.settings.cache_dir / "corrupt"
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{PREFIX}{getattr(entry, file)}: ") and word in lines[0]
    assert lines[0].endswith(f"; moved aside to {corrupt}, retraining")
    assert solver.fitted and "cached model" not in report.message
    moved = [p.name for p in corrupt.iterdir()]
    assert len(moved) == len(present) and all(any(m.endswith(f"-{n}") for m in moved) for n in present)
    # the retrained entry loads cleanly, with the model just trained
    again = _solver()
    assert fit_or_load(again, entry.settings) == report._replace(message=f"{report.message} (cached model)")
    assert capsys.readouterr().err == ""
    np.testing.assert_array_equal(again.solve(*GRID).delta, solver.solve(*GRID).delta)


def test_a_hit_is_the_recorded_report_and_the_same_model(entry, capsys):
    solver = _solver(progress=None)  # a query-only option: the same entry
    report = fit_or_load(solver, entry.settings)
    assert report == entry.report._replace(message=f"{entry.report.message} (cached model)")
    assert solver.fitted and capsys.readouterr().err == ""
    a, b = entry.solver.solve(*GRID), solver.solve(*GRID)
    np.testing.assert_array_equal(b.delta, a.delta)
    np.testing.assert_array_equal(b.omega, a.omega)
    assert sorted(p.name for p in entry.settings.cache_dir.iterdir()) == entry.names  # nothing moved


def test_a_ctrl_c_while_an_entry_loads_leaves_it_in_place(entry, monkeypatch):
    """Inside compiled code the KeyboardInterrupt comes wrapped (numba: a SystemError from it)."""
    solver = _solver()

    def interrupted(base):
        raise SystemError("returned a result with an exception set") from KeyboardInterrupt()

    monkeypatch.setattr(solver, "load", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fit_or_load(solver, entry.settings)
    assert sorted(p.name for p in entry.settings.cache_dir.iterdir()) == entry.names  # nothing moved


def test_a_store_marks_the_entry_complete_last(entry, monkeypatch):
    def fail(path):
        raise OSError("disk full")

    monkeypatch.setattr(entry.solver, "save", fail)
    with pytest.raises(OSError):
        store_cached(entry.solver, entry.report, entry.settings.cache_dir)
    assert not entry.fit.exists()  # a store that did not finish leaves no complete entry


def _other(value):
    if isinstance(value, bool):
        return not value
    if isinstance(value, (int, float)):
        return value * 2 + 1
    if value is None:
        return 1.5
    return f"{value}-other"


def test_the_key_covers_every_training_option_and_no_query_only_one(monkeypatch):
    base = _solver()
    key = cache_key(base)
    query_only = type(base).QUERY_OPTIONS  # declared by the adapter: threads, progress, query
    assert query_only and set(query_only) <= set(base.options)
    for name, value in base.options.items():
        other = _solver()
        other.options[name] = _other(value)
        assert (cache_key(other) == key) == (name in query_only), name
    assert cache_key(make_solver("torch-pinn", SMIB_IDENTIFICATION, **TINY)) != key
    assert cache_key(make_solver("torch-pinn", CASE, "paper", **TINY)) != key
    for name, fake in [("CACHE_FORMAT", model_cache.CACHE_FORMAT + 1), ("code_version", lambda: "other"),
                       ("library_versions", lambda libs: dict.fromkeys(libs, "0"))]:
        with monkeypatch.context() as patch:
            patch.setattr(model_cache, name, fake)
            assert cache_key(base) != key, name
    assert model_cache.Persistable(base)


# ---- the PINN model files on their own -----------------------------------------------------------


@pytest.fixture
def saved(tmp_path):
    """A model saved by `save_model` (random weights, with an identification): its two paths."""
    config = PinnConfig(hidden_layers=1, width=4, id_hidden_layers=1, id_width=3)
    arch, id_arch = Architecture.of(config, CASE), Architecture.of(config, CASE, identification=True)
    ident = {"m": 0.3, "d": 0.1, "arch": id_arch, "theta": init_theta(id_arch, 1)}
    return save_model(tmp_path / "model", solver="test", config=config, case=CASE, arch=arch,
                           theta=init_theta(arch, 0), identification=ident)


def _edit_json(path: Path, **changes) -> None:
    info = json.loads(path.read_text())
    path.write_text(json.dumps({**info, **changes}))


def _savez(path: Path, **arrays) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as data:
        return dict(data)


def _npy(path: Path) -> None:
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(3))


def _v1(meta: Path) -> None:
    info = json.loads(meta.read_text())
    info.pop("weights_sha256")
    meta.write_text(json.dumps({**info, "version": 1}))


def _nan(npz: Path, meta: Path, version: int) -> None:
    arrays = _arrays(npz)
    arrays["theta"][3] = np.nan
    _savez(npz, **arrays)
    if version == 1:
        _v1(meta)
    else:
        _edit_json(meta, weights_sha256=weights_sha256(arrays))


# damage(npz, meta) and (the file the message starts with, a word it says)
FILE_DAMAGES = {
    "truncated npz": (lambda n, m: _truncate(n), 0, "unreadable"),
    "garbage npz": (lambda n, m: n.write_bytes(GARBAGE), 0, "unreadable"),
    "npy, not npz": (lambda n, m: _npy(n), 0, "not an .npz"),
    "truncated json": (lambda n, m: _truncate(m), 1, "JSON"),
    "garbage json": (lambda n, m: m.write_bytes(GARBAGE), 1, "JSON"),
    "other format version": (lambda n, m: _edit_json(m, version=99), 1, "version"),
    "no weights hash": (lambda n, m: _edit_json(m, weights_sha256=None), 1, "weights_sha256"),
    "missing field": (lambda n, m: _edit_json(m, architecture=None), 1, "field"),
    "missing theta": (lambda n, m: _savez(n, id_theta=_arrays(n)["id_theta"]), 0, "'theta'"),
    "wrong shape": (lambda n, m: _savez(n, theta=np.zeros(5), id_theta=_arrays(n)["id_theta"]), 0, "shape"),
    "other weights": (lambda n, m: _savez(n, **{k: v + 1e-3 for k, v in _arrays(n).items()}), 0, "sha256"),
    "NaN weights, hash recomputed": (lambda n, m: _nan(n, m, 2), 0, "non-finite"),
    "NaN weights, version 1 (no hash)": (lambda n, m: _nan(n, m, 1), 0, "non-finite"),
}


@pytest.mark.parametrize("damage", list(FILE_DAMAGES))
def test_load_model_refuses_a_bad_file_and_names_it(saved, damage):
    apply, which, word = FILE_DAMAGES[damage]
    apply(*saved)
    with pytest.raises(CorruptModelError) as info:
        load_model(saved[0].with_suffix(""))
    assert str(info.value).startswith(f"{saved[which]}: ") and word in str(info.value)


def test_load_model_reads_what_save_model_wrote_and_version_1_files(saved):
    npz, meta = saved
    first = load_model(npz)
    assert first["case"] == CASE and first["identification"]["m"] == 0.3
    assert json.loads(meta.read_text())["weights_sha256"] == weights_sha256(_arrays(npz))
    _v1(meta)  # written before the weights' hash
    np.testing.assert_array_equal(load_model(npz)["theta"], first["theta"])
    npz.unlink()
    with pytest.raises(FileNotFoundError, match="no such model file") as info:
        load_model(npz)
    assert str(info.value).startswith(str(npz))


def _save_mismatched(tmp_path: Path, what: str) -> tuple[Path, Path]:
    """A model whose networks are not those of its config for the case it records."""
    three = THREE_MACHINES
    config = PinnConfig(hidden_layers=1, width=4, id_hidden_layers=1, id_width=3)
    arch = Architecture.of(config, three)
    theta, windows, ident = init_theta(arch, 0), None, None
    if what == "identification":  # a SMIB's identification beside a three-machine network
        id_arch = Architecture.of(config, CASE, identification=True)
        ident = {"m": 0.3, "d": 0.1, "arch": id_arch, "theta": init_theta(id_arch, 1)}
    else:  # windows of 5 s for a network of 2.5 s windows
        config = replace(config, window=2.5)
        arch = Architecture.of(config, three)
        windows = np.array([0.0, 5.0, 10.0])
        theta = np.stack([init_theta(arch, 0), init_theta(arch, 0, window=1)])
    return save_model(tmp_path / "model", solver="test", config=config, case=three, arch=arch,
                           theta=theta, windows=windows, identification=ident)


@pytest.mark.parametrize("what, says", [
    ("identification", "identification of 1 machine (m and d), case three-lossy has 3"),
    ("windows", "windows up to 5.0 s long, the window network covers 2.5 s"),
])
def test_load_model_refuses_networks_not_of_the_case_it_records(tmp_path, what, says):
    _, meta = _save_mismatched(tmp_path, what)
    with pytest.raises(CorruptModelError) as info:
        load_model(meta)
    assert str(info.value).startswith(f"{meta}: ") and says in str(info.value)


def test_save_model_replaces_a_file_whole_or_not_at_all(saved, monkeypatch):
    npz, meta = saved
    before = npz.read_bytes(), meta.read_bytes()
    loaded = load_model(npz)

    def fail(file, **arrays):
        file.write(b"PK half a file")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", fail)
    with pytest.raises(OSError, match="disk full"):
        save_model(npz, solver="test", config=loaded["config"], case=CASE, arch=loaded["arch"],
                        theta=loaded["theta"])
    assert (npz.read_bytes(), meta.read_bytes()) == before
    assert sorted(p.name for p in npz.parent.iterdir()) == sorted([npz.name, meta.name])  # no temporary left


def test_the_compiled_query_path_refuses_a_bad_file(saved):
    pytest.importorskip("numba")
    from solvers.pinn.compiled import compiled_model

    _truncate(saved[0])
    with pytest.raises(CorruptModelError, match="unreadable") as info:
        compiled_model(saved[0].with_suffix(""))
    assert str(info.value).startswith(str(saved[0]))


def test_model_cache_key_covers_training_and_ignores_how_a_model_is_queried():
    from harness.model_cache import TRAINING_LIBRARIES, cache_key
    from harness.versions import library_versions

    pytest.importorskip("jax")
    base = solvers.make_solver("jax-pinn", SMIB_INFERENCE)
    same = [solvers.make_solver("jax-pinn", SMIB_INFERENCE, **{key: value})
            for key, value in (("query", "numba"), ("threads", 1), ("progress", False))]
    assert {cache_key(s) for s in same} == {cache_key(base)}
    other = [solvers.make_solver("jax-pinn", SMIB_INFERENCE, seed=1),
             solvers.make_solver("jax-pinn", SMIB_INFERENCE, max_iterations=10),
             solvers.make_solver("jax-pinn", SMIB_INFERENCE.with_params(0.3, 0.1))]
    assert len({cache_key(s) for s in other} | {cache_key(base)}) == 4
    assert set(library_versions(TRAINING_LIBRARIES)) >= {"numpy", "scipy", "jax"}
