"""The force series ``reconstruct`` writes: the CSV's uncertainty columns and the HDF5, MATLAB
and UFF formats, each read back with its own library to the estimate's values."""

from __future__ import annotations

import csv
import dataclasses
import json
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import pyuff
import scipy.io

from forcecal.cli.main import main
from forcecal.errors import InputError
from forcecal.forces.estimate import series_columns, waveform_std_series
from forcecal.forces.steady import reconstruct
from forcecal.io import result_formats
from forcecal.io.result_formats import SERIES_FORMATS, SERIES_SUFFIXES
from forcecal.io.results import write_estimate
from forcecal.io.run_files import read_run, read_table_csv, write_run_csv, write_table_csv

SHORT_SECONDS = 0.4
"""The run is cut to 8 periods, starting at 0.1 s (a start time other than zero)."""
DOCUMENTED = ["time", "F1", "F2", "total", "F1_static", "F2_static", "total_static"]
"""The columns INTERFACES.md section 5 documents, in their order."""
STD_COLUMNS = ["F1_std", "F2_std", "total_std"]


@pytest.fixture(scope="module")
def short(paper):
    """(rig, model, run) of the 'paper' rig, its run cut to SHORT_SECONDS from 0.1 s."""
    rig, _, model, run = paper
    start, n = int(0.1 * run.fs), int(SHORT_SECONDS * run.fs)
    cut = dataclasses.replace(run, channels={k: np.asarray(v)[start:start + n]
                                             for k, v in run.channels.items()},
                              t0=run.t0 + start / run.fs)
    return rig, model, cut


@pytest.fixture(scope="module")
def est(short):
    rig, model, run = short
    return reconstruct(rig, model, run)


@pytest.fixture(scope="module")
def written(est, tmp_path_factory) -> dict[str, Path]:
    """Every format written once: format -> the series file (the JSON beside each)."""
    out = {}
    for fmt in SERIES_FORMATS:
        folder = tmp_path_factory.mktemp(fmt)
        series, js = write_estimate(est, folder, fmt=fmt)
        assert series == folder / f"paper{SERIES_SUFFIXES[fmt]}"
        assert js == folder / "paper.json"
        assert sorted(p.name for p in folder.iterdir()) == sorted([series.name, js.name])
        out[fmt] = series
    return out


def forces_and_total(est) -> dict[str, np.ndarray]:
    return {"F1": est.series[0], "F2": est.series[1], "total": est.total_series}


# --------------------------------------------------------------------------------------------
# the uncertainty at each instant


def test_std_without_f0_uncertainty_is_the_phasors_root_sum_square(est):
    still = dataclasses.replace(est, f0_std=0.0)
    std = waveform_std_series(still)
    expected = np.sqrt(np.r_[np.sum(est.force_std**2, axis=1), np.sum(est.total_std**2)])
    np.testing.assert_allclose(std, np.repeat(expected[:, None], est.time.size, axis=1),
                               rtol=1e-14)
    # the total's uncertainty is not the forces' root sum square: their errors are correlated
    assert not np.isclose(expected[2], np.hypot(expected[0], expected[1]), rtol=1e-3)


@pytest.mark.parametrize("f0_std", [None, 2e-3], ids=["as estimated", "large"])
def test_std_of_the_total_has_the_rms_of_waveform_std(est, f0_std):
    e = est if f0_std is None else dataclasses.replace(est, f0_std=f0_std)
    std = waveform_std_series(e)
    ac = np.sqrt(np.mean(std[-1] ** 2 - e.total_std[0] ** 2))    # AC part, RMS over the record
    np.testing.assert_allclose(ac, e.waveform_std, rtol=0.01 if f0_std else 1e-4)
    phasor_part = np.sqrt(np.r_[np.sum(e.force_std**2, axis=1), np.sum(e.total_std**2)])
    assert np.all(std >= phasor_part[:, None] * (1 - 1e-12))


def test_f0_uncertainty_moves_the_waveform_as_a_change_of_f0_would(est):
    """u(t)**2 - sum std_n**2 = (f0_std dx/df0)**2, dx/df0 with the phases held at mid-record."""
    f0_std = 1e-3
    e = dataclasses.replace(est, f0_std=f0_std)
    t = e.time
    t_mid = 0.5 * (t[0] + t[-1])
    n = np.arange(e.total.size)

    def total_at(f: float) -> np.ndarray:
        held = e.total * np.exp(1j * 2 * np.pi * n * (e.f0 - f) * t_mid)
        return (held @ np.exp(1j * 2 * np.pi * f * np.outer(n, t))).real

    step = 1e-4
    derivative = (total_at(e.f0 + step) - total_at(e.f0 - step)) / (2 * step)
    drift = np.sqrt(np.maximum(waveform_std_series(e)[-1] ** 2 - np.sum(e.total_std**2), 0))
    np.testing.assert_allclose(drift, f0_std * np.abs(derivative), rtol=1e-5,
                               atol=1e-9 * np.max(drift))
    assert drift[np.argmin(np.abs(t - t_mid))] < 0.01 * drift.max()


