"""Lab data in: UFF time-record runs, TDMS files of several groups, the rig's channel map, CSV
as DAQ software exports it, and folders of runs.

Every file here is written by the third-party library the format belongs to (pyuff, npTDMS)
or as text the way lab software writes it, never by forcecal's own writers.
"""

from __future__ import annotations

import gc
import re
import time
import tomllib
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import pyuff
import tomli_w
from nptdms import ChannelObject, TdmsWriter

from forcecal.cli.main import main
from forcecal.errors import DataError, InputError, RigError
from forcecal.io.run_files import read_run, read_table_csv, run_paths
from forcecal.rig import load_rig, parse_rig, rig_to_dict
from forcecal.schema.channels import node_channel, parse_node_channel

THIRD_PARTY = Path(__file__).resolve().parents[3] / "shared" / "data" / "third-party-uff"
SHORT_SECONDS = 0.4
FORCE_COLUMNS = ["F1", "F2", "total", "F1_static", "F2_static", "total_static"]
UFF_RTOL = 5e-12  # pyuff's ASCII values: %20.11e


# --------------------------------------------------------------------------------------------
# files as the lab's software writes them


def write_uff(path: Path, records: list[dict], fs: float, t0: float = 0.0,
              binary: bool = False) -> Path:
    """Time records written by pyuff: each record a dict of ``data`` and any prepare_58 keys
    (``id1``, ``rsp_node``, ``rsp_dir``, ``ordinate_axis_units_lab``...)."""
    sets = []
    for rec in records:
        rec = dict(rec)
        data = np.asarray(rec.pop("data"))
        fields = dict(binary=int(binary), func_type=1, rsp_node=1, rsp_dir=3, ref_node=0,
                      ref_dir=0, id1="NONE", abscissa_spacing=1, abscissa_inc=1.0 / fs,
                      abscissa_spec_data_type=17, abscissa_axis_units_lab="s",
                      ordinate_spec_data_type=0, orddenom_spec_data_type=0,
                      z_axis_spec_data_type=0)
        fields.update(rec)
        sets.append(pyuff.prepare_58(data=data, x=t0 + np.arange(data.size) / fs, **fields))
    path.unlink(missing_ok=True)
    uff = pyuff.UFF(str(path))
    with warnings.catch_warnings():  # pyuff leaves a reopened handle to the collector
        warnings.simplefilter("ignore", ResourceWarning)
        for dataset in sets:  # one at a time: pyuff mangles several 58b sets in one call
            uff.write_sets([dataset], mode="add")
        gc.collect()
    return path


def write_tdms(path: Path, groups: dict[str, dict[str, np.ndarray]], fs: float,
               t0: float = 0.0) -> Path:
    """A TDMS file written by npTDMS: one or more groups of waveform channels."""
    props = {"wf_increment": 1.0 / fs, "wf_start_offset": t0}
    objects = [ChannelObject(g, name, np.asarray(v, dtype=float), properties=props)
               for g, channels in groups.items() for name, v in channels.items()]
    with TdmsWriter(path) as writer:
        writer.write_segment(objects)
    return path


def write_text(path: Path, header: list[str], columns: list[np.ndarray], sep: str = ",",
               decimal: str = ".", units: list[str] | None = None) -> Path:
    """A CSV as lab software writes it: any delimiter, decimal comma, a units row."""
    def cell(v: float) -> str:
        text = repr(float(v))
        return text.replace(".", decimal) if decimal != "." else text

    lines = [sep.join(header)]
    if units is not None:
        lines.append(sep.join(units))
    lines += [sep.join(cell(c[k]) for c in columns) for k in range(len(columns[0]))]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def sines(n: int = 400, fs: float = 2000.0, names=("R1", "R2", "s1", "i")) -> dict:
    rng = np.random.default_rng(7)
    t = np.arange(n) / fs
    return {name: (k + 1) * np.sin(2 * np.pi * 40 * t + k) + 0.01 * rng.standard_normal(n)
            for k, name in enumerate(names)}


RIG = """\
[structure]
kind = "beam"
length = 0.6
mass_per_length = 3.768

[[gauges]]
name = "R1"
x = 0.0

[[gauges]]
name = "R2"
x = 0.6

[[forces]]
name = "F1"
x = 0.25

[[sensors]]
name = "s1"
x = 0.1
scale = SCALE

[actuator]
current = "i"

[acquisition]
frequency = 40.0
"""


