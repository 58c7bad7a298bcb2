# Two entry points: `make demo` and `make test`. Each creates .venv when missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

# Small dense matrices: one BLAS thread each is fastest, and keeps parallel runs from
# oversubscribing the cores.
export OMP_NUM_THREADS ?= 1
export OPENBLAS_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.PHONY: demo test lint bench clean docs

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/forcecal demo demo-output

# The suite runs on two workers (pytest-xdist), each test file on one, so that a file's
# fixtures are made once and the guide's commands (tests/test_docs.py) run in their order.
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# HTML documentation into docs/_build/html (Sphinx, MyST, autodoc); the docs extra is installed
# once, after which the build needs no network.
DOCS_STAMP := $(VENV)/.docs-installed

$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(BIN)/python -m sphinx -b html -q docs docs/_build/html

bench: $(STAMP)
	$(BIN)/python benchmarks/simulator.py
	$(BIN)/python benchmarks/accuracy.py
	$(BIN)/python benchmarks/calibration.py
	$(BIN)/python benchmarks/speed.py
	$(BIN)/python benchmarks/stated_vs_observed.py
	$(BIN)/python benchmarks/cluster.py
	$(BIN)/python benchmarks/any_drive.py
	$(BIN)/python benchmarks/frf_export.py

clean:
	rm -rf $(VENV) demo-output
