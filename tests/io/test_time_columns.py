"""The time column as labs name it: ``Zeit``, ``t``, ``X_Value`` (LabVIEW), ``Timestamp`` (any
case, a unit in the header); any other name, anywhere in the header, through the rig's
``[channels] time``; absolute stamps (ISO 8601 dates and times, seconds since an epoch) read as
seconds from the first sample. Each variant of the simulated 'paper' run reads as the run
itself; a time column the rig names and the file lacks, an unknown first column and dates in
another form are refused in one line naming the file and the column."""

from __future__ import annotations

import datetime
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w
from nptdms import ChannelObject, TdmsWriter

from forcecal.cli.main import main
from forcecal.errors import DataError, InputError, RigError
from forcecal.io.run_files import read_run
from forcecal.rig import load_rig, parse_rig, rig_to_dict

START = datetime.datetime(2024, 5, 1, 12, 0, 0)
EPOCH = 1714564800  # [s] START since 1970


@pytest.fixture(scope="module")
def original(paper_dir):
    """(header, rows as text, the run as read) of the simulated run."""
    lines = (paper_dir / "runs" / "paper.csv").read_text(encoding="utf-8").splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]], read_run(
        paper_dir / "runs" / "paper.csv")


def variant(original, path: Path, name: str, time=None, at: int = 0) -> Path:
    """The run with its time column named ``name`` (its cells ``time(k, cell)``), at column
    ``at``."""
    header, rows, _ = original
    cells = [[time(k, row[0]) if time else row[0], *row[1:]] for k, row in enumerate(rows)]
    table = [[name, *header[1:]], *cells]
    table = [[*row[1:at + 1], row[0], *row[at + 1:]] for row in table]
    path.write_text("\n".join(",".join(row) for row in table) + "\n", encoding="utf-8")
    return path


def assert_same_run(run, expected):
    assert (run.fs, run.t0) == (expected.fs, expected.t0)
    assert list(run.channels) == list(expected.channels)
    for name, values in expected.channels.items():
        np.testing.assert_array_equal(run.channels[name], values)


def mapped_rig(paper_dir, folder: Path, time: str) -> Path:
    """The paper rig with ``[channels] time = time``."""
    doc = tomllib.loads((paper_dir / "rig.toml").read_text(encoding="utf-8"))
    doc["channels"] = {"time": time}
    path = folder / "rig.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def model_json(paper_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("model") / "model.json"
    assert main(["scan", str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"), "-o",
                 str(out)]) == 0
    return out


def refused(code, capsys, out: Path) -> str:
    assert code == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert not out.exists()
    return lines[0]


# --------------------------------------------------------------------------------------------
# names understood without a map


@pytest.mark.parametrize("name", ["Zeit", "t", "X_Value", "Timestamp", "TIME", "zeit [s]",
                                  "Timestamp (s)", "x_value"])
def test_common_time_names_read_as_time(original, tmp_path, name):
    run = read_run(variant(original, tmp_path / "r.csv", name))
    assert_same_run(run, original[2])


def test_common_time_name_in_ms(original, tmp_path):
    run = read_run(variant(original, tmp_path / "r.csv", "Zeit [ms]",
                           lambda k, cell: f"{k / 10:.1f}"))         # 0.1 ms a step
    assert run.fs == pytest.approx(original[2].fs, rel=1e-12) and run.t0 == 0.0
    np.testing.assert_array_equal(run.channels["R1"], original[2].channels["R1"])


def test_common_names_in_tdms_and_hdf5(tmp_path):
    n, fs = 64, 1000.0
    time, signal = 5.0 + np.arange(n) / fs, np.sin(np.arange(n))
    tdms = tmp_path / "r.tdms"
    with TdmsWriter(tdms) as writer:
        writer.write_segment([ChannelObject("g", "Zeit", time), ChannelObject("g", "a", signal)])
    h5 = tmp_path / "r.h5"
    with h5py.File(h5, "w") as f:
        f["X_Value"], f["a"] = time, signal
    for path in (tdms, h5):
        run = read_run(path)
        assert list(run.channels) == ["a"] and run.t0 == 5.0
        assert run.fs == pytest.approx(fs, rel=1e-12)


def test_an_unknown_first_column_is_refused_naming_the_way_out(original, paper_dir, model_json,
                                                                tmp_path, capsys):
    run = variant(original, tmp_path / "r.csv", "Sample")
    out = tmp_path / "out"
    line = refused(main(["reconstruct", str(paper_dir / "rig.toml"), str(model_json), str(run),
                         "-o", str(out)]), capsys, out)
    assert f"run '{run}'" in line and "the first column is 'Sample'; expected 'time'" in line
    assert "'Zeit'" in line and "[channels] time" in line, line