def rig_file(tmp_path: Path, extra: str = "", scale: str = "1.0") -> Path:
    path = tmp_path / "rig.toml"
    path.write_text(RIG.replace("SCALE", scale) + extra, encoding="utf-8")
    return path


# --------------------------------------------------------------------------------------------
# UFF runs (written by pyuff)


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "58b"])
def test_uff_run_named_by_its_id_lines(tmp_path, binary):
    channels = sines(fs=5120.0)
    records = [dict(id1=name, rsp_node=k + 1, data=v) for k, (name, v) in
               enumerate(channels.items())]
    path = write_uff(tmp_path / "r07.uff", records, fs=5120.0, t0=0.25, binary=binary)
    run = read_run(path)
    assert (run.name, run.source) == ("r07", str(path))
    assert list(run.channels) == list(channels)
    assert run.fs == pytest.approx(5120.0, rel=5e-6)  # the increment as written: 6 digits
    assert run.t0 == pytest.approx(0.25, abs=1e-12)
    for name, values in channels.items():
        if binary:
            np.testing.assert_array_equal(run.channels[name], values)
        else:
            np.testing.assert_allclose(run.channels[name], values, rtol=UFF_RTOL, atol=1e-300)


def test_uff_run_named_by_node_and_direction_and_mapped_by_the_rig(tmp_path):
    channels = sines()
    nodes = {"R1": (1, 3), "R2": (2, 3), "s1": (12, 3), "i": (99, 0)}
    records = [dict(id1="Time Response", id2=f"Point {nodes[n][0]}", rsp_node=nodes[n][0],
                    rsp_dir=nodes[n][1], data=v) for n, v in channels.items()]
    path = write_uff(tmp_path / "r.unv", records, fs=2000.0)
    raw = read_run(path)
    assert list(raw.channels) == ["node 1 +Z", "node 2 +Z", "node 12 +Z", "node 99"]
    extra = """
[channels]
R1 = "node 1 +Z"
R2 = { node = 2, direction = "+Z" }
s1 = "Point 12"
i = { node = 99 }
"""
    rig = load_rig(rig_file(tmp_path, extra))
    run = read_run(path, rig)
    assert list(run.channels) == ["R1", "R2", "s1", "i"]
    for name, values in channels.items():
        np.testing.assert_allclose(run.channels[name], values, rtol=UFF_RTOL, atol=1e-300)


def test_uff_run_mapped_channel_missing(tmp_path):
    records = [dict(id1=n, rsp_node=k + 1, data=v) for k, (n, v) in enumerate(sines().items())]
    path = write_uff(tmp_path / "r.uff", records, fs=2000.0)
    rig = rig_file(tmp_path, '\n[channels]\ns1 = "node 12 -Y"\n')
    message = (rf"run '.*r\.uff': channel 'node 12 -Y' \(rig '{re.escape(str(rig))}', key "
               r"'channels\.s1'\) is not in the file; it holds 'R1', 'R2', 's1', 'i'")
    with pytest.raises(DataError, match=message):
        read_run(path, load_rig(rig))


def test_uff_run_refusals(tmp_path):
    ch = sines()
    spectra = [dict(func_type=4, id1="FRF", data=ch["R1"].astype(complex))]
    path = write_uff(tmp_path / "a.uff", spectra, fs=2000.0)
    with pytest.raises(InputError, match=r"a\.uff': none of the 1 dataset-58 records is a time "
                                         r"record \(function type 1; found function types 4\)"):
        read_run(path)
    twice = [dict(id1="Vib", rsp_node=3, data=ch["R1"]), dict(id1="Vib", rsp_node=3,
                                                             data=ch["R2"])]
    with pytest.raises(DataError, match=r"b\.uff': time records 1 and 2 are both 'node 3 \+Z'"):
        read_run(write_uff(tmp_path / "b.uff", twice, fs=2000.0))
    ms = [dict(id1="a", data=ch["R1"]), dict(id1="b", data=ch["R2"],
                                              abscissa_axis_units_lab="h")]
    with pytest.raises(InputError, match=r"c\.uff': record 'b' gives its time in 'h'"):
        read_run(write_uff(tmp_path / "c.uff", ms, fs=2000.0))
    short = [dict(id1="a", data=ch["R1"][:10])]
    with pytest.raises(DataError, match=r"d\.uff': 10 samples; at least 16"):
        read_run(write_uff(tmp_path / "d.uff", short, fs=2000.0))


