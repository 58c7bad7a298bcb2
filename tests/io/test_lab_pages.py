"""The lab pages (docs/labs/*.md) say what the readers accept, and the readers do.

Every ```toml block of a lab page parses; every one that is a whole rig (it has a
``[structure]`` table) loads with :func:`forcecal.load_rig`. Each page's rig then reads a file
written the way that page describes, by the third-party library of the format (pyuff,
npTDMS), and the refusals the page quotes are the ones the readers give.
"""

from __future__ import annotations

import gc
import re
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import pyuff
from nptdms import ChannelObject, GroupObject, TdmsWriter
from uff_files import retype

import forcecal
from forcecal.errors import DataError, InputError, RigError

LABS = Path(__file__).resolve().parents[2] / "docs" / "labs"
PAGES = ("polytec.md", "ni-tdms.md", "testlab-uff.md")
FS = 2000.0            # Hz
F0 = 20.0              # Hz, the pages' [acquisition] frequency
N_SAMPLES = 1000       # 0.5 s: 10 periods
RUN_NAMES = {"R1", "R2", "s1", "s2", "i"}


def toml_blocks(page: str) -> list[str]:
    text = (LABS / page).read_text(encoding="utf-8")
    return re.findall(r"^```toml\n(.*?)^```", text, flags=re.M | re.S)


def page_rig(page: str, tmp_path: Path, replace: tuple[str, str] | None = None):
    """The page's (first) whole rig, written to ``tmp_path/rig.toml`` and loaded."""
    text = next(b for b in toml_blocks(page) if "[structure]" in b)
    if replace is not None:
        assert replace[0] in text
        text = text.replace(*replace)
    path = tmp_path / "rig.toml"
    path.write_text(text, encoding="utf-8")
    return forcecal.load_rig(path)


def write_uff(path: Path, sets: list[dict]) -> Path:
    """Datasets written by pyuff, one at a time (as lab software appends them)."""
    path.unlink(missing_ok=True)
    uff = pyuff.UFF(str(path))
    with warnings.catch_warnings():  # pyuff leaves a reopened handle to the collector
        warnings.simplefilter("ignore", ResourceWarning)
        for dataset in sets:
            uff.write_sets([dataset], mode="add")
        gc.collect()
    return path


def record(data: np.ndarray, node: int, direction: int = 3, func_type: int = 1,
           **fields) -> dict:
    """A dataset 58: a time record (function type 1) with an even abscissa in s, or a spectrum
    (12) or FRF (4) over frequency."""
    time = func_type == 1
    step = 1.0 / FS if time else F0 / 4
    base = dict(binary=0, func_type=func_type, rsp_node=node, rsp_dir=direction, ref_node=0,
                ref_dir=0, id1="Time" if time else "FFT", abscissa_spacing=1,
                abscissa_inc=step, abscissa_min=0.0, abscissa_spec_data_type=17 if time else 18,
                abscissa_axis_units_lab="s" if time else "Hz", ordinate_spec_data_type=0,
                orddenom_spec_data_type=0, z_axis_spec_data_type=0)
    base.update(fields)
    return pyuff.prepare_58(data=data, x=np.arange(data.size) * step, **base)


