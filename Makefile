# swingbench: `make test` and `make bench` each set up .venv and every dependency from nothing.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
EXTRAS := torch,jax,diffrax,numba,matpower,dask,asv,crosscheck,dev

.PHONY: setup test test-slow bench bench-quick lint clean

setup: $(STAMP)

# torch is pinned (torch==2.13.0, CPU build) in pyproject.toml: an unpinned torch pulls GBs of CUDA.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[$(EXTRAS)]"
	$(BIN)/python -m solvers.numba_cache  # numba kernels into numba's on-disk cache (~30 s, once)
	touch $@

# two workers, one test file each at a time (module fixtures are built once). `make test` leaves out
# the tests marked slow (end-to-end runs through the CLI, cross-checks against ANDES, training to an
# accuracy, JIT-heavy adapter checks); `make test-slow` runs just those, and CI runs both
test: setup
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not slow"

test-slow: setup
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m slow

# --overwrite: results/ holds the last run's rows; they are renamed to results/rows.<UTC time>.jsonl
# (and metadata.<UTC time>.json), which git ignores: delete them once the new run is committed
bench: setup
	$(BIN)/swingbench run --overwrite --out results --update-readme README.md

bench-quick: setup
	$(BIN)/swingbench run --quick --overwrite --out results/quick

# the layering (the import-linter contracts in pyproject.toml), no import circle outside systems/,
# ruff over every package and the tests, mypy on the files pyproject.toml names. The import graph
# takes well under a second to build: no cache folder for it.
lint: setup
	$(BIN)/lint-imports --no-logo --no-cache
	$(BIN)/python .ci/import_cycles.py
	$(BIN)/ruff check systems solvers harness benchmarks tests .ci
	$(BIN)/mypy

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis

# asv benchmarks (benchmarks/, asv.conf.json) in the project's own .venv (`-E existing`), with this
# checkout first on the import path (ASV_PYTHONPATH; asv drops PYTHONPATH), so a worktree that shares
# another checkout's .venv measures its own code. `make asv` keeps its results in benchmarks/results/
# (committed: the history) under the HEAD commit; `make asv-publish` renders that history to
# .asv/html, which `make docs` serves at site/asv/. `make asv-compare` is the regression gate
# between BASE and HEAD (scripts/asv_compare.py).
# BENCH=REGEX (asv --bench; it matches "name(param, ...)" too) runs a subset of the benchmarks.
# `make asv-quick` runs each benchmark once with small budgets, saves nothing, and fails (asv exits 2)
# if any benchmark fails.
.PHONY: asv asv-quick asv-compare asv-publish
ASV_RUN = ASV_PYTHONPATH=$(CURDIR) $(BIN)/asv run --environment existing:$(abspath $(BIN))/python --show-stderr
ASV_BENCH = $(if $(BENCH),--bench '$(BENCH)')
# the commit `make asv-compare` measures HEAD against: origin/main where there is one, else main
BASE ?= $(shell git rev-parse --verify -q origin/main > /dev/null && echo origin/main || echo main)

asv: setup
	$(BIN)/asv machine --yes > /dev/null
	$(ASV_RUN) --set-commit-hash $$(git rev-parse HEAD) --durations 10 $(ASV_BENCH)

asv-quick: setup
	$(BIN)/asv machine --yes > /dev/null
	SWINGBENCH_ASV_QUICK=1 $(ASV_RUN) --quick --durations 5 $(ASV_BENCH)

# exit 1 when a benchmark got slower than 1.1x beyond asv's statistics, or started failing
asv-compare: setup
	$(BIN)/asv machine --yes > /dev/null
	$(BIN)/python scripts/asv_compare.py --base $(BASE) --factor 1.1 $(ASV_BENCH)

asv-publish: setup
	$(BIN)/asv publish

# the documentation site (mkdocs.yml, docs/) into site/; --strict: any warning (a broken link, an
# anchor that is not there) fails the build. NO_MKDOCS_2_WARNING: without Material's end-of-life banner
.PHONY: docs
EXTRAS := $(EXTRAS),docs

# asv-publish first: the site serves the asv history of .asv/html at asv/ (scripts/mkdocs_extra_files.py)
docs: setup asv-publish
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

# the GPU check (scripts/gpu_check.sh; docs/scaling.md): both JAX PINNs on a GPU, rows into results/gpu/.
# No setup: the GPU machine has no .venv (the script takes the project from this checkout and carried
# wheels, scripts/gpu_wheels.sh). CI never runs it.
.PHONY: gpu-check
gpu-check:
	PYTHON=$(PYTHON) bash scripts/gpu_check.sh