def test_uff_records_at_two_rates_are_refused(tmp_path):
    ch = sines()
    a = write_uff(tmp_path / "a.uff", [dict(id1="a", data=ch["R1"])], fs=2000.0)
    b = write_uff(tmp_path / "b.uff", [dict(id1="b", data=ch["R2"])], fs=1000.0)
    path = tmp_path / "r.uff"
    path.write_bytes(a.read_bytes() + b.read_bytes())
    with pytest.raises(DataError, match=r"record 'b' is sampled every 0\.001 s, record 'a' "
                                        r"every 0\.0005 s"):
        read_run(path)


def test_uff_unit_label_checked_against_the_scale(tmp_path):
    ch = sines()
    records = [dict(id1=n, rsp_node=k + 1, data=v, ordinate_axis_units_lab="mm" if n == "s1"
                    else "NONE") for k, (n, v) in enumerate(ch.items())]
    path = write_uff(tmp_path / "r.uff", records, fs=2000.0)
    with pytest.raises(DataError, match=r"channel 's1' is in mm, but rig .* key "
                                        r"'sensors\[0\]\.scale' = 1 reads it as m"):
        read_run(path, load_rig(rig_file(tmp_path)))
    assert list(read_run(path, load_rig(rig_file(tmp_path, scale="1e-3"))).channels) == list(ch)


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
@pytest.mark.parametrize("name", ["Sample_UFF58_ascii.uff", "Sample_UFF58b_bin.uff"])
def test_third_party_time_record_is_a_run(name):
    run = read_run(THIRD_PARTY / name)
    assert list(run.channels) == ["Mic 01.0Scalar"]
    assert run.fs == 65536.0 and run.n_samples == 79292


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
def test_third_party_short_record_is_refused_in_one_line():
    with pytest.raises(DataError, match=r"13 samples; at least 16"):
        read_run(THIRD_PARTY / "time-history-not-all-columns-filled.uff")


# --------------------------------------------------------------------------------------------
# TDMS with several groups (written by npTDMS)


def test_tdms_group_chosen_by_the_rig_or_the_caller(tmp_path):
    data, meta = sines(), sines(names=("temperature", "s1"))
    path = write_tdms(tmp_path / "r.tdms", {"Meta": meta, "Data": data}, fs=2000.0, t0=1.5)
    with pytest.raises(InputError, match=r"r\.tdms': expected one group of channels, found "
                                         r"'(Meta|Data)', '(Data|Meta)'; choose one with --group "
                                         r"NAME or \[acquisition\] group"):
        read_run(path)
    run = read_run(path, load_rig(rig_file(tmp_path, "group = \"Data\"\n")))
    assert list(run.channels) == list(data) and run.t0 == 1.5
    np.testing.assert_array_equal(run.channels["s1"], data["s1"])
    run = read_run(path, load_rig(rig_file(tmp_path, "group = \"Data\"\n")), group="Meta")
    assert list(run.channels) == ["temperature", "s1"]
    with pytest.raises(InputError, match=r"no group 'Raw' \(the group chosen for the runs\); "
                                         r"the file's groups: '(Meta|Data)', '(Data|Meta)'"):
        read_run(path, group="Raw")


