"""Scan files: Universal File (ASCII and binary), HDF5 and NPZ readers and writers."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pytest
import pyuff
from hypothesis import given, settings
from hypothesis import strategies as st

from forcecal.errors import DataError, InputError
from forcecal.io import _uff_write as uff
from forcecal.io.scan_files import read_scan, write_scan_hdf5, write_scan_npz
from forcecal.io.uff import read_scan_uff, read_uff_geometry, write_scan_uff
from forcecal.records import Scan

THIRD_PARTY = Path(__file__).resolve().parents[3] / "shared" / "data" / "third-party-uff"

# pyuff writes ASCII dataset-58 values as %20.11e: 12 significant digits, so a value comes back
# within half a unit in the 12th digit, 5e-12 relative. Measured on the round trip below:
# at most 4.9e-12. Binary 58b values are float64 and come back bit for bit.
ASCII_RTOL = 5e-12


def make_scan(rng, n_points=5, n_samples=256, n_dim=1, fs=5120.0, quantity="velocity"):
    x = np.sort(rng.uniform(0.0, 0.6, n_points))
    points = x[:, None] if n_dim == 1 else np.column_stack([x, rng.uniform(-0.2, 0.2, n_points)])
    t = np.arange(n_samples) / fs
    phase = rng.uniform(0, 2 * np.pi, (n_points, 1))
    response = 1e-3 * np.sin(2 * np.pi * 40 * t + phase) + 1e-5 * rng.standard_normal(
        (n_points, n_samples)
    )
    reference = 2.0 * np.sin(2 * np.pi * 40 * t + phase + 0.3) + 0.6
    return Scan(points, response, reference, fs=fs, quantity=quantity, source="made")


def write_sets(path: Path, sets: list[dict]) -> Path:
    """Write hand-made datasets with pyuff (through the module's own writer helper)."""
    uff._write_sets(sets, path)
    return path


def node_set(nodes, x, y=None, z=None):
    n = len(nodes)
    y = np.zeros(n) if y is None else np.asarray(y, float)
    z = np.zeros(n) if z is None else np.asarray(z, float)
    return uff._node_set(np.asarray(nodes), np.column_stack([x, y, z]))


def vib(node, n=64, fs=1000.0, quantity="velocity", seed=0):
    data = np.random.default_rng(seed).standard_normal(n)
    return uff._vibration_set(node, data, fs, quantity, binary=False)


def ref(node, n=64, fs=1000.0, seed=1):
    data = np.random.default_rng(seed).standard_normal(n)
    return uff._reference_set(node, data, fs, binary=False)


# --------------------------------------------------------------------------------------------
# round trips


def test_uff_ascii_round_trip_precision(tmp_path):
    rng = np.random.default_rng(11)
    scan = make_scan(rng)
    path = write_scan_uff(scan, tmp_path / "scan.uff")
    back = read_scan_uff(path)
    assert back.source == str(path)
    assert back.quantity == "velocity"
    assert back.fs == scan.fs
    np.testing.assert_array_equal(back.points, scan.points)  # 2411 keeps 17 digits
    for name in ("response", "reference"):
        got, want = getattr(back, name), getattr(scan, name)
        rel = np.max(np.abs(got - want) / np.abs(want))
        assert rel <= ASCII_RTOL, f"{name}: relative error {rel:.3g}"


def test_uff_binary_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(12)
    scan = make_scan(rng, n_dim=2, quantity="displacement")
    back = read_scan_uff(write_scan_uff(scan, tmp_path / "scan.uff", binary=True))
    assert back.quantity == "displacement"
    assert back.fs == scan.fs
    np.testing.assert_array_equal(back.points, scan.points)
    np.testing.assert_array_equal(back.response, scan.response)
    np.testing.assert_array_equal(back.reference, scan.reference)


def test_uff_writes_the_contract_fields(tmp_path):
    scan = make_scan(np.random.default_rng(13), n_points=3)
    path = write_scan_uff(scan, tmp_path / "scan.uff", node_offset=101)
    sets = pyuff.UFF(str(path)).read_sets()
    assert [s["type"] for s in sets] == [2411] + [58] * 6
    np.testing.assert_array_equal(sets[0]["node_nums"], [101, 102, 103])
    vib_set, ref_set = sets[1], sets[2]
    assert vib_set["id2"].strip() == "Vib  Velocity"
    assert vib_set["ordinate_spec_data_type"] == 11
    assert vib_set["ordinate_axis_units_lab"] == "m/s"
    assert ref_set["id2"].strip() == "Ref1  Current"
    assert ref_set["ordinate_axis_units_lab"] == "A"
    for s in sets[1:]:
        assert s["func_type"] == 1
        assert s["rsp_dir"] == 3
    assert [s["rsp_node"] for s in sets[1:]] == [101, 101, 102, 102, 103, 103]
    assert not list(tmp_path.glob("*.part"))


@pytest.mark.parametrize("fs", [5120.0, 65536.0, 12800.0, 2000.0, 44100.0, 25600.0, 1234.5])
def test_sampling_rate_survives_six_digit_increment(tmp_path, fs):
    scan = make_scan(np.random.default_rng(14), n_points=2, n_samples=32, fs=fs)
    assert read_scan_uff(write_scan_uff(scan, tmp_path / "s.uff")).fs == fs


def test_points_are_ordered_by_node_and_line_scan_is_1d(tmp_path):
    sets = [node_set([3, 1, 2, 9], [0.3, 0.1, 0.2, 0.9])]
    for node in (3, 1, 2):
        sets += [ref(node, seed=node), vib(node, seed=10 + node)]
    with pytest.warns(UserWarning, match="no records for node 9"):
        scan = read_scan_uff(write_sets(tmp_path / "s.uff", sets))
    np.testing.assert_array_equal(scan.points, [[0.1], [0.2], [0.3]])  # node 9 is unmeasured
    np.testing.assert_allclose(scan.response[0], vib(1, seed=11)["data"], rtol=ASCII_RTOL)


def test_dataset_164_units_are_converted_to_metres(tmp_path):
    units = pyuff.prepare_164(
        units_code=5,
        units_description="mm",
        temp_mode=1,
        length=1000.0,
        force=1.0,
        temp=1.0,
        temp_offset=273.15,
    )
    nodes = node_set([1, 2], [100.0, 500.0], [0.0, 20.0], [5.0, 5.0])  # mm
    sets = [units, nodes, vib(1), ref(1), vib(2, seed=3), ref(2, seed=4)]
    path = write_sets(tmp_path / "mm.uff", sets)
    geometry = read_uff_geometry(path)
    np.testing.assert_allclose(geometry[2], (0.5, 0.02, 0.005), rtol=1e-15)
    scan = read_scan_uff(path)
    np.testing.assert_allclose(scan.points, [[0.1, 0.0], [0.5, 0.02]], rtol=1e-15)
    # velocity in mm/s (ordinate length exponent 1) comes back in m/s
    np.testing.assert_allclose(scan.response[0], vib(1)["data"] / 1000.0, rtol=1e-11)
    np.testing.assert_allclose(scan.reference[0], ref(1)["data"], rtol=1e-11)  # current: no change


def test_reference_label_is_configurable(tmp_path):
    sets = [node_set([1], [0.1]), vib(1)]
    reference = ref(1)
    reference["id2"] = "Current clamp"
    path = write_sets(tmp_path / "s.uff", [*sets, reference])
    with pytest.raises(InputError, match="no record whose id line 2 contains 'Ref'"):
        read_scan_uff(path)
    assert read_scan_uff(path, reference_label="Current").n_points == 1


# --------------------------------------------------------------------------------------------
# error paths


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"scan '.*nothere\.uff': file does not exist"):
        read_scan_uff(tmp_path / "nothere.uff")


