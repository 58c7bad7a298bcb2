"""Run recordings (CSV, TDMS, HDF5), result tables and the clipping check."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from nptdms import ChannelObject, TdmsWriter

from forcecal.errors import DataError, InputError
from forcecal.io.run_files import (
    read_run,
    read_table_csv,
    write_run_csv,
    write_run_hdf5,
    write_run_tdms,
    write_table_csv,
)
from forcecal.records import Run
from forcecal.signals.checks import MIN_SAMPLES, check_clipping

WRITERS = {".csv": write_run_csv, ".tdms": write_run_tdms, ".h5": write_run_hdf5}


def make_run(rng, n=1000, fs=2000.0, t0=0.0, names=("R1", "R2", "s1", "i")):
    t = t0 + np.arange(n) / fs
    channels = {
        name: (k + 1) * np.sin(2 * np.pi * 40 * t + k) + 0.01 * rng.standard_normal(n)
        for k, name in enumerate(names)
    }
    return Run(channels=channels, fs=fs, t0=t0, name="made", source="made")


def write_csv(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def csv_text(time, **columns) -> str:
    lines = [",".join(["time", *columns])]
    for k, t in enumerate(time):
        lines.append(",".join([repr(float(t))] + [repr(float(c[k])) for c in columns.values()]))
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# round trips


@pytest.mark.parametrize("suffix", [".csv", ".tdms", ".h5"])
def test_run_round_trip(tmp_path, suffix):
    run = make_run(np.random.default_rng(21), t0=0.125)
    path = WRITERS[suffix](run, tmp_path / f"r07{suffix}")
    back = read_run(path)
    assert back.name == "r07"
    assert back.source == str(path)
    assert list(back.channels) == list(run.channels)
    for name, values in run.channels.items():
        np.testing.assert_array_equal(back.channels[name], values)
    assert back.fs == pytest.approx(run.fs, rel=1e-12)
    assert back.t0 == pytest.approx(run.t0, rel=1e-12)
    assert not list(tmp_path.glob("*.part"))


def test_hdf5_run_keeps_t0_and_fs_exactly(tmp_path):
    run = make_run(np.random.default_rng(22), fs=5120.0, t0=-0.5)
    back = read_run(write_run_hdf5(run, tmp_path / "r.hdf5"))
    assert (back.fs, back.t0) == (5120.0, -0.5)


def test_table_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(23)
    time = 0.3 + np.arange(200) / 3000.0
    columns = {"F1": rng.standard_normal(200) * 1e3, "total": rng.standard_normal(200) * 1e-9}
    path = write_table_csv(tmp_path / "r.forces.csv", time, columns)
    assert path.read_text().splitlines()[0] == "time,F1,total"
    t, back = read_table_csv(path)
    np.testing.assert_array_equal(t, time)
    assert list(back) == ["F1", "total"]
    for name in columns:
        np.testing.assert_array_equal(back[name], columns[name])


def test_table_csv_refuses_bad_columns(tmp_path):
    with pytest.raises(InputError, match="column name 'a,b' cannot be written"):
        write_table_csv(tmp_path / "t.csv", np.arange(3.0), {"a,b": np.zeros(3)})
    with pytest.raises(InputError, match="column 'F1' has 2 values, time has 3"):
        write_table_csv(tmp_path / "t.csv", np.arange(3.0), {"F1": np.zeros(2)})
    assert not (tmp_path / "t.csv").exists()


def test_csv_with_rounded_time_stamps_is_accepted(tmp_path):
    """Stamps written with 6 decimals at 3 kHz deviate by up to 1e-6 s: rounding, not jitter."""
    rng = np.random.default_rng(24)
    time = np.round(np.arange(400) / 3000.0, 6)
    values = rng.standard_normal(400).tolist()
    lines = ["time,a"] + [f"{t:.6f},{v!r}" for t, v in zip(time, values, strict=True)]
    run = read_run(write_csv(tmp_path / "r.csv", "\n".join(lines) + "\n"))
    assert run.fs == pytest.approx(3000.0, rel=1e-5)


def test_csv_with_six_significant_digit_time_is_accepted(tmp_path):
    """'%.6g' stamps at 10 kHz: 1e-5 s resolution above 1 s, finer below."""
    time = np.arange(30000) / 10000.0
    lines = ["time,a"] + [f"{t:.6g},{float(np.sin(t))!r}" for t in time]
    run = read_run(write_csv(tmp_path / "r.csv", "\n".join(lines) + "\n"))
    assert run.fs == pytest.approx(10000.0, rel=1e-9)


def test_repeated_stamp_in_coarse_csv_is_found(tmp_path):
    time = np.round(np.arange(50) / 100.0, 2)
    time[20:] -= 0.01  # stamp 0.19 written twice, one step lost
    lines = ["time,a"] + [f"{t:.2f},1.0" for t in time]
    with pytest.raises(DataError, match=r"not uniform: the step of 0 s at t=0\.19 s \(row 21\)"):
        read_run(write_csv(tmp_path / "r.csv", "\n".join(lines) + "\n"))


def test_csv_with_bom_blank_lines_and_spaces(tmp_path):
    time = np.arange(20) / 100.0
    body = csv_text(time, a=np.ones(20)).replace(",", ", ").replace("\n", "\n\n", 3)
    path = tmp_path / "r.csv"
    path.write_bytes("\ufeff".encode() + body.encode())
    run = read_run(path)
    assert list(run.channels) == ["a"]
    assert run.fs == pytest.approx(100.0)


def test_tdms_sampling_from_a_time_channel(tmp_path):
    fs, n = 1000.0, 64
    time = 2.0 + np.arange(n) / fs
    path = tmp_path / "r.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [ChannelObject("g", "time", time), ChannelObject("g", "s1", np.cos(time))]
        )
    run = read_run(path)
    assert list(run.channels) == ["s1"]
    assert run.fs == pytest.approx(fs, rel=1e-9)
    assert run.t0 == 2.0


def test_hdf5_sampling_from_a_time_dataset(tmp_path):
    path = tmp_path / "r.h5"
    with h5py.File(path, "w") as h5:
        h5["time"] = np.arange(32) / 50.0
        h5["i"] = np.ones(32)
    run = read_run(path)
    assert run.fs == pytest.approx(50.0)
    assert list(run.channels) == ["i"]


# --------------------------------------------------------------------------------------------
# error paths


def test_missing_file_and_unknown_suffix(tmp_path):
    with pytest.raises(InputError, match=r"run '.*r07\.csv': file does not exist"):
        read_run(tmp_path / "r07.csv")
    path = tmp_path / "r07.txt"
    path.write_text("time,a\n")
    with pytest.raises(InputError, match=r"r07\.txt': unknown file type.*\.csv, \.tdms"):
        read_run(path)


def test_empty_file_and_header_only(tmp_path):
    with pytest.raises(DataError, match=r"r\.csv': the file is empty"):
        read_run(write_csv(tmp_path / "r.csv", "\n\n"))
    with pytest.raises(DataError, match=r"r\.csv': a header but no data rows"):
        read_run(write_csv(tmp_path / "r.csv", "time,a,b\n"))


def test_non_numeric_cell_names_row_and_column(tmp_path):
    time = np.arange(40) / 100.0
    text = csv_text(time, a=np.zeros(40), s2=np.ones(40)).splitlines()
    text[7] = text[7].rsplit(",", 1)[0] + ",oops"  # row 8 of the file (header is row 1)
    with pytest.raises(DataError, match=r"r\.csv': row 8, column 's2': 'oops' is not a number"):
        read_run(write_csv(tmp_path / "r.csv", "\n".join(text) + "\n"))


def test_nan_samples_are_counted_and_located(tmp_path):
    fs, n = 1000.0, 1000
    s2 = np.sin(np.arange(n) / 10.0)
    s2[310:722] = np.nan
    path = write_csv(tmp_path / "r07.csv", csv_text(np.arange(n) / fs, s1=np.ones(n), s2=s2))
    message = r"run '.*r07\.csv': channel 's2' has 412 NaN samples starting at t=0\.31 s"
    with pytest.raises(DataError, match=message):
        read_run(path)


@pytest.mark.parametrize("suffix", [".csv", ".tdms", ".h5"])
def test_infinite_samples_in_every_format(tmp_path, suffix):
    run = make_run(np.random.default_rng(25), n=100, fs=100.0, names=("a", "b"))
    run.channels["b"][50:53] = np.inf
    path = WRITERS[suffix](run, tmp_path / f"r{suffix}")
    with pytest.raises(DataError, match=r"channel 'b' has 3 infinite samples starting at t=0\.5 s"):
        read_run(path)


def test_dropped_sample_is_located(tmp_path):
    time = np.delete(np.arange(100) / 100.0, 60)  # sample at t = 0.60 s missing
    path = write_csv(tmp_path / "r.csv", csv_text(time, a=np.zeros(99)))
    message = r"time stamps are not uniform: the step of 0\.02 s at t=0\.59 s \(row 61\)"
    with pytest.raises(DataError, match=message):
        read_run(path)


def test_jittered_time_channel_in_tdms(tmp_path):
    time = np.arange(64) / 1000.0
    time[20] += 1e-5
    path = tmp_path / "r.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment([ChannelObject("g", "time", time), ChannelObject("g", "a", time)])
    with pytest.raises(DataError, match=r"not uniform.*\(sample 19\)"):
        read_run(path)


def test_too_few_samples(tmp_path):
    n = MIN_SAMPLES - 1
    path = write_csv(tmp_path / "r.csv", csv_text(np.arange(n) / 10.0, a=np.zeros(n)))
    with pytest.raises(DataError, match=rf"r\.csv': {n} samples; at least {MIN_SAMPLES}"):
        read_run(path)


@pytest.mark.parametrize(
    ("text", "error", "message"),
    [
        ("sample,a\n0,1\n", InputError, "the first column is 'sample'; expected 'time'"),
        ("time\n0\n", DataError, "no channel columns after 'time'"),
        ("time,a,a\n0,1,2\n", InputError, "column 'a' appears twice"),
        ("time,,b\n0,1,2\n", InputError, "column 2 has no name"),
        ("time,a\n0,1\n0.1,2,3\n", DataError, "row 3 has 3 cells, the header 2"),
    ],
)
def test_bad_csv_layouts(tmp_path, text, error, message):
    with pytest.raises(error, match=message):
        read_run(write_csv(tmp_path / "r.csv", text))


def test_time_that_does_not_increase(tmp_path):
    time = np.arange(20)[::-1] / 10.0
    with pytest.raises(DataError, match="time stamps do not increase"):
        read_run(write_csv(tmp_path / "r.csv", csv_text(time, a=np.zeros(20))))


def test_tdms_without_sampling(tmp_path):
    path = tmp_path / "r.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment([ChannelObject("g", "a", np.zeros(32))])
    with pytest.raises(InputError, match=r"r\.tdms': no 'wf_increment' property and no 'time'"):
        read_run(path)


def test_tdms_with_two_groups(tmp_path):
    path = tmp_path / "r.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment([ChannelObject("g1", "a", np.zeros(32)), ChannelObject("g2", "b", [])])
        writer.write_segment([ChannelObject("g2", "b", np.zeros(32))])
    with pytest.raises(InputError, match=r"expected one group of channels, found 'g1', 'g2'"):
        read_run(path)


def test_tdms_channels_of_unequal_length(tmp_path):
    props = {"wf_increment": 0.001}
    path = tmp_path / "r.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [
                ChannelObject("g", "a", np.zeros(32), properties=props),
                ChannelObject("g", "b", np.zeros(30), properties=props),
            ]
        )
    with pytest.raises(DataError, match="channel 'b' has 30 samples, channel 'a' has 32"):
        read_run(path)


def test_hdf5_without_sampling_and_with_a_matrix(tmp_path):
    path = tmp_path / "r.h5"
    with h5py.File(path, "w") as h5:
        h5["a"] = np.zeros(32)
    with pytest.raises(InputError, match="no 'fs' attribute on the file root and no 'time'"):
        read_run(path)
    with h5py.File(path, "w") as h5:
        h5.attrs["fs"] = 100.0
        h5["a"] = np.zeros((32, 2))
    with pytest.raises(DataError, match=r"dataset 'a' is not a numeric 1-D channel"):
        read_run(path)


@pytest.mark.parametrize("suffix", [".tdms", ".h5"])
def test_corrupt_binary_files(tmp_path, suffix):
    path = tmp_path / f"r{suffix}"
    path.write_bytes(b"\x00\x01garbage" * 10)
    with pytest.raises(InputError, match=rf"r{suffix}': not a readable"):
        read_run(path)


def test_read_table_csv_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_table_csv(tmp_path / "none.csv")
    with pytest.raises(DataError, match=r"row 3, column 'F1': 'x' is not a number"):
        read_table_csv(write_csv(tmp_path / "t.csv", "time,F1\n0,1\n1,x\n"))


# --------------------------------------------------------------------------------------------
# clipping


def sine(n=20000, fs=5000.0, f=40.0, amplitude=1.0, offset=0.0, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    return offset + amplitude * np.sin(2 * np.pi * f * t + 0.3) + noise * rng.standard_normal(n)


@pytest.mark.parametrize("offset", [0.0, 0.5, -3.0, 1e3])
@pytest.mark.parametrize("amplitude", [1e-3, 1.0, 50.0])
def test_clean_noisy_sinusoids_are_not_clipped(offset, amplitude):
    x = sine(amplitude=amplitude, offset=offset * amplitude, noise=0.01 * amplitude)
    check_clipping(x, "i", "r.csv", 5000.0)  # raises on a false positive


@pytest.mark.parametrize("quantum", [1e-3, 1e-2, 0.05])
def test_quantised_sinusoids_are_not_clipped(quantum):
    x = np.round(sine(offset=0.2) / quantum) * quantum
    check_clipping(x, "i", "r.csv", 5000.0)


def test_sampling_locked_to_the_period_is_not_clipped():
    x = np.sin(2 * np.pi * np.arange(6400) / 64)  # the peak value recurs once per period
    check_clipping(x, "i", "r.csv", 6400.0)


def test_constant_channel_is_not_clipping():
    check_clipping(np.full(100, 3.0), "c", "r.csv", 100.0)


@pytest.mark.parametrize("quantum", [None, 1e-3])
def test_flat_top_at_the_maximum_is_found(quantum):
    x = np.minimum(sine(offset=0.5), 1.4)
    if quantum:
        x = np.round(x / quantum) * quantum
    message = r"run 'r07\.csv': channel 'i' is clipped: .* sit at its maximum 1\.4"
    with pytest.raises(DataError, match=message):
        check_clipping(x, "i", "r07.csv", 5000.0)


def test_flat_bottom_at_the_minimum_is_found():
    x = np.maximum(sine(amplitude=2.0, offset=-1.0), -2.9)
    with pytest.raises(DataError, match=r"channel 'R2' is clipped: .* minimum -2\.9"):
        check_clipping(x, "R2", "r.tdms", 5000.0)


def test_slight_clipping_is_found():
    """1 % of the samples held at the rail (5 per period): peaks cut 0.05 % below the crest."""
    x = sine(fs=20000.0, noise=0.0)
    level = np.quantile(x, 0.99)
    with pytest.raises(DataError, match="is clipped"):
        check_clipping(np.minimum(x, level), "i", "r.csv", 20000.0)


@settings(max_examples=60, deadline=None)
@given(
    amplitude=st.floats(1e-3, 1e3),
    offset=st.floats(-2.0, 2.0),
    frequency=st.floats(5.0, 400.0),
    phase=st.floats(0.0, 6.3),
    bits=st.integers(6, 16),
)
def test_no_false_alarm_on_quantised_sinusoids(amplitude, offset, frequency, phase, bits):
    """An ADC of ``bits`` bits spanning 1.25 times the signal range never looks clipped."""
    t = np.arange(8000) / 5000.0
    x = amplitude * (offset + np.sin(2 * np.pi * frequency * t + phase))
    quantum = 2.5 * amplitude / 2**bits
    check_clipping(np.round(x / quantum) * quantum, "i", "r.csv", 5000.0)