def test_hdf5_group_chosen_by_the_rig_or_the_caller(tmp_path):
    """An HDF5 file written by h5py as a DAQ logger would: a setup group and one group of
    channels per acquisition, the rate on each group."""
    data, meta = sines(), sines(names=("temperature", "s1"))
    path = tmp_path / "r.h5"
    with h5py.File(path, "w") as h5:
        h5.create_group("setup").attrs["operator"] = "J. Doe"
        for name, channels, t0 in (("runs/Data", data, 1.5), ("runs/Meta", meta, 0.0)):
            g = h5.create_group(name)
            g.attrs["fs"], g.attrs["t0"] = 2000.0, t0
            for ch, v in channels.items():
                g.create_dataset(ch, data=v)
    with pytest.raises(InputError, match=r"r\.h5': expected one group of channels, found "
                                         r"'runs/Data', 'runs/Meta'; choose one with --group"):
        read_run(path)
    run = read_run(path, load_rig(rig_file(tmp_path, "group = \"runs/Data\"\n")))
    assert sorted(run.channels) == sorted(data) and run.t0 == 1.5 and run.fs == 2000.0
    np.testing.assert_array_equal(run.channels["s1"], data["s1"])
    run = read_run(path, group="runs/Meta")
    assert sorted(run.channels) == ["s1", "temperature"]
    with pytest.raises(InputError, match=r"no group 'Raw' \(the group chosen for the runs\); "
                                         r"the file's groups of datasets: 'runs/Data', "
                                         r"'runs/Meta'"):
        read_run(path, group="Raw")
    single = tmp_path / "one.h5"                  # one group of channels needs no choice
    with h5py.File(single, "w") as h5:
        g = h5.create_group("Data")
        g.attrs["fs"] = 2000.0
        for ch, v in data.items():
            g.create_dataset(ch, data=v)
    np.testing.assert_array_equal(read_run(single).channels["R1"], data["R1"])


def test_tdms_daq_names_mapped_by_the_rig(tmp_path):
    ch = sines()
    daq = {f"cDAQ1Mod1/ai{k}": v for k, v in enumerate(ch.values())}
    path = write_tdms(tmp_path / "r.tdms", {"Data": daq, "Log": {"note": np.zeros(4)}},
                      fs=2000.0)
    extra = ('group = "Data"\n\n[channels]\nR1 = "cDAQ1Mod1/ai0"\nR2 = "cDAQ1Mod1/ai1"\n'
             's1 = "cDAQ1Mod1/ai2"\ni = "cDAQ1Mod1/ai3"\n')
    run = read_run(path, load_rig(rig_file(tmp_path, extra)))
    assert list(run.channels) == ["R1", "R2", "s1", "i"]
    for name, values in ch.items():
        np.testing.assert_array_equal(run.channels[name], values)
    bad = rig_file(tmp_path, extra.replace("ai3", "ai7"))
    message = (rf"channel 'cDAQ1Mod1/ai7' \(rig '{re.escape(str(bad))}', key 'channels\.i'\) "
               "is not in the file")
    with pytest.raises(DataError, match=message):
        read_run(path, load_rig(bad))


# --------------------------------------------------------------------------------------------
# the rig's [channels] and acquisition.group


def test_channel_map_forms_and_round_trip(tmp_path):
    extra = """group = "Data"

[channels]
R1 = "cDAQ1Mod1/ai0"
R2 = "Node 7 z"
s1 = { node = 12, direction = -3 }
i = { node = 4, direction = "RX" }
"""
    rig = load_rig(rig_file(tmp_path, extra))
    assert rig.run_group == "Data"
    assert dict(rig.channel_map) == {"R1": "cDAQ1Mod1/ai0", "R2": "node 7 +Z",
                                     "s1": "node 12 -Z", "i": "node 4 +RX"}
    again = parse_rig(tomllib.loads(tomli_w.dumps(rig_to_dict(rig))), source="again")
    assert again.channel_map == rig.channel_map and again.run_group == "Data"
    assert parse_node_channel("node 3 -y") == (3, -2) and node_channel(3, -2) == "node 3 -Y"
    assert parse_node_channel("cDAQ1Mod1/ai0") is None


@pytest.mark.parametrize(("extra", "key", "what"), [
    ('s9 = "ai0"', "channels.s9", "is not a channel of the rig; expected one of R1, R2, s1, i"),
    ('F1 = "ai0"', "channels.F1", "is not a channel of the rig"),
    ('s1 = "ai0"\nR1 = "ai0"', "channels.R1", "= 'ai0' is also the channel of 'channels.s1'"),
    ("s1 = 3", "channels.s1", "must be a channel name of the run files"),
    ('s1 = ""', "channels.s1", "must be a channel name"),
    ('s1 = "node 12 +Q"', "channels.s1", "= 'node 12 +Q' is not 'node N' followed by a "
     "direction"),
    ('s1 = { node = 12, direction = "up" }', "channels.s1.direction", "must be one of +X"),
    ("s1 = { node = -1 }", "channels.s1.node", "must be a node number"),
    ('s1 = { node = 1, dof = 3 }', "channels.s1.dof", "is not a key of a node channel"),
])
def test_bad_channel_maps_name_the_key(tmp_path, extra, key, what):
    path = rig_file(tmp_path, f"\n[channels]\n{extra}\n")
    with pytest.raises(RigError, match=re.escape(f"rig '{path}': key '{key}' {what}")):
        load_rig(path)