@pytest.mark.parametrize(
    "content",
    [b"", b"hello\nworld\n", b"    -1\nxx\n    -1\n", b"    -1\n    58\nfoo\n    -1\n"],
    ids=["empty", "text", "bad-block", "bad-58"],
)
def test_not_a_universal_file(tmp_path, content):
    path = tmp_path / "junk.uff"
    path.write_bytes(content)
    with pytest.raises(InputError, match=r"scan '.*junk\.uff': not a (readable )?Universal File"):
        read_scan_uff(path)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=60), st.just(b"    -1\n")), max_size=12))
def test_garbage_only_ever_raises_input_error(tmp_path_factory, chunks):
    path = tmp_path_factory.mktemp("garbage") / "g.uff"
    path.write_bytes(b"".join(chunks))
    with pytest.raises(InputError) as info:
        read_scan_uff(path)
    assert "\n" not in str(info.value)
    assert "g.uff" in str(info.value)


def test_no_coordinates(tmp_path):
    path = write_sets(tmp_path / "s.uff", [vib(1), ref(1)])
    with pytest.raises(InputError, match=r"s\.uff': no node coordinates \(dataset 2411 or 15\)"):
        read_scan_uff(path)


def test_no_time_records(tmp_path):
    path = write_sets(tmp_path / "s.uff", [node_set([1], [0.1])])
    with pytest.raises(InputError, match=r"s\.uff': no time records \(dataset 58\)"):
        read_scan_uff(path)


