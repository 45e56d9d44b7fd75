# swingbench: `make test` and `make bench` each set up .venv and every dependency from nothing.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
EXTRAS := torch,jax,dask,asv,dev

.PHONY: setup test bench bench-quick lint clean

setup: $(STAMP)

# torch is pinned (torch==2.13.0, CPU build) in pyproject.toml: an unpinned torch pulls GBs of CUDA.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[$(EXTRAS)]"
	touch $@

test: setup
	$(BIN)/python -m pytest -q

bench: setup
	$(BIN)/swingbench run --out results --update-readme README.md

bench-quick: setup
	$(BIN)/swingbench run --quick --out results/quick

lint: setup
	$(BIN)/ruff check harness solvers tests benchmarks

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
