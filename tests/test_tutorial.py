"""The tutorial notebook runs as shown, and its results agree with the virtual rig's truth.

docs/tutorial.ipynb is read with nbformat and its code cells are executed in order in one
namespace, as a kernel would, in a scratch working folder and with matplotlib's Agg backend (no
Jupyter kernel is needed). The notebook keeps no outputs, so it cannot show stale results.
"""

from __future__ import annotations

import ast
from pathlib import Path

import matplotlib
import nbformat
import numpy as np

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "tutorial.ipynb"
FORCE_RTOL = 0.01               # reconstructed total force vs truth, RMS over its AC amplitude
LAW_RTOL = 0.001                # calibrated law vs the true force, RMS over its RMS


def code_cells(notebook) -> list[str]:
    return [cell.source for cell in notebook.cells if cell.cell_type == "code"]


def run_cells(sources: list[str]) -> dict:
    """Execute the cells in one namespace; the value of a cell's last expression is evaluated
    (as a kernel would display it) but not shown."""
    namespace: dict = {"__name__": "__main__"}
    for k, source in enumerate(sources, start=1):
        tree = ast.parse(source, filename=f"<cell {k}>")
        last = tree.body.pop() if tree.body and isinstance(tree.body[-1], ast.Expr) else None
        exec(compile(tree, f"<cell {k}>", "exec"), namespace)
        if last is not None:
            value = eval(compile(ast.Expression(last.value), f"<cell {k}>", "eval"), namespace)
            for view in ("_repr_html_", "__repr__"):
                if hasattr(value, view):
                    getattr(value, view)()
    return namespace


def test_the_notebook_is_valid_and_stores_no_outputs():
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    cells = [c for c in notebook.cells if c.cell_type == "code"]
    assert len(cells) >= 8
    assert all(not c.outputs and c.execution_count is None for c in cells)
    assert not any(line.lstrip().startswith(("%", "!")) for c in cells
                   for line in c.source.splitlines()), "magics need a kernel"


def test_the_tutorial_runs_and_matches_the_truth(tmp_path, monkeypatch):
    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    ns = run_cells(code_cells(notebook))
    import matplotlib.pyplot as plt

    plt.close("all")

    assert (tmp_path / "forcecal-tutorial" / "calibration" / "calibration.json").is_file()
    # the reconstruction: close to the truth, and much closer than the reactions alone
    assert ns["error"] < FORCE_RTOL, ns["error"]
    assert ns["error_static"] > 5 * ns["error"]
    assert 0.05 < ns["est"].inertia_share < 0.2
    assert list(ns["forces"].columns) == ["F1", "F2", "total", "F1_static", "F2_static",
                                          "total_static"]
    # the figure: three panels, with the truth drawn
    axes = ns["fig"].axes
    assert len(axes) == 3
    assert any(line.get_label() == "total truth" for line in axes[2].get_lines())
    # the calibration: the chosen law gives the true force from the true current and gaps
    assert ns["law_error"] < LAW_RTOL, ns["law_error"]
    assert ns["cal"].law == ns["result"].calibration.law
    assert np.all(np.diff(ns["prediction"].total) > 0)     # more current, more force