# --------------------------------------------------------------------------------------------
# CSV as lab software writes it


def test_semicolon_decimal_comma_and_units_row(tmp_path):
    ch = sines()
    t = 0.5 + np.arange(400) / 2000.0
    path = write_text(tmp_path / "r.csv", ["Time", *ch], [t, *ch.values()], sep=";",
                      decimal=",", units=["s", "N", "N", "m", "A"])
    run = read_run(path)
    assert list(run.channels) == list(ch)
    assert run.fs == pytest.approx(2000.0, rel=1e-9) and run.t0 == 0.5
    for name, values in ch.items():
        np.testing.assert_array_equal(run.channels[name], values)


def test_tab_delimiter_units_in_the_header_and_time_in_ms(tmp_path):
    ch = sines()
    t_ms = np.arange(400) / 2.0
    header = ["Time [ms]", "R1 (N)", "R2 [N]", "s1 [mm]", "i [A]"]
    path = write_text(tmp_path / "r.csv", header, [t_ms, *ch.values()], sep="\t")
    run = read_run(path)
    assert list(run.channels) == list(ch)
    assert run.fs == pytest.approx(2000.0, rel=1e-9)
    rig = load_rig(rig_file(tmp_path, scale="0.001"))
    assert list(read_run(path, rig).channels) == list(ch)
    with pytest.raises(DataError, match=r"r\.csv': channel 's1' is in mm, but rig .* key "
                                        r"'sensors\[0\]\.scale' = 1 reads it as m; expected a "
                                        r"scale near 0\.001"):
        read_run(path, load_rig(rig_file(tmp_path)))


@pytest.mark.parametrize("header", ["Time (s)", "time [s]", "TIME", "time [us]"])
def test_time_column_spellings(tmp_path, header):
    factor = 1e6 if "us" in header else 1.0
    t = np.arange(100) / 1000.0 * factor
    path = write_text(tmp_path / "r.csv", [header, "a [V]"], [t, np.sin(t)])
    assert read_run(path).fs == pytest.approx(1000.0, rel=1e-9)


def test_names_with_parentheses_stay_names(tmp_path):
    t = np.arange(20) / 10.0
    path = write_text(tmp_path / "r.csv", ["time", "phi(1)", "R1 (2)", "Dev1/ai0 (V)"],
                      [t, t, t, t])
    run = read_run(path)
    assert list(run.channels) == ["phi(1)", "R1 (2)", "Dev1/ai0"]


def test_time_unit_not_understood(tmp_path):
    path = write_text(tmp_path / "r.csv", ["time [h]", "a"], [np.arange(20.0), np.ones(20)])
    with pytest.raises(InputError, match=r"r\.csv': the time column is in 'h'; expected s, ms"):
        read_run(path)


def test_units_row_disagreeing_with_the_header(tmp_path):
    path = write_text(tmp_path / "r.csv", ["time [s]", "a"], [np.arange(20.0), np.ones(20)],
                      units=["ms", "V"])
    with pytest.raises(InputError, match=r"column 'time' is in 's' by the header and in 'ms' by "
                                         "the units row"):
        read_run(path)


def test_bad_cell_in_a_decimal_comma_file_is_located(tmp_path):
    t = np.arange(40) / 100.0
    path = write_text(tmp_path / "r.csv", ["time", "a", "b"], [t, np.ones(40), np.zeros(40)],
                      sep=";", decimal=",", units=["s", "V", "V"])
    lines = path.read_text().splitlines()
    lines[9] = lines[9].rsplit(";", 1)[0] + ";1.234,5"   # row 10 of the file
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"row 10, column 'b': '1\.234,5' is not a number"):
        read_run(path)


