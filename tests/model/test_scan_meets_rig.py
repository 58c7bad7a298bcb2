"""A scan that does not belong to its rig, or a model to a changed rig, is refused at once and
for its real cause (not by the fit it would break): a plate's scan on a beam rig, a beam's scan
on a plate rig, a scan short of a gauge, and a saved model used with an edited rig, each named
in one line with what was expected and what was found, nothing written."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from forcecal.cli.main import main
from forcecal.rig import load_rig
from forcecal.simulate.export import write_simulation


@pytest.fixture(scope="module")
def plate_dir(tmp_path_factory) -> Path:
    """The 'plate' preset written in the public formats (seed 0)."""
    out = tmp_path_factory.mktemp("plate")
    write_simulation(out, "plate", seed=0)
    return out


@pytest.fixture(scope="module")
def model_json(paper_dir, tmp_path_factory) -> Path:
    """``forcecal scan`` of the 'paper' rig: a MODEL.json whose source is the scan."""
    path = tmp_path_factory.mktemp("model") / "model.json"
    assert main(["scan", str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"),
                 "-o", str(path)]) == 0
    return path


def longer_rig(paper_dir: Path, folder: Path, length: float) -> Path:
    """The 'paper' rig with its beam (and gauge R2, at its end) made ``length`` long."""
    doc = tomllib.loads((paper_dir / "rig.toml").read_text())
    doc["structure"]["length"] = length
    doc["gauges"][1]["x"] = length
    path = folder / f"rig_{length:g}.toml"
    path.write_text(tomli_w.dumps(doc))
    return path


def refused(code: int, capsys, *words: str) -> str:
    """Exit status 2 and one line on stderr holding every one of ``words``."""
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    for word in words:
        assert word in lines[0], f"{word!r} not in: {lines[0]}"
    return lines[0]


def test_a_plate_scan_on_a_beam_rig_is_another_structure(paper_dir, plate_dir, tmp_path,
                                                          capsys):
    """Once "the Vandermonde matrix is numerically rank deficient ... add points"."""
    out = tmp_path / "model.json"
    code = main(["scan", str(paper_dir / "rig.toml"), str(plate_dir / "scan.uff"),
                 "-o", str(out)])
    line = refused(code, capsys, f"scan '{plate_dir / 'scan.uff'}'",
                   f"rig '{paper_dir / 'rig.toml'}'", "2-D", "x in [0, 0.5] m, y in [0, 0.4] m",
                   "along x", "another structure")
    assert "Vandermonde" not in line and "order" not in line
    assert not out.exists()


def test_a_beam_scan_on_a_plate_rig_is_a_line(paper_dir, plate_dir, tmp_path, capsys):
    """Once "'scan '...'': points need x, y; found 1 columns"."""
    out = tmp_path / "model.json"
    code = main(["scan", str(plate_dir / "rig.toml"), str(paper_dir / "scan.uff"),
                 "-o", str(out)])
    line = refused(code, capsys, f"scan '{paper_dir / 'scan.uff'}' on rig "
                   f"'{plate_dir / 'rig.toml'}'", "x only", "1-D", "(x, y)")
    assert "''" not in line and "columns" not in line
    assert not out.exists()


@pytest.mark.parametrize("command", ["scan", "reconstruct"])
def test_a_scan_short_of_a_gauge_is_refused(command, paper_dir, tmp_path, capsys):
    """A 0.8 m rig and a scan of 0-0.6 m: once accepted by ``scan``, and ``reconstruct`` then
    blamed the sensors ("sit near a node ... move a sensor")."""
    rig = longer_rig(paper_dir, tmp_path, 0.8)
    out = tmp_path / "out"
    scan = str(paper_dir / "scan.uff")
    argv = (["scan", str(rig), scan, "-o", str(out / "model.json")] if command == "scan" else
            ["reconstruct", str(rig), scan, str(paper_dir / "runs" / "paper.csv"),
             "-o", str(out)])
    line = refused(main(argv), capsys, f"scan '{scan}' on rig '{rig}'", "gauge R2 at x = 0.8 m",
                   "scanned extent x in [0, 0.6] m", "spans x in [0, 0.8] m")
    assert "node" not in line and "sensor s" not in line
    assert not out.exists()


def test_a_scan_a_little_short_of_a_gauge_is_noted(paper_dir, tmp_path, capsys):
    """Scans rarely reach the very ends: 2 cm short of a 0.62 m beam's end gauge is kept,
    with a note naming the gauge."""
    rig = longer_rig(paper_dir, tmp_path, 0.62)
    out = tmp_path / "model.json"
    code = main(["scan", str(rig), str(paper_dir / "scan.uff"), "-o", str(out)])
    said = capsys.readouterr()
    assert code == 0, said.err
    notes = [line for line in said.out.splitlines() if "gauge R2" in line]
    assert len(notes) == 1 and notes[0].startswith("note: "), said.out
    assert "gauge R2 (0.02 m)" in notes[0] and "x in [0, 0.6] m" in notes[0], notes
    assert out.exists()


@pytest.mark.parametrize("command", ["reconstruct", "stream"])
def test_a_model_with_a_changed_rig_names_the_model_file(command, paper_dir, model_json,
                                                         tmp_path, capsys):
    """Once "model '<the scan>' was built for ...": the refusal names the MODEL.json given."""
    rig = longer_rig(paper_dir, tmp_path, 0.8)
    run = str(paper_dir / "runs" / "paper.csv")
    out = tmp_path / "out"
    target = out if command == "reconstruct" else out / "forces.csv"
    code = main([command, str(rig), str(model_json), run, "-o", str(target)])
    line = refused(code, capsys, f"model '{model_json}'", f"rig '{rig}'",
                   "'gauges[1].x' is 0.6", "has 0.8", "'structure.length' 0.6 -> 0.8",
                   "forcecal scan")
    assert "scan.uff" not in line
    assert not out.exists()


def test_structures_tell_a_line_scan_from_a_grid(paper_dir, plate_dir):
    """A beam accepts points along x with a little y (across its width); a plate refuses
    points along one line even when they give (x, y)."""
    beam = load_rig(paper_dir / "rig.toml").structure
    plate = load_rig(plate_dir / "rig.toml").structure
    x = np.linspace(0.0, 0.5, 21)
    assert beam.scan_mismatch(np.column_stack([x, 0.01 * (-1.0) ** np.arange(21)])) is None
    diagonal = np.column_stack([x, 0.8 * x])
    assert "along a line" in (plate.scan_mismatch(diagonal) or "")
    grid = np.column_stack([x, 0.4 * np.sin(7 * x) ** 2])
    assert plate.scan_mismatch(grid) is None
