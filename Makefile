# Two entry points: `make demo` and `make test`. Each creates .venv when missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

# BLAS threads: forcecal sets its own (--threads, FORCECAL_THREADS; one by default), and the
# tests' direct calls are pinned by tests/conftest.py.

.PHONY: demo test lint bench clean docs tutorial

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

# docs/tutorial.ipynb executed in place, its outputs stored for the docs page: a Jupyter kernel
# (nbclient, ipykernel; figures inline as PNG) runs it in a scratch folder. The simulation is
# seeded, no timings are recorded and each cell's printed lines are kept as one output, so the
# outputs change only when the results do.
tutorial: $(DOCS_STAMP)
	$(BIN)/python -c 'import tempfile, nbclient, nbformat; \
	nb = nbformat.read("docs/tutorial.ipynb", as_version=4); \
	scratch = tempfile.TemporaryDirectory(); \
	nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", record_timing=False, \
	                        coalesce_streams=True, \
	                        resources={"metadata": {"path": scratch.name}}).execute(); \
	nbformat.write(nb, "docs/tutorial.ipynb")'

# the benchmarks call the stages directly, not the commands that limit their own threads
bench: export OPENBLAS_NUM_THREADS ?= 1
bench: export OMP_NUM_THREADS ?= 1
bench: export MKL_NUM_THREADS ?= 1
bench: $(STAMP)
	$(BIN)/python benchmarks/simulator.py
	$(BIN)/python benchmarks/accuracy.py
	$(BIN)/python benchmarks/calibration.py
	$(BIN)/python benchmarks/speed.py
	$(BIN)/python benchmarks/stated_vs_observed.py
	$(BIN)/python benchmarks/cluster.py
	$(BIN)/python benchmarks/any_drive.py
	$(BIN)/python benchmarks/scan_redraw.py
	$(BIN)/python benchmarks/frf_export.py
	$(BIN)/python benchmarks/mistakes.py
	$(BIN)/python benchmarks/weight.py
	$(BIN)/python benchmarks/threads.py
	$(BIN)/python benchmarks/fuzz.py

clean:
	rm -rf $(VENV) demo-output