def test_rounded_time_stamps_with_a_decimal_comma(tmp_path):
    t = np.arange(3000) / 3000.0
    lines = ["time;a"] + [f"{v:.6f};{float(np.sin(v))!r}".replace(".", ",") for v in t]
    path = tmp_path / "r.csv"
    path.write_text("\n".join(lines) + "\n")
    assert read_run(path).fs == pytest.approx(3000.0, rel=1e-5)


def test_table_with_units_reads_like_the_plain_table(tmp_path):
    t = np.arange(20) / 10.0
    a = write_text(tmp_path / "a.csv", ["time", "F1"], [t, t**2])
    b = write_text(tmp_path / "b.csv", ["time [ms]", "F1 [N]"], [t * 1e3, t**2], sep=";",
                   decimal=",")
    (ta, ca), (tb, cb) = read_table_csv(a), read_table_csv(b)
    np.testing.assert_allclose(tb, ta, rtol=1e-15)
    np.testing.assert_array_equal(cb["F1"], ca["F1"])


def test_csv_reads_as_fast_as_a_plain_numeric_loader(tmp_path):
    """A 6 MB run: no slower than numpy's loadtxt of the same numbers (it was 3 to 5 times
    slower with a CSV module parse)."""
    n = 50_000
    t = np.arange(n) / 10000.0
    ch = sines(n=n, fs=10000.0, names=("R1", "R2", "s1", "s2", "i", "phi"))
    path = write_text(tmp_path / "big.csv", ["time", *ch], [t, *ch.values()])

    def best(f) -> float:
        times = []
        for _ in range(3):
            start = time.perf_counter()
            f()
            times.append(time.perf_counter() - start)
        return min(times)

    ours = best(lambda: read_run(path))
    plain = best(lambda: np.loadtxt(path, delimiter=",", skiprows=1))
    assert ours < plain, f"read_run {ours:.3f} s, np.loadtxt {plain:.3f} s"


# --------------------------------------------------------------------------------------------
# folders of runs


def test_a_folder_stands_for_its_run_files(tmp_path):
    folder = tmp_path / "runs"
    (folder / "old").mkdir(parents=True)
    ch = sines()
    t = np.arange(400) / 2000.0
    write_text(folder / "r2.csv", ["time", *ch], [t, *ch.values()])
    write_tdms(folder / "r1.tdms", {"Data": ch}, fs=2000.0)
    write_text(folder / "r1.forces.csv", ["time", "F1"], [t, t])
    (folder / "notes.txt").write_text("bench 3\n")
    (folder / ".hidden.csv").write_text("x\n")
    runs, notes = run_paths([folder, tmp_path / "other.h5"])
    assert runs == [str(folder / "r1.tdms"), str(folder / "r2.csv"), str(tmp_path / "other.h5")]
    assert notes == [f"run folder '{folder}': 2 run files; skipped 'notes.txt', 'old/', "
                     "'r1.forces.csv' (not run files)"]
    with pytest.raises(InputError, match=r"run folder '.*old': no run files in it"):
        run_paths([folder / "old"])


# --------------------------------------------------------------------------------------------
# the command line on lab files


@pytest.fixture(scope="module")
def lab(paper_dir, tmp_path_factory):
    """The simulated paper lab: its rig, a saved model and its run cut to SHORT_SECONDS."""
    root = tmp_path_factory.mktemp("lab")
    model = root / "model.json"
    assert main(["scan", str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"), "-o",
                 str(model)]) == 0
    run = read_run(paper_dir / "runs" / "paper.csv")
    n = int(round(SHORT_SECONDS * run.fs))
    channels = {k: v[:n] for k, v in run.channels.items()}
    csv = write_text(root / "paper.csv", ["time", *channels],
                     [run.t0 + np.arange(n) / run.fs, *channels.values()])
    out = root / "csv-forces"
    assert main(["reconstruct", str(paper_dir / "rig.toml"), str(model), str(csv), "-o",
                 str(out)]) == 0
    return {"rig": paper_dir / "rig.toml", "model": model, "channels": channels, "fs": run.fs,
            "forces": read_table_csv(out / "paper.forces.csv")[1]}


