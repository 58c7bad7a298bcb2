"""The tutorial notebook runs as shown, its results agree with the virtual rig's truth, and it
stores the outputs the documentation shows.

docs/tutorial.ipynb is stored executed (``make tutorial``: a Jupyter kernel runs it in a scratch
folder). Its stored outputs are checked for shape: every code cell executed once, in order, with
outputs, the figures as PNG images, no errors and nothing on stderr. Its code cells are then
executed here in order in one namespace, as a kernel would, in a scratch working folder and
with matplotlib's Agg backend (no Jupyter kernel is needed), and the results compared with the
simulator's truth.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import matplotlib
import nbformat
import numpy as np

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "tutorial.ipynb"
FORCE_RTOL = 0.01               # reconstructed total force vs truth, RMS over its AC amplitude
LAW_RTOL = 0.001                # calibrated law vs the true force, RMS over its RMS
MAX_NOTEBOOK_BYTES = 1_000_000  # the stored outputs stay small (figures at a modest dpi)
FIGURE_CALLS = ("fig_forces(", "plt.subplots(")   # a cell that draws shows one PNG


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


def ends_with_value(source: str) -> bool:
    """Whether a kernel displays the cell's last expression: not silenced by ``;``, not a
    ``print`` (whose value is None)."""
    body = ast.parse(source).body
    if not body or not isinstance(body[-1], ast.Expr) or source.rstrip().endswith(";"):
        return False
    last = body[-1].value
    return not (isinstance(last, ast.Call) and getattr(last.func, "id", None) == "print")


def stored_text(cells) -> str:
    """Everything the cells printed, as stored."""
    return "".join(o.text for c in cells for o in c.outputs if o.output_type == "stream")


def test_the_notebook_stores_its_executed_outputs():
    assert NOTEBOOK.stat().st_size < MAX_NOTEBOOK_BYTES
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    cells = [c for c in notebook.cells if c.cell_type == "code"]
    assert len(cells) >= 8
    # executed once, top to bottom, by one kernel: `make tutorial` after every change
    assert [c.execution_count for c in cells] == list(range(1, len(cells) + 1))
    for k, cell in enumerate(cells, start=1):
        kinds = [o.output_type for o in cell.outputs]
        assert kinds, f"code cell {k} stores no output"
        assert "error" not in kinds, f"code cell {k} stores an error"
        assert not any(o.output_type == "stream" and o.name == "stderr" for o in cell.outputs), (
            f"code cell {k} wrote to stderr (a warning?)")
        results = [o for o in cell.outputs if o.output_type == "execute_result"]
        assert len(results) == ends_with_value(cell.source), f"code cell {k}"
        assert all(o.execution_count == cell.execution_count for o in results)
        images = [o for o in cell.outputs if "image/png" in o.get("data", {})]
        draws = any(call in cell.source for call in FIGURE_CALLS)
        assert len(images) == draws, f"code cell {k}: {len(images)} images"
    assert not any(line.lstrip().startswith(("%", "!")) for c in cells
                   for line in c.source.splitlines()), "magics need IPython"
    # the page shows a good result: the stored figures of merit pass the checks below
    printed = stored_text(cells)
    force = re.search(r"total force, RMS error over its AC amplitude: ([\d.]+) %", printed)
    law = re.search(r"law vs truth over run \S+: RMS error ([\d.e-]+) %", printed)
    assert force and law, printed
    assert float(force.group(1)) / 100 < FORCE_RTOL
    assert float(law.group(1)) / 100 < LAW_RTOL


def test_the_tutorial_runs_and_matches_the_truth(tmp_path, monkeypatch):
    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    ns = run_cells(code_cells(notebook))
    import matplotlib.pyplot as plt

    plt.close("all")

    home = tmp_path / "forcecal-tutorial"
    for written in ("model.json", "my-lab/g1000_dc06_ac02.tdms", "my-lab/tare.tdms",
                    "forces/g1000_dc06_ac02.forces.csv", "forces/g1000_dc06_ac02.json",
                    "calibration/calibration.json"):
        assert (home / written).is_file(), written
    # the lab's own files: the DAQ's names in the file, the rig's after the channel map
    assert ns["run"].source.endswith(".tdms")
    assert {"R1", "R2", "s1", "s2", "i"} <= set(ns["run"].channels)
    assert "R1" not in ns["forcecal"].read_run(home / "my-lab" / "tare.tdms").channels
    # the reconstruction: close to the truth, much closer than the reactions alone, and the
    # tare matters (the files' gauges carry offsets)
    assert ns["error"] < FORCE_RTOL, ns["error"]
    assert ns["error_static"] > 5 * ns["error"]
    assert ns["error_untared"] > 5 * ns["error"]
    assert ns["untared"].notes and not ns["est"].notes
    assert 0.05 < ns["est"].inertia_share < 0.2
    names = ["F1", "F2", "total"]
    assert list(ns["forces"].columns) == [*names, *(f"{n}_static" for n in names),
                                          *(f"{n}_std" for n in names)]
    assert ns["inside"] > 0.9                # F1's error within its ±2σ band
    # the figures: F1 against the truth with its band, and the report's forces figure
    assert len(ns["fig_f1"].axes) == 2
    axes = ns["fig"].axes
    assert len(axes) == 2 + 2 * 3            # J, R; each force and the total, and its error
    assert any(line.get_label() == "total truth" for ax in axes for line in ax.get_lines())
    # the calibration: the chosen law gives the true force from the true current and gaps
    assert ns["law_error"] < LAW_RTOL, ns["law_error"]
    assert ns["cal"].law == ns["result"].calibration.law
    assert np.all(np.diff(ns["prediction"].total) > 0)     # more current, more force
