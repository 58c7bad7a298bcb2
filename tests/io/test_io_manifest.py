"""The campaign manifest: reading, writing, and the messages for a wrong row."""

from __future__ import annotations

from pathlib import Path

import pytest

from forcecal.errors import InputError
from forcecal.io.manifest import ManifestEntry, read_manifest, write_manifest


@pytest.fixture
def campaign(tmp_path) -> Path:
    """A folder with runs/ holding three (empty) run files."""
    runs = tmp_path / "runs"
    runs.mkdir()
    for name in ("g080.csv", "g100.csv", "tare.csv"):
        (runs / name).write_text("time,i\n")
    return tmp_path


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_contract_example(campaign):
    path = write(campaign / "m.csv", "run,gap\nruns/g080.csv,0.0008\nruns/g100.csv,0.001\n")
    entries = read_manifest(path)
    assert entries == [
        ManifestEntry(run=(campaign / "runs/g080.csv").resolve(), gap=0.0008),
        ManifestEntry(run=(campaign / "runs/g100.csv").resolve(), gap=0.001),
    ]


def test_round_trip_with_every_kind_of_column(campaign):
    rows = [
        {"run": "runs/g080.csv", "gap": 8e-4, "dc": 0.6, "repeat": 1},
        {"run": Path("runs/g100.csv"), "gap_F1": 1e-3, "gap_F2": 1.1e-3, "dc": 1.0},
        {"run": "runs/tare.csv", "tare": True, "gap": None},
    ]
    path = write_manifest(campaign / "m.csv", rows)
    assert path.read_text().splitlines()[0] == "run,gap,dc,repeat,gap_F1,gap_F2,tare"
    first, second, third = read_manifest(path)
    assert first.gap == 8e-4
    assert first.gaps == {}
    assert first.labels == {"dc": "0.6", "repeat": "1"}
    assert not first.tare
    assert second.gap is None
    assert second.gaps == {"F1": 1e-3, "F2": 1.1e-3}
    assert second.labels == {"dc": "1.0", "repeat": ""}
    assert third.tare
    assert third.run == (campaign / "runs" / "tare.csv").resolve()
    assert not list(campaign.glob("*.part"))


def test_runs_resolve_against_the_manifest_folder(campaign, monkeypatch):
    sub = campaign / "sub"
    sub.mkdir()
    path = write(sub / "m.csv", "run\n../runs/g080.csv\n")
    monkeypatch.chdir(campaign / "runs")  # the working folder must not matter
    (entry,) = read_manifest(path)
    assert entry.run == (campaign / "runs" / "g080.csv").resolve()


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("true", True),
        ("TRUE", True),
        ("1", True),
        ("yes", True),
        ("false", False),
        ("0", False),
        ("no", False),
        ("", False),
    ],
)
def test_tare_values(campaign, text, expected):
    path = write(campaign / "m.csv", f"run,tare\nruns/tare.csv,{text}\n")
    assert read_manifest(path)[0].tare is expected


def test_missing_tare_column_means_false(campaign):
    assert read_manifest(write(campaign / "m.csv", "run\nruns/g080.csv\n"))[0].tare is False


# --------------------------------------------------------------------------------------------
# error paths


def test_missing_manifest(tmp_path):
    with pytest.raises(InputError, match=r"manifest '.*m\.csv': file does not exist"):
        read_manifest(tmp_path / "m.csv")


def test_no_run_column(campaign):
    path = write(campaign / "m.csv", "file,gap\nruns/g080.csv,0.001\n")
    with pytest.raises(InputError, match=r"m\.csv': no 'run' column \(found: 'file', 'gap'\)"):
        read_manifest(path)


def test_run_that_does_not_exist_names_the_row(campaign):
    path = write(campaign / "m.csv", "run,gap\nruns/g080.csv,0.001\nruns/x.csv,0.001\n")
    with pytest.raises(InputError, match=r"manifest '.*m\.csv' row 3: run 'runs/x\.csv' does not"):
        read_manifest(path)


@pytest.mark.parametrize("gap", ["-0.001", "0", "abc", "nan", "inf"])
def test_gap_must_be_a_positive_number(campaign, gap):
    path = write(campaign / "m.csv", f"run,gap\nruns/g080.csv,{gap}\n")
    with pytest.raises(InputError, match=rf"row 2: gap '{gap}' is not a positive number"):
        read_manifest(path)


def test_per_point_gap_must_be_a_positive_number(campaign):
    path = write(campaign / "m.csv", "run,gap_F2\nruns/g080.csv,0.001\nruns/g100.csv,-1\n")
    with pytest.raises(InputError, match=r"row 3: gap_F2 '-1' is not a positive number"):
        read_manifest(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty"),
        ("run,gap\n", "no runs listed"),
        ("run,tare\nruns/g080.csv,maybe\n", "row 2: tare 'maybe' is not one of"),
        ("run,gap\n,0.001\n", "row 2: the 'run' cell is empty"),
        ("run,gap\nruns/g080.csv,0.001,7\n", "row 2: 3 cells, the header names 2"),
        ("run,dc,dc\nruns/g080.csv,1,2\n", "column 'dc' appears twice"),
        ("run,gap_\nruns/g080.csv,1\n", "column 'gap_' names no force point"),
    ],
)
def test_malformed_manifests(campaign, text, message):
    with pytest.raises(InputError, match=message):
        read_manifest(write(campaign / "m.csv", text))


def test_write_requires_run(tmp_path):
    with pytest.raises(InputError, match="row 3 has no 'run'"):
        write_manifest(tmp_path / "m.csv", [{"run": "a.csv"}, {"gap": 0.001}])
    assert not (tmp_path / "m.csv").exists()