def rig_with(lab, folder: Path, **tables) -> Path:
    doc = tomllib.loads(lab["rig"].read_text(encoding="utf-8"))
    for key, value in tables.items():
        doc.setdefault(key, {}).update(value)
    path = folder / "rig.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path


def forces_match(lab, out: Path, name: str = "paper", atol: float = 1e-9) -> None:
    got = read_table_csv(out / f"{name}.forces.csv")[1]
    for column in FORCE_COLUMNS:
        np.testing.assert_allclose(got[column], lab["forces"][column], rtol=0, atol=atol,
                                   err_msg=column)


def refused(code: int, capsys, out: Path, *names: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    for name in names:
        assert name in err, f"{name!r} not in {err}"
    assert not out.exists() or not any(out.iterdir())
    return err


def test_reconstruct_a_uff_run_written_by_pyuff(lab, tmp_path):
    records = [dict(id1=name, rsp_node=k + 1, data=v)
               for k, (name, v) in enumerate(lab["channels"].items())]
    run = write_uff(tmp_path / "paper.uff", records, fs=lab["fs"], binary=True)
    out = tmp_path / "out"
    assert main(["reconstruct", str(lab["rig"]), str(lab["model"]), str(run), "-o",
                 str(out)]) == 0
    forces_match(lab, out)


def test_reconstruct_tdms_groups_and_daq_names(lab, tmp_path, capsys):
    daq = {f"Dev1/ai{k}": v for k, v in enumerate(lab["channels"].values())}
    mapping = {name: f"Dev1/ai{k}" for k, name in enumerate(lab["channels"])
               if name in ("R1", "R2", "s1", "s2", "i", "phi")}
    run = write_tdms(tmp_path / "paper.tdms", {"Setup": {"T": np.zeros(8)}, "Data": daq},
                     fs=lab["fs"])
    rig = rig_with(lab, tmp_path, channels=mapping)
    out = tmp_path / "out"
    code = main(["reconstruct", str(rig), str(lab["model"]), str(run), "-o", str(out)])
    refused(code, capsys, out, str(run), "'Setup'", "'Data'", "--group")
    assert main(["reconstruct", str(rig), str(lab["model"]), str(run), "-o", str(out),
                 "--group", "Data"]) == 0
    forces_match(lab, out)
    grouped = rig_with(lab, tmp_path, channels=mapping, acquisition={"group": "Data"})
    out2 = tmp_path / "out2"
    assert main(["stream", str(grouped), str(lab["model"]), str(run), "-o",
                 str(out2 / "s.csv")]) == 0
    wrong = rig_with(lab, tmp_path, channels={**mapping, "s2": "Dev1/ai9"})
    out3 = tmp_path / "out3"
    code = main(["reconstruct", str(wrong), str(lab["model"]), str(run), "-o", str(out3),
                 "--group", "Data"])
    refused(code, capsys, out3, str(run), str(wrong), "channels.s2", "Dev1/ai9")


def test_reconstruct_a_folder_of_runs(lab, tmp_path, capsys):
    folder = tmp_path / "runs"
    folder.mkdir()
    ch = lab["channels"]
    t = np.arange(len(ch["R1"])) / lab["fs"]
    write_text(folder / "paper.csv", ["Time (s)", *ch], [t, *ch.values()], sep=";",
               decimal=",")
    records = [dict(id1=name, rsp_node=k + 1, data=v) for k, (name, v) in enumerate(ch.items())]
    write_uff(folder / "second.uff", records, fs=lab["fs"], binary=True)
    (folder / "README.txt").write_text("two runs\n")
    out = tmp_path / "out"
    assert main(["reconstruct", str(lab["rig"]), str(lab["model"]), str(folder), "-o",
                 str(out)]) == 0
    stdout = capsys.readouterr().out
    assert f"note: run folder '{folder}': 2 run files; skipped 'README.txt'" in stdout
    forces_match(lab, out)
    forces_match(lab, out, "second")
    empty = tmp_path / "empty"
    empty.mkdir()
    code = main(["reconstruct", str(lab["rig"]), str(lab["model"]), str(empty), "-o",
                 str(tmp_path / "out2")])
    refused(code, capsys, tmp_path / "out2", str(empty), "no run files")