# --------------------------------------------------------------------------------------------
# CSV


def test_csv_keeps_the_documented_columns_first_and_adds_std(est, written):
    path = written["csv"]
    header = path.read_text().splitlines()[0]
    assert header.split(",") == DOCUMENTED + STD_COLUMNS
    time, columns = read_table_csv(path)                         # the project's own reader
    np.testing.assert_array_equal(time, est.time)
    std = waveform_std_series(est)
    for k, (name, values) in enumerate(forces_and_total(est).items()):
        np.testing.assert_array_equal(columns[name], values)
        np.testing.assert_array_equal(columns[f"{name}_std"], std[k])
    np.testing.assert_array_equal(columns["total_static"], est.static_series.sum(axis=0))


def test_csv_reads_with_pandas_and_the_csv_module(est, written):
    frame = pd.read_csv(written["csv"])
    assert list(frame.columns) == DOCUMENTED + STD_COLUMNS
    assert all(frame[c].dtype == np.float64 for c in frame.columns)
    np.testing.assert_array_equal(frame["total_std"].to_numpy(), waveform_std_series(est)[-1])
    with open(written["csv"], newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == est.time.size
    assert float(rows[0]["F1"]) == est.series[0, 0]


def test_csv_reads_back_as_a_run(est, written):
    run = read_run(written["csv"])
    assert list(run.channels) == DOCUMENTED[1:] + STD_COLUMNS
    np.testing.assert_allclose(run.time, est.time, rtol=0, atol=1e-12)


def test_json_names_the_series_file_and_every_unit(est, written):
    for fmt, path in written.items():
        doc = json.loads((path.parent / "paper.json").read_text())
        assert doc["series"] == {"file": path.name, "format": fmt,
                                 "units": {"time": "s", **{c: "N" for c in
                                                           DOCUMENTED[1:] + STD_COLUMNS}}}
        assert doc["waveform_std_n"] == est.waveform_std
        assert "generalized_coordinates" in doc


# --------------------------------------------------------------------------------------------
# HDF5, MATLAB, UFF


def test_hdf5_round_trip(est, written):
    columns = series_columns(est)
    with h5py.File(written["hdf5"], "r") as h5:
        assert h5.attrs["format"] == result_formats.HDF5_FORMAT
        assert h5.attrs["run"] == "paper"
        assert h5.attrs["fundamental_hz"] == est.f0
        assert h5.attrs["fundamental_std_hz"] == est.f0_std
        assert list(h5.attrs["notes"]) == list(est.notes)
        np.testing.assert_array_equal(h5["time"][()], est.time)
        assert h5["time"].attrs["units"] == "s"
        assert [n for n in h5 if isinstance(h5[n], h5py.Dataset)] == ["time", *columns]
        for name, values in columns.items():
            np.testing.assert_array_equal(h5[name][()], values)
            assert h5[name].attrs["units"] == "N"
        assert h5["F1"].attrs["std"] == "F1_std"
        assert h5["total_std"].attrs["quantity"] == "standard uncertainty"
        assert h5["F2_static"].attrs["quantity"] == "reactions-only force"
        harmonics = h5["harmonics"]
        np.testing.assert_array_equal(harmonics["harmonic"][()], est.harmonics)
        np.testing.assert_array_equal(harmonics["kept"][()], est.kept)
        np.testing.assert_array_equal(harmonics["F2"][()], est.force[1])
        np.testing.assert_array_equal(harmonics["F2_std"][()], est.force_std[1])
        np.testing.assert_array_equal(harmonics["total"][()], est.total)
        np.testing.assert_array_equal(harmonics["total_std"][()], est.total_std)
        assert harmonics["total"].attrs["units"] == "N"
    run = read_run(written["hdf5"])                        # the run layout: read_run reads it
    np.testing.assert_array_equal(run.channel("total_std"), columns["total_std"])
    np.testing.assert_allclose(run.time, est.time, rtol=0, atol=1e-12)


def test_mat_round_trip(est, written):
    mat = scipy.io.loadmat(written["mat"], simplify_cells=True)
    names = ["F1", "F2", "total"]
    assert list(mat["names"]) == names
    assert mat["run_name"] == "paper"
    std = waveform_std_series(est)
    np.testing.assert_array_equal(mat["time"], est.time)
    for k, name in enumerate(names):
        np.testing.assert_array_equal(mat["forces"][:, k], forces_and_total(est)[name])
        np.testing.assert_array_equal(mat["force_std"][:, k], std[k])
    np.testing.assert_array_equal(mat["static"][:, :2], est.static_series.T)
    np.testing.assert_array_equal(mat["phasors"], np.vstack([est.force, est.total]).T)
    np.testing.assert_array_equal(mat["phasor_std"], np.vstack([est.force_std, est.total_std]).T)
    np.testing.assert_array_equal(mat["harmonics"], est.harmonics)
    np.testing.assert_array_equal(mat["kept"], est.kept.astype(int))
    assert mat["f0"] == est.f0 and mat["f0_std"] == est.f0_std
    assert mat["waveform_std"] == est.waveform_std
    assert list(np.atleast_1d(mat["notes"])) == list(est.notes)
    assert mat["units"]["time"] == "s" and mat["units"]["force_std"] == "N"
    assert mat["units"]["f0"] == "Hz"
    raw = scipy.io.loadmat(written["mat"])                  # MATLAB's shapes: columns in time
    assert raw["time"].shape == (est.time.size, 1)
    assert raw["forces"].shape == (est.time.size, 3)
    assert not {"std", "run"} & set(raw)                    # no MATLAB function shadowed


def test_uff_round_trip(est, written):
    sets = pyuff.UFF(str(written["uff"])).read_sets()
    sets = sets if isinstance(sets, list) else [sets]
    columns = series_columns(est)
    assert [s["id1"] for s in sets] == list(columns)
    for s, (name, values) in zip(sets, columns.items(), strict=True):
        assert s["type"] == 58 and s["func_type"] == 1
        np.testing.assert_allclose(s["data"], values, rtol=1e-11,
                                   atol=1e-11 * np.abs(values).max(), err_msg=name)
        np.testing.assert_allclose(s["x"], est.time, rtol=0, atol=1e-9)
        assert s["abscissa_spec_data_type"] == 17 and s["abscissa_axis_units_lab"] == "s"
        assert s["ordinate_spec_data_type"] == 13 and s["ordinate_axis_units_lab"] == "N"
        assert s["ordinate_force_unit_exp"] == 1 and s["ordinate_len_unit_exp"] == 0
        assert s["id4"] == "run paper"
    by_name = {s["id1"]: s for s in sets}
    assert by_name["F2_std"]["id2"] == "Force  std"
    assert by_name["F2_std"]["rsp_node"] == by_name["F2"]["rsp_node"] == 2
    assert by_name["total_static"]["rsp_node"] == 3
    run = read_run(written["uff"])                           # channels named by ID line 1
    assert list(run.channels) == list(columns)
    np.testing.assert_allclose(run.t0, est.time[0], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# refusals and atomicity


def test_unknown_format_writes_nothing(est, tmp_path):
    with pytest.raises(InputError, match="'xls'"):
        write_estimate(est, tmp_path, fmt="xls")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("fmt", ["csv", "hdf5", "mat", "uff"])
def test_a_failed_write_leaves_neither_file(est, tmp_path, monkeypatch, fmt):
    """The series half written, then an error: no series, no JSON, no temporary file."""
    def half_then_fail(est, path, fmt, columns=None):
        Path(path).write_bytes(b"half")
        raise KeyboardInterrupt

    monkeypatch.setattr("forcecal.io.results.write_series", half_then_fail)
    with pytest.raises(KeyboardInterrupt):
        write_estimate(est, tmp_path / "out", fmt=fmt)
    assert not [p for p in (tmp_path / "out").iterdir()]


def test_an_earlier_output_survives_a_failed_write(est, tmp_path, monkeypatch):
    write_estimate(est, tmp_path, fmt="mat")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("scipy.io.savemat", fail)
    with pytest.raises(OSError, match="disk full"):
        write_estimate(est, tmp_path, fmt="mat")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_a_force_named_like_another_columns_is_refused(est):
    twin = dataclasses.replace(est, force_names=("F1", "F1_std"))
    with pytest.raises(InputError, match="F1_std"):
        series_columns(twin)


# --------------------------------------------------------------------------------------------
# a long series: made, checked and written a block of rows at a time


LONG_ROWS = 600_000
"""Rows of the long series: about nine blocks of ``result_formats.SERIES_ROWS``."""


def long_estimate(est, n: int):
    """``est`` over ``n`` samples at 10 kHz: its phasors, random series (a long run's)."""
    rng = np.random.default_rng(3)
    n_f = len(est.force_names)
    return dataclasses.replace(est, time=est.time[0] + np.arange(n) / 10_000.0,
                               series=rng.standard_normal((n_f, n)),
                               static_series=rng.standard_normal((n_f, n)))


def test_a_block_of_the_columns_holds_the_whole_s_values(est):
    long = long_estimate(est, 140_000)
    whole = series_columns(long)
    for start, stop in ((0, 65_536), (1_000, 70_000), (131_072, None)):
        part = series_columns(long, start, stop)
        assert list(part) == list(whole)
        for name, values in part.items():
            np.testing.assert_array_equal(values, whole[name][start:stop])


def test_a_long_series_is_written_in_the_memory_of_a_few_blocks(est, tmp_path):
    """The peak of the memory writing allocates, in channel lengths: about 2.5 (6.4 when the
    columns were made whole), the values those of the whole columns."""
    long = long_estimate(est, LONG_ROWS)
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        path, _ = write_estimate(long, tmp_path, fmt="hdf5")
        peak = tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()
    assert peak / (8 * LONG_ROWS) < 4, peak / (8 * LONG_ROWS)
    with h5py.File(path, "r") as h5:
        for name, values in series_columns(long).items():
            np.testing.assert_array_equal(h5[name][()], values)


def test_csv_written_in_blocks_is_the_table_of_the_whole_columns(est, tmp_path):
    long = long_estimate(est, 70_000)                         # two blocks of rows
    blocks = result_formats.write_series(long, tmp_path / "blocks.csv", "csv")
    whole = write_table_csv(tmp_path / "whole.csv", long.time, series_columns(long))
    assert blocks.read_bytes() == whole.read_bytes()


# --------------------------------------------------------------------------------------------
# the command


@pytest.fixture(scope="module")
def lab_files(paper_dir, short, tmp_path_factory) -> tuple[Path, Path, Path]:
    """(rig.toml, MODEL.json, the short run as CSV)."""
    _, model, run = short
    folder = tmp_path_factory.mktemp("lab")
    return (paper_dir / "rig.toml", model.save(folder / "model.json"),
            write_run_csv(run, folder / "paper.csv"))


@pytest.mark.parametrize("fmt", ["mat", "uff"])
def test_reconstruct_format_option(lab_files, est, tmp_path, capsys, fmt):
    rig, model, run = lab_files
    out = tmp_path / "out"
    code = main(["reconstruct", str(rig), str(model), str(run), "-o", str(out), "--format", fmt])
    assert code == 0, capsys.readouterr().err
    name = f"paper{SERIES_SUFFIXES[fmt]}"
    assert sorted(p.name for p in out.iterdir()) == sorted([name, "paper.json"])
    assert f"{out / name}: f0" in capsys.readouterr().out
    assert json.loads((out / "paper.json").read_text())["series"]["format"] == fmt


def test_reconstruct_refuses_an_unknown_format(lab_files, tmp_path, capsys):
    rig, model, run = lab_files
    out = tmp_path / "out"
    code = main(["reconstruct", str(rig), str(model), str(run), "-o", str(out), "--format", "xls"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "xls" in err
    assert not out.exists()


def test_the_command_offers_every_format():
    """The command line's choices are the writer's formats."""
    import argparse

    from forcecal.cli import parser as cli_parser

    parser = argparse.ArgumentParser()
    cli_parser._reconstruct_parser(parser.add_subparsers(), argparse.HelpFormatter)
    action = next(a for a in parser._subparsers._group_actions[0].choices["reconstruct"]._actions
                  if a.dest == "format")
    assert tuple(action.choices) == SERIES_FORMATS and action.default == SERIES_FORMATS[0]


def test_notes_reach_every_self_describing_format(est, tmp_path):
    notes = ("harmonic 3: no shape in the scan model", "sensor χ² = 4.2, above 3")
    noted = dataclasses.replace(est, notes=notes)
    h5_path, _ = write_estimate(noted, tmp_path / "h5", fmt="hdf5")
    with h5py.File(h5_path, "r") as h5:
        assert [n.decode() if isinstance(n, bytes) else n for n in h5.attrs["notes"]] \
            == list(notes)
    mat_path, _ = write_estimate(noted, tmp_path / "mat", fmt="mat")
    assert list(scipy.io.loadmat(mat_path, simplify_cells=True)["notes"]) == list(notes)