def test_no_reference_records(tmp_path):
    path = write_sets(tmp_path / "s.uff", [node_set([1, 2], [0.1, 0.2]), vib(1), vib(2)])
    with pytest.raises(InputError, match="no reference records"):
        read_scan_uff(path)


def test_point_without_reference_is_named(tmp_path):
    sets = [node_set([1, 2], [0.1, 0.2]), vib(1), ref(1), vib(2)]
    with pytest.raises(DataError, match=r"node 2 has a vibration record but no reference"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_reference_without_vibration_is_named(tmp_path):
    sets = [node_set([1, 2], [0.1, 0.2]), vib(1), ref(1), ref(2)]
    with pytest.raises(DataError, match=r"node 2 has a reference record but no vibration"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_two_references_at_one_node(tmp_path):
    second = ref(1, seed=5)
    second["id2"] = "Ref2  Voltage"
    sets = [node_set([1], [0.1]), vib(1), ref(1), second]
    path = write_sets(tmp_path / "s.uff", sets)
    with pytest.raises(DataError, match=r"node 1 has 2 reference records .*'Ref2  Voltage'"):
        read_scan_uff(path)
    assert read_scan_uff(path, reference_label="Ref1").n_points == 1


def test_records_of_unequal_length(tmp_path):
    sets = [node_set([1, 2], [0.1, 0.2]), vib(1), ref(1), vib(2, n=60), ref(2, n=60)]
    with pytest.raises(DataError, match=r"node 2: vibration record has 60 samples, expected 64"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_records_of_unequal_sampling(tmp_path):
    sets = [node_set([1, 2], [0.1, 0.2]), vib(1), ref(1), vib(2), ref(2, fs=2000.0)]
    with pytest.raises(DataError, match=r"node 2: reference record sampled every 0\.0005 s"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_records_at_a_node_without_coordinates(tmp_path):
    sets = [node_set([1], [0.1]), vib(1), ref(1), vib(4), ref(4)]
    with pytest.raises(DataError, match=r"node 4 has time records but no coordinates"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_mixed_quantities(tmp_path):
    sets = [node_set([1, 2], [0.1, 0.2]), vib(1), ref(1), vib(2, quantity="displacement")]
    sets.append(ref(2))
    with pytest.raises(DataError, match=r"node 2 records displacement but node 1 records velocity"):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))


def test_unknown_vibration_quantity(tmp_path):
    acceleration = vib(1)
    acceleration.update(ordinate_spec_data_type=12, id2="Vib  Acceleration")
    sets = [node_set([1, 2], [0.1, 0.2]), acceleration, ref(1), vib(2), ref(2)]
    message = r"node 1 has a reference record but no vibration.*'Vib  Acceleration' .*type 12\)"
    with pytest.raises(DataError, match=message):
        read_scan_uff(write_sets(tmp_path / "s.uff", sets))
    with pytest.raises(InputError, match=r"no vibration records .*'Vib  Acceleration'"):
        read_scan_uff(write_sets(tmp_path / "t.uff", [*sets[:3]]))


def test_writer_refuses_nan(tmp_path):
    scan = make_scan(np.random.default_rng(15), n_points=2, n_samples=32)
    scan.response[1, 5] = np.nan
    with pytest.raises(DataError, match="response holds NaN"):
        write_scan_uff(scan, tmp_path / "s.uff")
    assert not (tmp_path / "s.uff").exists()


# --------------------------------------------------------------------------------------------
# files written by other tools


def third_party_files() -> list[Path]:
    return sorted(THIRD_PARTY.glob("*.uff")) if THIRD_PARTY.is_dir() else []


EXPECTED_MISSING = {
    "Sample_UFF58_ascii.uff": r"no node coordinates \(dataset 2411 or 15\)",
    "Sample_UFF58b_bin.uff": r"no node coordinates \(dataset 2411 or 15\)",
    "TestLab_161_164_18_15_82.uff": r"no time records \(dataset 58\)",
    "time-history-not-all-columns-filled.uff": r"no node coordinates \(dataset 2411 or 15\)",
}


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
@pytest.mark.parametrize("name", sorted(EXPECTED_MISSING))
def test_third_party_files_say_which_dataset_is_missing(name):
    path = THIRD_PARTY / name
    if not path.is_file():
        pytest.skip(f"{name} not present")
    with pytest.raises(InputError) as info:
        read_scan_uff(path)
    message = str(info.value)
    assert "\n" not in message
    assert name in message
    assert re.search(EXPECTED_MISSING[name], message)


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
def test_every_third_party_file_fails_cleanly():
    for path in third_party_files():
        with pytest.raises(InputError):
            read_scan_uff(path)


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
def test_testlab_geometry_with_units_dataset_is_parsed():
    path = THIRD_PARTY / "TestLab_161_164_18_15_82.uff"
    if not path.is_file():
        pytest.skip("TestLab file not present")
    geometry = read_uff_geometry(path)  # dataset 164 there gives length factor 1
    assert len(geometry) == 36
    assert geometry[1] == pytest.approx((-2.4, -0.95, 0.0))
    assert geometry[5] == pytest.approx((-1.2, 8.35, 0.0))


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason="third-party UFF files not present")
def test_geometry_of_a_file_without_nodes():
    path = THIRD_PARTY / "Sample_UFF58_ascii.uff"
    if not path.is_file():
        pytest.skip("sample file not present")
    with pytest.raises(InputError, match=r"no node coordinates \(dataset 2411 or 15\)"):
        read_uff_geometry(path)


# --------------------------------------------------------------------------------------------
# HDF5 / NPZ scans and the dispatcher


@pytest.mark.parametrize("n_dim", [1, 2])
@pytest.mark.parametrize("suffix", [".npz", ".h5", ".hdf5"])
def test_hdf5_npz_round_trip_is_exact(tmp_path, suffix, n_dim):
    scan = make_scan(np.random.default_rng(16), n_dim=n_dim, quantity="displacement")
    path = tmp_path / f"scan{suffix}"
    (write_scan_npz if suffix == ".npz" else write_scan_hdf5)(scan, path)
    back = read_scan(path)
    assert back.fs == scan.fs
    assert back.quantity == "displacement"
    assert back.source == str(path)
    for name in ("points", "response", "reference"):
        np.testing.assert_array_equal(getattr(back, name), getattr(scan, name))


@pytest.mark.parametrize("suffix", [".uff", ".unv", ".UFF"])
def test_dispatch_to_uff(tmp_path, suffix):
    scan = make_scan(np.random.default_rng(17), n_points=2, n_samples=32)
    path = write_scan_uff(scan, tmp_path / f"scan{suffix}", binary=True)
    np.testing.assert_array_equal(read_scan(path).response, scan.response)


def test_unknown_scan_suffix(tmp_path):
    path = tmp_path / "scan.mat"
    path.write_bytes(b"")
    with pytest.raises(InputError, match=r"scan '.*scan\.mat': unknown file type.*\.uff.*\.npz"):
        read_scan(path)


@pytest.mark.parametrize("key", ["x", "response", "reference", "fs", "quantity"])
@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_missing_key_is_named(tmp_path, key, suffix):
    scan = make_scan(np.random.default_rng(18), n_points=2, n_samples=32)
    content = {
        "x": scan.x,
        "response": scan.response,
        "reference": scan.reference,
        "fs": scan.fs,
        "quantity": scan.quantity,
    }
    del content[key]
    path = tmp_path / f"scan{suffix}"
    if suffix == ".npz":
        np.savez(path, **content)
    else:
        with h5py.File(path, "w") as h5:
            for name, value in content.items():
                h5[name] = value
    with pytest.raises(InputError, match=rf"scan{suffix}': missing '{key}'"):
        read_scan(path)


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_missing_and_corrupt_hdf5_npz(tmp_path, suffix):
    with pytest.raises(InputError, match="does not exist"):
        read_scan(tmp_path / f"none{suffix}")
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(b"not a container at all")
    with pytest.raises(InputError, match=rf"bad{suffix}': not a readable"):
        read_scan(path)


def test_npz_that_is_a_single_array_or_holds_objects(tmp_path):
    path = tmp_path / "s.npz"
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(3))
    with pytest.raises(InputError, match=r"s\.npz': a single array"):
        read_scan(path)
    np.savez(path, x=np.array([{"a": 1}], dtype=object))
    with pytest.raises(InputError, match=r"s\.npz': not a readable NPZ archive"):
        read_scan(path)


def test_bad_fs_in_npz(tmp_path):
    scan = make_scan(np.random.default_rng(19), n_points=2, n_samples=32)
    path = tmp_path / "s.npz"
    np.savez(
        path,
        x=scan.x,
        response=scan.response,
        reference=scan.reference,
        fs=-1.0,
        quantity="velocity",
    )
    with pytest.raises(InputError, match="'fs' must be one positive number"):
        read_scan(path)


def test_a_scan_cut_short_is_refused_naming_the_missing_nodes(tmp_path):
    sets = [node_set([1, 2, 3, 4, 5], [0.1, 0.2, 0.3, 0.4, 0.5])]
    for node in (1, 2):
        sets += [ref(node, seed=node), vib(node, seed=10 + node)]
    with pytest.raises(DataError, match=r"no records for node 3, 4, 5 \(a scan cut short"):
        read_scan_uff(write_sets(tmp_path / "cut.uff", sets))