def signals(n_channels: int, seed: int = 3) -> np.ndarray:
    """(n_channels, N_SAMPLES) sines at F0 with a random phase each, plus a little noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(N_SAMPLES) / FS
    phases = rng.uniform(0, 2 * np.pi, (n_channels, 1))
    return np.sin(2 * np.pi * F0 * t + phases) + 1e-3 * rng.standard_normal((n_channels, t.size))


def test_every_toml_block_parses_and_every_rig_loads(tmp_path):
    for page in PAGES:
        blocks = toml_blocks(page)
        assert any("[structure]" in b for b in blocks), f"{page} shows no whole rig"
        for k, block in enumerate(blocks):
            tomllib.loads(block)
            if "[structure]" in block:
                path = tmp_path / f"{page}.{k}.toml"
                path.write_text(block, encoding="utf-8")
                rig = forcecal.load_rig(path)
                assert rig.drive_frequency == F0
                assert {*rig.gauge_names, *rig.sensor_names, rig.actuator.current} == RUN_NAMES


# --------------------------------------------------------------------------------------------
# polytec.md: a scan exported in time mode or as spectra; FRFs refused


def psv_scan(path: Path, n_points: int = 13, func_type: int = 1, twice: int | None = None
             ) -> Path:
    """A PSV-like scan: node coordinates (dataset 15), per node a velocity record (ordinate
    type 11, 'Vib  Velocity') and a current record ('Ref1  Current'); or their spectra
    (function type 12) or FRFs (4)."""
    nodes = np.arange(1, n_points + 1)
    x = np.linspace(0.0, 0.6, n_points)
    zeros = np.zeros(n_points, dtype=int)
    sets = [pyuff.prepare_15(node_nums=nodes, def_cs=zeros, disp_cs=zeros, color=zeros + 8,
                             x=x, y=0 * x, z=0 * x)]
    vib, ref = 1e-3 * signals(n_points, seed=1), signals(n_points, seed=2)
    for k, node in enumerate(nodes):
        pairs = [(vib[k], "Vib  Velocity", 11), (ref[k], "Ref1  Current", 0)]
        if node == twice:
            pairs.append((vib[k], "Vib  Displacement", 8))
        for values, id2, ordinate in pairs:
            data = values if func_type == 1 else np.fft.rfft(values)[:40] / values.size
            sets.append(record(data, int(node), func_type=min(func_type, 4), id2=id2,
                               ordinate_spec_data_type=ordinate))
    write_uff(path, sets)
    return retype(path, func_type) if func_type == 12 else path


def test_polytec_time_export_is_read_as_a_scan(tmp_path):
    rig = page_rig("polytec.md", tmp_path)
    scan = forcecal.read_scan(psv_scan(tmp_path / "scan.uff"), rig=rig)
    assert scan.n_points == 13
    assert scan.quantity == "velocity"
    assert scan.fs == FS
    np.testing.assert_allclose(scan.points[:, 0], np.linspace(0.0, 0.6, 13))


def test_polytec_second_vibration_record_on_a_node_is_refused(tmp_path):
    with pytest.raises(DataError, match=r"node 4 has 2 vibration records \('Vib  Velocity', "
                                        r"'Vib  Displacement'\); expected one"):
        forcecal.read_scan(psv_scan(tmp_path / "scan.uff", twice=4))


def test_polytec_spectrum_export_is_read_as_spectra(tmp_path):
    scan = forcecal.read_scan(psv_scan(tmp_path / "scan_fft.uff", func_type=12))
    assert isinstance(scan, forcecal.ScanSpectra)
    assert scan.points.shape == (13, 1) and scan.quantity == "velocity"
    assert scan.amplitude == "peak"                     # no 'RMS' in the records' labels


def test_polytec_frf_export_is_refused_saying_why(tmp_path):
    path = psv_scan(tmp_path / "scan_frf.uff", func_type=4)
    with pytest.raises(InputError, match=r"scan '.*scan_frf.uff': none of the 26 dataset-58 "
                                         r"records is a time record \(function type 1\) or a "
                                         r"spectrum \(function type 12\); found 26 frequency "
                                         r"response functions .* relative to the drive's "
                                         r"fundamental, which the method needs, are lost"):
        forcecal.read_scan(path)


# --------------------------------------------------------------------------------------------
# ni-tdms.md: groups and DAQ channel names

DAQ = ("cDAQ1Mod1/ai0", "cDAQ1Mod1/ai1", "cDAQ1Mod2/ai0", "cDAQ1Mod2/ai1", "cDAQ1Mod3/ai0")


def daq_tdms(path: Path, groups: tuple[str, ...] = ("Setup", "Data")) -> Path:
    """A TDMS file as NI software writes it: the run's group of DAQ channels with waveform
    properties, beside a group of settings."""
    values = signals(len(DAQ))
    props = {"wf_increment": 1.0 / FS, "wf_start_offset": 0.0}
    objects: list = [GroupObject(group) for group in groups]
    for group in groups:
        if group == "Data":
            objects += [ChannelObject(group, name, values[k], properties=props)
                        for k, name in enumerate(DAQ)]
        else:
            objects.append(ChannelObject(group, "gain", np.ones(4)))
    with TdmsWriter(path) as writer:
        writer.write_segment(objects)
    return path


def test_ni_tdms_daq_names_and_group_from_the_rig(tmp_path):
    rig = page_rig("ni-tdms.md", tmp_path)
    path = daq_tdms(tmp_path / "r01.tdms")
    run = forcecal.read_run(path, rig)
    assert set(run.channels) == RUN_NAMES
    assert run.fs == FS
    raw = forcecal.read_run(path, group="Data")
    assert set(raw.channels) == set(DAQ)
    np.testing.assert_array_equal(run.channels["i"], raw.channels["cDAQ1Mod3/ai0"])


def test_ni_tdms_refusals_quoted_on_the_page(tmp_path):
    path = daq_tdms(tmp_path / "r01.tdms")
    with pytest.raises(InputError, match="expected one group of channels, found 'Setup', "
                                         "'Data'; choose one with --group NAME or"):
        forcecal.read_run(path)
    other = daq_tdms(tmp_path / "r02.tdms", groups=("Setup", "Log"))
    with pytest.raises(InputError, match=r"no group 'Data' \(the group chosen for the runs\); "
                                         "the file's groups: 'Setup', 'Log'"):
        forcecal.read_run(other, page_rig("ni-tdms.md", tmp_path))
    with pytest.raises(RigError, match=r"key 'channels\.s9' is not a channel of the rig; "
                                       r"expected one of R1, R2, s1, s2, i"):
        page_rig("ni-tdms.md", tmp_path, ('i = "cDAQ1Mod3/ai0"', 's9 = "cDAQ1Mod3/ai0"'))
    renamed = page_rig("ni-tdms.md", tmp_path, ('i = "cDAQ1Mod3/ai0"', 'i = "cDAQ1Mod3/ai7"'))
    with pytest.raises(DataError, match=r"channel 'cDAQ1Mod3/ai7' \(rig '.*rig.toml', key "
                                        r"'channels.i'\) is not in the file; it holds "
                                        r"'cDAQ1Mod1/ai0'"):
        forcecal.read_run(path, renamed)


# --------------------------------------------------------------------------------------------
# testlab-uff.md: time records named by node and direction


def write_testlab_uff(path: Path) -> Path:
    """Time records with one repeated ID line 1 (named by node and direction), probes in mm,
    the current on a node without a direction, and an FRF that a run ignores."""
    values = signals(5)
    layout = [(1, 3, "N"), (2, 3, "N"), (12, 3, "mm"), (14, 3, "mm"), (100, 0, "A")]
    sets = [record(values[k], node, direction, ordinate_axis_units_lab=unit)
            for k, (node, direction, unit) in enumerate(layout)]
    sets.append(record(np.fft.rfft(values[2])[:40], 12, 3, func_type=4))
    return write_uff(path, sets)


def test_testlab_records_mapped_by_node_and_direction(tmp_path):
    rig = page_rig("testlab-uff.md", tmp_path)
    path = write_testlab_uff(tmp_path / "r01.uff")
    run = forcecal.read_run(path, rig)
    assert set(run.channels) == RUN_NAMES
    raw = forcecal.read_run(path)
    assert set(raw.channels) == {"node 1 +Z", "node 2 +Z", "node 12 +Z", "node 14 +Z",
                                 "node 100"}
    np.testing.assert_array_equal(run.channels["s2"], raw.channels["node 14 +Z"])


def test_testlab_unit_label_checked_against_the_scale(tmp_path):
    rig = page_rig("testlab-uff.md", tmp_path, ("scale = 0.001               # the export is in mm",
                                                "scale = 1.0"))
    with pytest.raises(DataError, match=r"channel 'node 12 \+Z' \(rig channel 's1'\) is in mm, "
                                        r"but rig '.*rig.toml' key 'sensors\[0\].scale' = 1 "
                                        r"reads it as m; expected a scale near 0.001 "
                                        r"\(or -0.001\)"):
        forcecal.read_run(write_testlab_uff(tmp_path / "r01.uff"), rig)


def test_testlab_file_without_time_records_is_refused(tmp_path):
    values = signals(4)
    path = write_uff(tmp_path / "r01.uff", [record(np.fft.rfft(v)[:40], k + 1, func_type=4)
                                            for k, v in enumerate(values)])
    with pytest.raises(InputError, match=r"none of the 4 dataset-58 records is a time record "
                                         r"\(function type 1; found function types 4\)"):
        forcecal.read_run(path)
