"""Tests of how the reports present their numbers, tables and figures: digits set by the
uncertainty, inputs relative to one stated root, headers that do not break, figures shown at
the size they were drawn at and written in the format asked for.

Every test builds small inputs of its own (no simulation), so the file runs in well under a
second; the command line's option is tested beside the simulated run (test_report.py).
"""

from __future__ import annotations

import re

import pytest
from matplotlib.figure import Figure

from forcecal.errors import InputError
from forcecal.report import Image, Section, Table, build_report
from forcecal.report._templates import style_sheet
from forcecal.report.cells import plus_minus, quantity, relative_paths, unc, value
from forcecal.report.figures import figure_bytes
from forcecal.report.pipeline import provenance_section

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _figure(width: float = 3.0) -> Figure:
    fig = Figure(figsize=(width, 1.0))
    fig.add_subplot().plot([0, 1], [1, 0])
    return fig


# --------------------------------------------------------------------------------------------
# numbers


@pytest.mark.parametrize(("x", "u", "text"), [
    (0.0012494, 0.00083, "0.00125 ± 0.00083"),         # the phasor the report over-stated
    (1.0002, 1.04e-4, "1.00020 ± 0.00010"),             # |Q| = 1.000 ± 0.0001 before
    (0.9996, 0.000998, "0.9996 ± 0.0010"),              # u rounds up to the next decade
    (20.014008, 1.2e-5, "20.014008 ± 0.000012"),        # u in the value's notation
    (3e-6, 1e-3, "0.0000 ± 0.0010"),                    # a value below u's digit is 0
    (1.00491e-5, 2.3e-9, "1.00491e-05 ± 2.3e-09"),
    (-0.025, 0.0012, "-0.0250 ± 0.0012"),
])
def test_a_value_carries_the_digits_its_uncertainty_warrants(x, u, text):
    assert plus_minus(x, u) == text
    assert value(x, u) == text.split(" ± ")[0]
    assert float(unc(u)) == float(f"{u:.2g}")


def test_without_an_uncertainty_six_digits_and_quantities_in_the_prefix_that_suits():
    assert value(0.000634282, 0.0) == "0.000634282"
    assert quantity(0.00118, "N", 2) == "1.2 mN"
    assert quantity(4.975e-5, "m", 4) == "49.75 µm"
    assert plus_minus(49.750, 0.098, "µm") == "49.750 ± 0.098 µm"


def test_input_paths_are_relative_to_one_stated_root(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    runs = tmp_path / "lab" / "runs"
    runs.mkdir(parents=True)
    for name in ("lab/rig.toml", "lab/manifest.csv", "lab/runs/g1.csv"):
        (tmp_path / name).write_text("x", encoding="utf-8")
    root, paths = relative_paths(["lab/rig.toml", str(runs / "g1.csv"), "lab/manifest.csv",
                                  "<scan>"])
    assert root == str(tmp_path / "lab")
    assert paths == ["rig.toml", "runs/g1.csv", "manifest.csv", "<scan>"]
    prov = {"forcecal_version": "0", "python": "3", "created_utc": "now", "command": "c",
            "inputs": [{"path": "lab/rig.toml", "bytes": 1, "sha256": "ab"},
                       {"path": str(runs / "g1.csv")}]}
    page = build_report("t", [provenance_section(prov)])
    assert f"Input paths are relative to {tmp_path / 'lab'}" in page
    assert "<td>runs/g1.csv</td>" in page and str(runs) not in page


# --------------------------------------------------------------------------------------------
# tables and figures on the page


def _rules(css: str) -> dict[str, str]:
    """Selector -> declarations of a style sheet (one rule per selector list)."""
    return {sel.strip(): body for sel, body in re.findall(r"([^{}]+)\{([^{}]*)\}", css)}


def test_table_headers_do_not_break_mid_word():
    rules = _rules(style_sheet())
    assert "white-space: nowrap" in rules["th"]
    breaking = [sel for sel, body in rules.items()
                if "overflow-wrap: anywhere" in body and re.search(r"\b(th|td)\b", sel)]
    assert not breaking, breaking
    page = build_report("t", [Section("s", [Table([["g0800_dc04_ac01", "1"]],
                                                   header=["parameter / s", "value"])])])
    assert "<th>parameter / s</th>" in page and "white-space: nowrap" in page
    assert '<div class="wide"><table>' in page           # a wide table scrolls, whole


def test_figures_are_shown_at_the_size_they_were_drawn_at():
    fig = _figure(width=12.0)
    page = build_report("t", [Section("s", [Image(fig, caption="Fig. 1: a line", dpi=20)])])
    assert re.search(r'<img src="data:image/png;base64,[^"]+" width="1152" ', page)
    svg = figure_bytes(_figure(), "svg")
    assert svg.lstrip().startswith(b"<?xml") and b"<svg" in svg
    page = build_report("t", [Section("s", [Image(svg, caption="svg", width=576.0),
                                            Image(figure_bytes(_figure(), "png", dpi=20),
                                                  caption="pdf", link="figures/a.pdf")])])
    assert re.search(r'<img src="data:image/svg\+xml;base64,[^"]+" width="576" ', page)
    assert '<a href="figures/a.pdf"><img src="data:image/png;base64,' in page
    assert figure_bytes(_figure(), "pdf").startswith(b"%PDF")
    assert figure_bytes(_figure(), "png", dpi=20).startswith(PNG_SIGNATURE)
    with pytest.raises(InputError, match="figure format 'jpg'"):
        figure_bytes(_figure(), "jpg")