# --------------------------------------------------------------------------------------------
# [channels] time


@pytest.mark.parametrize("at", [0, 3])
def test_the_rig_maps_any_name_to_the_time(original, paper_dir, tmp_path, at):
    rig = load_rig(mapped_rig(paper_dir, tmp_path, "Sample Time"))
    run = read_run(variant(original, tmp_path / "r.csv", "Sample Time [s]", at=at), rig)
    assert_same_run(run, read_run(paper_dir / "runs" / "paper.csv",
                                  load_rig(paper_dir / "rig.toml")))


def test_a_mapped_time_reconstructs_as_the_original(original, paper_dir, model_json, tmp_path):
    rig = mapped_rig(paper_dir, tmp_path, "Zeitstempel")
    run = variant(original, tmp_path / "paper.csv", "Zeitstempel")
    assert main(["reconstruct", str(rig), str(model_json), str(run), "-o",
                 str(tmp_path / "mapped")]) == 0
    assert main(["reconstruct", str(paper_dir / "rig.toml"), str(model_json),
                 str(paper_dir / "runs" / "paper.csv"), "-o", str(tmp_path / "plain")]) == 0
    mapped = (tmp_path / "mapped" / "paper.forces.csv").read_text()
    assert mapped == (tmp_path / "plain" / "paper.forces.csv").read_text()


def test_a_mapped_time_column_the_file_lacks_is_refused(original, paper_dir, model_json,
                                                        tmp_path, capsys):
    rig = mapped_rig(paper_dir, tmp_path, "Zeit")
    run = paper_dir / "runs" / "paper.csv"                         # its time is 'time'
    out = tmp_path / "out"
    line = refused(main(["reconstruct", str(rig), str(model_json), str(run), "-o", str(out)]),
                   capsys, out)
    assert f"run '{run}': time column 'Zeit'" in line, line
    assert f"rig '{rig}', key 'channels.time'" in line and "not in the file" in line, line
    assert "'time', 'R1'" in line, line


def test_the_time_key_round_trips_and_other_keys_stay_refused(paper_dir, tmp_path):
    rig = load_rig(mapped_rig(paper_dir, tmp_path, "Zeit"))
    assert dict(rig.channel_map) == {"time": "Zeit"}
    assert rig_to_dict(rig)["channels"] == {"time": "Zeit"}
    doc = rig_to_dict(rig)
    doc["channels"] = {"zeit": "Zeit"}
    with pytest.raises(RigError, match=r"'channels\.zeit' is not a channel of the rig; "
                                       r"expected one of .*time"):
        parse_rig(doc, "rig.toml")


# --------------------------------------------------------------------------------------------
# absolute stamps


def _iso(k: int, cell: str, sep: str = "T") -> str:
    return (START + datetime.timedelta(microseconds=100 * k)).isoformat(
        sep=sep, timespec="microseconds")


@pytest.mark.parametrize("form", ["iso", "iso with a space and Z", "epoch seconds"])
def test_absolute_stamps_are_seconds_from_the_first(original, tmp_path, form):
    time = {"iso": _iso,
            "iso with a space and Z": lambda k, cell: _iso(k, cell, " ") + "Z",
            "epoch seconds": lambda k, cell: f"{EPOCH + k // 10_000}.{k % 10_000:04d}"}[form]
    run = read_run(variant(original, tmp_path / "r.csv", "Timestamp", time))
    assert_same_run(run, original[2])                                   # t0 = 0, fs exact


def test_dates_in_another_form_are_refused_at_their_row(original, tmp_path):
    german = variant(original, tmp_path / "r.csv", "Zeit",
                     lambda k, cell: f"01.05.2024 12:00:{k / 10_000:07.4f}")
    with pytest.raises(DataError, match=r"r\.csv': row 2, column 'Zeit': '01\.05\.2024 "
                                        r"12:00:00\.0000' is not a number of seconds nor a "
                                        r"date and time \(ISO 8601"):
        read_run(german)
    broken = variant(original, tmp_path / "b.csv", "Timestamp",
                     lambda k, cell: "noon" if k == 7 else _iso(k, cell))
    with pytest.raises(DataError, match=r"b\.csv': row 9, column 'Timestamp': 'noon' is not a "
                                        r"date and time like the first row's"):
        read_run(broken)


def test_a_refused_time_unit_still_names_the_column(original, tmp_path):
    with pytest.raises(InputError, match=r"the time column is in 'min'"):
        read_run(variant(original, tmp_path / "r.csv", "Zeit [min]"))
