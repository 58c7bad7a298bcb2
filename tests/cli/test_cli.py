"""The command line as a user meets it (INTERFACES.md section 5).

One simulated 'paper' lab (``forcecal simulate``) serves every test; each test copies and alters
the files it needs. A refused input must give exit status 2, exactly one line on stderr that
names the file, key or channel at fault, and leave nothing in the output folder.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import forcecal
from forcecal.cli.main import main
from forcecal.io.run_files import (
    read_run,
    read_table_csv,
    write_run_hdf5,
    write_run_tdms,
    write_table_csv,
)

THIRD_PARTY_UFF58 = Path("/work/shared/data/third-party-uff/Sample_UFF58_ascii.uff")
FORCE_COLUMNS = ["time", "F1", "F2", "total", "F1_static", "F2_static", "total_static",
                 "F1_std", "F2_std", "total_std"]
SHORT_SECONDS = 0.4
COMMANDS = ["demo", "simulate", "scan", "reconstruct", "calibrate", "predict", "stream", "report"]


# --------------------------------------------------------------------------------------------
# the lab and helpers


@pytest.fixture(scope="session")
def lab(tmp_path_factory) -> Path:
    """``forcecal simulate LAB --preset paper``: rig.toml, scan.uff, runs/paper.csv, truth/."""
    out = tmp_path_factory.mktemp("cli") / "lab"
    assert main(["simulate", str(out), "--preset", "paper"]) == 0
    return out


@pytest.fixture(scope="session")
def model_json(lab, tmp_path_factory) -> Path:
    """``forcecal scan`` of the lab: the spatial model the reconstruct tests start from."""
    path = tmp_path_factory.mktemp("model") / "model.json"
    assert main(["scan", str(lab / "rig.toml"), str(lab / "scan.uff"), "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="session")
def run_table(lab) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The lab's run as (time, columns)."""
    return read_table_csv(lab / "runs" / "paper.csv")


@pytest.fixture(scope="session")
def short_run(run_table, tmp_path_factory) -> Path:
    """The lab's run cut to its first SHORT_SECONDS (8 periods), to keep reconstruction quick."""
    time, columns = run_table
    n = int(round(SHORT_SECONDS / (time[1] - time[0])))
    folder = tmp_path_factory.mktemp("short")
    return write_table_csv(folder / "paper.csv", time[:n], {k: v[:n] for k, v in columns.items()})


@pytest.fixture(scope="session")
def csv_forces(lab, model_json, short_run, tmp_path_factory) -> Path:
    """``forcecal reconstruct`` of the (short) run, CSV, with the saved model: the output folder."""
    out = tmp_path_factory.mktemp("forces")
    code = main(["reconstruct", str(lab / "rig.toml"), str(model_json), str(short_run),
                 "-o", str(out)])
    assert code == 0
    return out


@pytest.fixture(scope="session")
def scan_datasets(lab) -> list[str]:
    """The datasets of the lab's scan.uff as text: the nodes (2411), then per point its
    vibration and reference records (58)."""
    text = (lab / "scan.uff").read_text()
    return re.findall(r"^ {4}-1\n(.*?)^ {4}-1\n", text, re.S | re.M)


def cli(*argv: object) -> int:
    return main([str(a) for a in argv])


def assert_refused(code: int, capsys, out: Path, *names: str) -> str:
    """Exit 2, one line on stderr naming every one of ``names``, nothing left in ``out``."""
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("forcecal"), line
    for name in names:
        assert name in line, f"{name!r} not named in: {line}"
    left = sorted(str(p.relative_to(out)) for p in out.rglob("*")) if out.exists() else []
    assert left == [], left
    return line


def edited_rig(lab: Path, folder: Path, edit: Callable[[dict], None]) -> Path:
    """A copy of the lab's rig.toml with ``edit`` applied to its parsed document."""
    doc = tomllib.loads((lab / "rig.toml").read_text(encoding="utf-8"))
    edit(doc)
    path = folder / "rig.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path


def edited_run(run_table, folder: Path, edit) -> Path:
    """A copy of the lab's run with ``edit(time, columns) -> (time, columns)`` applied."""
    time, columns = run_table
    time, columns = edit(time.copy(), {k: v.copy() for k, v in columns.items()})
    return write_table_csv(folder / "paper.csv", time, columns)


def scan_subset(scan_datasets, path: Path, n_points: int = 4, coordinates: bool = True,
                keep: Callable[[str, int], bool] = lambda kind, node: True) -> Path:
    """A small UFF of the lab's first ``n_points`` scan points; ``keep(kind, node)`` selects
    records (kind 'vibration' or 'reference'); ``coordinates=False`` drops dataset 2411."""
    nodes, records = scan_datasets[0], scan_datasets[1:]
    kept = []
    measured: set[int] = set()
    for record in records[: 2 * n_points]:
        lines = record.splitlines()
        kind = "reference" if "Ref" in lines[2] else "vibration"
        node = int(lines[6].split()[5])
        measured.add(node)
        if keep(kind, node):
            kept.append(record)
    if coordinates:  # the geometry of the measured points only (a subset, not a scan cut short)
        head, *pairs = nodes.splitlines(keepends=True)
        pairs = [pairs[k] + pairs[k + 1] for k in range(0, len(pairs) - 1, 2)
                 if int(pairs[k].split()[0]) in measured]
        kept.insert(0, head + "".join(pairs))
    path.write_text("".join(f"    -1\n{d}    -1\n" for d in kept))
    return path


# --------------------------------------------------------------------------------------------
# success paths


def test_scan_writes_the_model(model_json):
    doc = json.loads(model_json.read_text())
    assert doc["format"] == "forcecal spatial model 1"
    assert doc["gauges"] == ["R1", "R2"]
    assert doc["f0_hz"] == pytest.approx(20.0, rel=0.01)
    assert 1 in doc["harmonics"]
    assert len(doc["shapes"]) == len(doc["harmonics"])
    assert not list(model_json.parent.glob(".*.part"))


def test_reconstruct_writes_forces_and_summary(csv_forces, short_run):
    assert sorted(p.name for p in csv_forces.iterdir()) == ["paper.forces.csv", "paper.json"]
    header = (csv_forces / "paper.forces.csv").read_text().splitlines()[0]
    assert header.split(",") == FORCE_COLUMNS
    time, columns = read_table_csv(csv_forces / "paper.forces.csv")
    np.testing.assert_allclose(time, read_table_csv(short_run)[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(columns["total"], columns["F1"] + columns["F2"], atol=1e-9)

    doc = json.loads((csv_forces / "paper.json").read_text())
    assert doc["run"] == "paper"
    assert doc["fundamental_hz"] == pytest.approx(20.0, rel=0.01)
    assert {"F1", "F2", "total"} <= set(doc["forces"])
    for name in ("F1", "F2"):
        rows = doc["forces"][name]
        assert [r["harmonic"] for r in rows][:2] == [0, 1]
        for row in rows:
            assert row["amplitude_n"] >= 0
            assert -np.pi <= row["phase_rad"] <= np.pi
            assert row["std_n"] > 0
    assert 0 < doc["inertia_share"] < 1
    assert "psi_condition_number" in doc["conditioning"]


def test_reconstruct_from_the_scan_matches_the_saved_model(lab, short_run, csv_forces, tmp_path,
                                                           capsys):
    out = tmp_path / "out"
    code = cli("reconstruct", lab / "rig.toml", lab / "scan.uff", short_run, "-o", out)
    assert code == 0, capsys.readouterr().err
    assert "paper.forces.csv" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["paper.forces.csv", "paper.json"]
    header = (out / "paper.forces.csv").read_text().splitlines()[0]
    assert header.split(",") == FORCE_COLUMNS
    _, direct = read_table_csv(out / "paper.forces.csv")
    _, saved = read_table_csv(csv_forces / "paper.forces.csv")
    for name in FORCE_COLUMNS[1:]:
        np.testing.assert_allclose(direct[name], saved[name], rtol=0, atol=1e-9, err_msg=name)


@pytest.mark.parametrize("writer,suffix", [(write_run_tdms, ".tdms"), (write_run_hdf5, ".h5")],
                         ids=["tdms", "hdf5"])
def test_tdms_and_hdf5_runs_give_the_csv_forces(lab, model_json, short_run, csv_forces, tmp_path,
                                                writer, suffix):
    run = writer(read_run(short_run), tmp_path / f"paper{suffix}")
    out = tmp_path / "out"
    assert cli("reconstruct", lab / "rig.toml", model_json, run, "-o", out) == 0
    time, got = read_table_csv(out / "paper.forces.csv")
    ref_time, ref = read_table_csv(csv_forces / "paper.forces.csv")
    np.testing.assert_allclose(time, ref_time, rtol=0, atol=1e-9)
    for name in FORCE_COLUMNS[1:]:
        np.testing.assert_allclose(got[name], ref[name], rtol=0, atol=1e-9, err_msg=name)


def test_interrupted_write_leaves_no_file(lab, model_json, short_run, tmp_path, capsys,
                                          monkeypatch):
    from forcecal.io import table_writer

    real = table_writer.TableWriter.write

    def half_then_interrupt(self, time, columns):
        half = time.size // 2                      # half the rows reach the file, then Ctrl-C
        real(self, time[:half], columns[:, :half])
        self.flush()
        raise KeyboardInterrupt

    monkeypatch.setattr(table_writer.TableWriter, "write", half_then_interrupt)
    out = tmp_path / "out"
    code = cli("reconstruct", lab / "rig.toml", model_json, short_run, "-o", out)
    err = capsys.readouterr().err
    assert code == 130
    assert len(err.splitlines()) == 1 and "interrupted" in err
    assert sorted(out.rglob("*")) == []


@pytest.mark.parametrize("command", COMMANDS)
def test_help_of_every_command_shows_an_example(command, capsys):
    assert main([command, "--help"]) == 0
    help_text = capsys.readouterr().out
    assert "example" in help_text
    assert f"forcecal {command} " in help_text


def test_version_through_python_m():
    done = subprocess.run([sys.executable, "-m", "forcecal", "--version"], capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"forcecal {forcecal.__version__}"


# --------------------------------------------------------------------------------------------
# missing and unreadable files


@pytest.mark.parametrize("missing", ["rig", "model", "run"])
def test_missing_input_file_of_reconstruct(missing, lab, model_json, tmp_path, capsys):
    files = {"rig": lab / "rig.toml", "model": model_json, "run": lab / "runs" / "paper.csv"}
    files[missing] = tmp_path / {"rig": "nothere.toml", "model": "nothere.json",
                                 "run": "nothere.csv"}[missing]
    out = tmp_path / "out"
    code = cli("reconstruct", files["rig"], files["model"], files["run"], "-o", out)
    assert_refused(code, capsys, out, str(files[missing]))


def test_missing_scan(lab, tmp_path, capsys):
    out = tmp_path / "out"
    code = cli("scan", lab / "rig.toml", tmp_path / "nothere.uff", "-o", out / "model.json")
    assert_refused(code, capsys, out, "nothere.uff")


def test_scan_that_is_not_a_universal_file(lab, tmp_path, capsys):
    scan = tmp_path / "scan.uff"
    scan.write_text("Polytec export\nx,y,velocity\n0.1,0.0,1e-3\nthis is not a UFF\n")
    out = tmp_path / "out"
    code = cli("scan", lab / "rig.toml", scan, "-o", out / "model.json")
    assert_refused(code, capsys, out, str(scan), "Universal File")


@pytest.mark.parametrize("source", ["own", "third-party"])
def test_scan_without_coordinates(source, lab, scan_datasets, tmp_path, capsys):
    if source == "own":
        scan = scan_subset(scan_datasets, tmp_path / "scan.uff", coordinates=False)
    else:
        scan = THIRD_PARTY_UFF58
        if not scan.is_file():
            pytest.skip("third-party UFF samples not available")
    out = tmp_path / "out"
    code = cli("scan", lab / "rig.toml", scan, "-o", out / "model.json")
    assert_refused(code, capsys, out, str(scan), "coordinates", "2411")


def test_scan_without_reference_records(lab, scan_datasets, tmp_path, capsys):
    scan = scan_subset(scan_datasets, tmp_path / "scan.uff",
                       keep=lambda kind, node: kind == "vibration")
    out = tmp_path / "out"
    code = cli("scan", lab / "rig.toml", scan, "-o", out / "model.json")
    assert_refused(code, capsys, out, str(scan), "reference")


def test_scan_point_without_reference(lab, scan_datasets, tmp_path, capsys):
    scan = scan_subset(scan_datasets, tmp_path / "scan.uff",
                       keep=lambda kind, node: not (kind == "reference" and node == 3))
    out = tmp_path / "out"
    code = cli("scan", lab / "rig.toml", scan, "-o", out / "model.json")
    assert_refused(code, capsys, out, str(scan), "node 3", "reference")


# --------------------------------------------------------------------------------------------
# run recordings that cannot be used


def reconstruct_refused(lab, model_json, run, tmp_path, capsys, *names, rig=None) -> str:
    out = tmp_path / "out"
    code = cli("reconstruct", rig or lab / "rig.toml", model_json, run, "-o", out)
    return assert_refused(code, capsys, out, *names)


def test_run_missing_a_channel_of_the_rig(lab, model_json, run_table, tmp_path, capsys):
    def drop_s2(time, columns):
        del columns["s2"]
        return time, columns

    run = edited_run(run_table, tmp_path, drop_s2)
    reconstruct_refused(lab, model_json, run, tmp_path, capsys, str(run), "'s2'")


@pytest.mark.parametrize("bad", [np.nan, np.inf], ids=["nan", "inf"])
def test_run_with_nonfinite_samples(bad, lab, model_json, run_table, tmp_path, capsys):
    def spoil(time, columns):
        columns["s1"][500:503] = bad
        return time, columns

    run = edited_run(run_table, tmp_path, spoil)
    reconstruct_refused(lab, model_json, run, tmp_path, capsys, str(run), "'s1'",
                        "NaN" if np.isnan(bad) else "infinite")


def test_run_with_nonuniform_time_stamps(lab, model_json, run_table, tmp_path, capsys):
    def jitter(time, columns):
        time[500] += 0.3 * (time[1] - time[0])
        return time, columns

    run = edited_run(run_table, tmp_path, jitter)
    reconstruct_refused(lab, model_json, run, tmp_path, capsys, str(run), "not uniform")


def test_run_with_a_clipped_gauge(lab, model_json, run_table, tmp_path, capsys):
    def clip(time, columns):
        peak = np.max(np.abs(columns["R1"]))
        columns["R1"] = np.clip(columns["R1"], -0.9 * peak, 0.9 * peak)
        return time, columns

    run = edited_run(run_table, tmp_path, clip)
    reconstruct_refused(lab, model_json, run, tmp_path, capsys, str(run), "'R1'", "clipped")


def test_run_shorter_than_five_periods(lab, model_json, run_table, tmp_path, capsys):
    def four_periods(time, columns):
        n = int(round(4 / 20.0 / (time[1] - time[0])))
        return time[:n], {k: v[:n] for k, v in columns.items()}

    run = edited_run(run_table, tmp_path, four_periods)
    reconstruct_refused(lab, model_json, run, tmp_path, capsys, str(run), "periods")


@pytest.mark.parametrize("command", ["scan", "reconstruct"])
def test_drive_frequency_contradicted_by_the_data(command, lab, model_json, short_run,
                                                  scan_datasets, tmp_path, capsys):
    rig = edited_rig(lab, tmp_path, lambda d: d["acquisition"].update(frequency=33.0))
    out = tmp_path / "out"
    if command == "scan":
        data = scan_subset(scan_datasets, tmp_path / "scan.uff", n_points=8)
        code = cli("scan", rig, data, "-o", out / "model.json")
    else:
        data = short_run
        code = cli("reconstruct", rig, model_json, data, "-o", out)
    line = assert_refused(code, capsys, out, "33")
    assert str(data) in line or "acquisition.frequency" in line, line


# --------------------------------------------------------------------------------------------
# rig files that contradict themselves


def _set(table: str, index: int, key: str, value):
    def edit(doc):
        doc[table][index][key] = value
    return edit


@pytest.mark.parametrize("edit,key", [
    (_set("gauges", 1, "x", 0.7), "gauges[1].x"),
    (_set("forces", 0, "x", -0.05), "forces[0].x"),
    (_set("sensors", 1, "x", 0.65), "sensors[1].x"),
], ids=["gauge", "force", "sensor"])
def test_point_off_the_structure(edit, key, lab, model_json, tmp_path, capsys):
    rig = edited_rig(lab, tmp_path, edit)
    line = reconstruct_refused(lab, model_json, lab / "runs" / "paper.csv", tmp_path, capsys,
                               str(rig), key, rig=rig)
    assert "off the structure" in line


@pytest.mark.parametrize("edit,key", [
    (_set("sensors", 1, "name", "s1"), "sensors[1].name"),
    (_set("sensors", 0, "name", "R1"), "sensors[0].name"),
], ids=["two-sensors", "sensor-as-gauge"])
def test_duplicate_names(edit, key, lab, model_json, tmp_path, capsys):
    rig = edited_rig(lab, tmp_path, edit)
    line = reconstruct_refused(lab, model_json, lab / "runs" / "paper.csv", tmp_path, capsys,
                               str(rig), key, rig=rig)
    assert "twice" in line


def test_two_forces_at_one_point(lab, model_json, tmp_path, capsys):
    rig = edited_rig(lab, tmp_path, _set("forces", 1, "x", 0.25))
    reconstruct_refused(lab, model_json, lab / "runs" / "paper.csv", tmp_path, capsys,
                        str(rig), "forces[1].x", "same point", rig=rig)


def test_fewer_sensors_than_shapes(lab, model_json, tmp_path, capsys):
    rig = edited_rig(lab, tmp_path, lambda d: d.update(sensors=[]))
    reconstruct_refused(lab, model_json, lab / "runs" / "paper.csv", tmp_path, capsys,
                        str(rig), "sensors", rig=rig)


def test_sensors_at_a_node_of_the_shape(lab, model_json, short_run, tmp_path, capsys):
    def to_the_ends(doc):
        doc["sensors"][0]["x"] = 0.0
        doc["sensors"][1]["x"] = 0.6

    rig = edited_rig(lab, tmp_path, to_the_ends)
    # a model records its rig's sensor layout: this rig's model comes from the scan
    reconstruct_refused(lab, lab / "scan.uff", short_run, tmp_path, capsys,
                        "s1", "s2", "node", rig=rig)


def test_a_model_is_refused_for_another_rig(lab, model_json, short_run, tmp_path, capsys):
    """Editing the rig's masses after 'forcecal scan' makes its model stale: refused, naming
    the key that differs (once the forces were bit-identical with a 1e30 kg armature, which
    the rig's number limits now refuse by themselves)."""
    def heavy(doc):
        doc["structure"]["masses"][0]["mass"] = 2.5

    rig = edited_rig(lab, tmp_path, heavy)
    reconstruct_refused(lab, model_json, short_run, tmp_path, capsys,
                        "structure.masses[0].mass", "forcecal scan", rig=rig)


def test_manifest_naming_a_missing_run(lab, model_json, tmp_path, capsys):
    pytest.importorskip("forcecal.campaign")
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("run,gap\nruns/nothere.csv,0.001\n")
    out = tmp_path / "out"
    code = cli("calibrate", lab / "rig.toml", model_json, "--manifest", manifest, "-o", out)
    assert_refused(code, capsys, out, str(manifest), "runs/nothere.csv")


@pytest.mark.parametrize("command", ["reconstruct", "report"])
def test_two_runs_with_one_name(command, lab, model_json, tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    copy = other / "paper.csv"
    copy.write_bytes((lab / "runs" / "paper.csv").read_bytes())
    out = tmp_path / "out"
    scan = model_json if command == "reconstruct" else lab / "scan.uff"
    code = cli(command, lab / "rig.toml", scan, lab / "runs" / "paper.csv", copy, "-o", out)
    assert_refused(code, capsys, out, str(copy), "paper.forces.csv")


# --------------------------------------------------------------------------------------------
# bad arguments


@pytest.mark.parametrize("argv,named", [
    (["frobnicate"], "frobnicate"),
    ([], "command"),
    (["scan", "rig.toml", "scan.uff"], "-o"),
    (["reconstruct", "rig.toml", "model.json", "run.csv"], "-o"),
    (["predict", "calibration.json", "--current", "lots", "--gap", "0.001"], "--current"),
], ids=["unknown-command", "no-command", "scan-without-o", "reconstruct-without-o",
        "not-a-number"])
def test_bad_arguments(argv, named, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert_refused(main(argv), capsys, tmp_path, named)


# --------------------------------------------------------------------------------------------
# arguments and outputs under interruption


@pytest.mark.parametrize(("argv", "option"), [
    (["--harmonics", "0"], "--harmonics"),
    (["--harmonics", "-3"], "--harmonics"),
])
def test_harmonics_below_one_are_refused_even_with_a_model(lab, model_json, short_run, tmp_path,
                                                           capsys, argv, option):
    out = tmp_path / "out"
    code = cli("reconstruct", lab / "rig.toml", model_json, short_run, "-o", out, *argv)
    assert_refused(code, capsys, out, option)


def test_an_empty_output_path_is_refused(lab, model_json, short_run, tmp_path, capsys,
                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = cli("reconstruct", lab / "rig.toml", model_json, short_run, "-o", "")
    assert_refused(code, capsys, tmp_path / "out", "-o/--output")
    assert not list(tmp_path.iterdir())


def test_a_negative_seed_is_refused(tmp_path, capsys):
    assert_refused(cli("simulate", tmp_path / "out", "--seed", "-1"), capsys, tmp_path / "out",
                   "--seed")


def test_stream_refuses_an_unknown_output_type(lab, model_json, short_run, tmp_path, capsys):
    out = tmp_path / "out.mat"
    code = cli("stream", lab / "rig.toml", model_json, short_run, "-o", out)
    assert_refused(code, capsys, out, "out.mat", ".csv")
    assert not out.exists()


def test_report_refuses_a_missing_truth_folder(lab, model_json, short_run, tmp_path, capsys):
    out = tmp_path / "out"
    code = cli("report", lab / "rig.toml", lab / "scan.uff", short_run, "-o", out,
               "--truth", tmp_path / "nonexistent")
    assert_refused(code, capsys, out, "--truth")


@pytest.mark.parametrize(("current", "gap", "option"), [
    ("1e308", "0.0009", "--current"), ("nan", "0.0009", "--current"),
    ("1", "0.8", "--gap"), ("1", "1e-12", "--gap"), ("1", "inf", "--gap"),
])
def test_predict_refuses_absurd_inputs(tmp_path, capsys, current, gap, option):
    pytest.importorskip("forcecal.campaign")
    from forcecal.actuator import Calibration

    cal = Calibration(law="k_i2_s2", params=np.array([9e-6]), covariance=np.array([[1e-18]]),
                      n_poles=2, current_range=(0.8, 1.2), gap_range=(0.0008, 0.001))
    path = cal.save(tmp_path / "calibration.json")
    code = cli("predict", path, "--current", current, "--gap", gap, "--json")
    assert_refused(code, capsys, tmp_path / "none", option)


def _flux_calibration(tmp_path: Path) -> Path:
    from forcecal.actuator import Calibration

    cal = Calibration(law="flux", params=np.array([8e-4]), covariance=np.array([[1e-18]]),
                      n_poles=2, current_range=(0.2, 1.5), gap_range=(0.0006, 0.0012),
                      flux_range=(1.6e-5, 1.8e-4))
    return cal.save(tmp_path / "calibration.json")


def test_predict_follows_the_flux_law_from_the_flux(tmp_path, capsys):
    pytest.importorskip("forcecal.campaign")
    from forcecal.actuator import predict_flux
    from forcecal.campaign import load_calibration

    path = _flux_calibration(tmp_path)
    assert cli("predict", path, "--flux", "1e-4", "--json") == 0
    out = json.loads(capsys.readouterr().out)
    want = predict_flux(load_calibration(path), 1e-4)
    assert out["law"] == "flux" and out["total_n"] == pytest.approx(float(want.total), rel=1e-12)
    assert out["total_n"] == pytest.approx(2 * 1e-8 / (forcecal.actuator.MU0 * 8e-4), rel=1e-12)
    for argv, named in ((("--current", "1", "--gap", "1e-3"), "--flux"),
                        (("--flux", "1e-4", "--current", "1"), "without --current"),
                        (("--flux", "1e-4", "--frequency", "50"), "--frequency"),
                        (("--flux", "nan"), "argument --flux: nan Wb is not a finite"),
                        (("--flux", "2e-3"), "more than 10 times the largest calibrated flux")):
        assert_refused(cli("predict", path, *argv), capsys, tmp_path / "none", named, "flux")


def test_predict_of_a_current_law_asks_for_current_and_gap(tmp_path, capsys):
    from forcecal.actuator import Calibration

    cal = Calibration(law="k_i2_s2", params=np.array([9e-6]), covariance=np.array([[1e-18]]),
                      n_poles=2, current_range=(0.8, 1.2), gap_range=(0.0008, 0.001))
    path = cal.save(tmp_path / "calibration.json")
    for argv in (("--current", "1"), ("--gap", "1e-3"), ("--current", "1", "--gap", "1e-3",
                                                        "--flux", "1e-4")):
        assert_refused(cli("predict", path, *argv), capsys, tmp_path / "none",
                       "--current A and --gap M", "k_i2_s2")


def test_calibrate_laws_are_checked_and_reach_the_calibration(lab, model_json, tmp_path, capsys,
                                                             monkeypatch):
    import forcecal.campaign

    out = tmp_path / "out"
    code = cli("calibrate", lab / "rig.toml", model_json, "--manifest", lab / "m.csv", "-o", out,
               "--laws", "k_i2_sfe2", "fluxx")
    assert "known: k_i2_s2" in assert_refused(code, capsys, out, "--laws", "'fluxx'")
    no_flux = edited_rig(lab, tmp_path, lambda d: d["actuator"].pop("flux", None))
    code = cli("calibrate", no_flux, model_json, "--manifest", lab / "m.csv", "-o", out,
               "--laws", "flux")
    assert_refused(code, capsys, out, "--laws", "flux channel", str(no_flux))
    asked: list[object] = []

    def calibrate_campaign(*args, laws=None, **kwargs):
        asked.append(laws)
        raise forcecal.errors.InputError("stopped here")

    monkeypatch.setattr(forcecal.campaign, "calibrate_campaign", calibrate_campaign)
    code = cli("calibrate", lab / "rig.toml", model_json, "--manifest", lab / "m.csv", "-o", out,
               "--laws", "flux", "k_i2_sfe2", "flux")
    assert_refused(code, capsys, out, "stopped here")
    assert [[law.name for law in laws] for laws in asked] == [["flux", "k_i2_sfe2"]]


@pytest.mark.parametrize(("law", "flux", "hinted"), [
    ("k_i2_sfe2_sat", np.ones(3), True), ("k_i2_sfe2_sat", None, False),
    ("k_i2_sfe2", np.ones(3), False)])
def test_a_saturating_law_with_the_runs_flux_points_to_the_flux_law(law, flux, hinted, tmp_path):
    from types import SimpleNamespace

    from forcecal.actuator.laws import get_law
    from forcecal.cli.main import _calibration_summary

    fitted = [SimpleNamespace(name=n) for n in ("k_i2_sfe2", "k_i2_sfe2_sat")]
    result = SimpleNamespace(
        calibration=SimpleNamespace(law=law, law_object=get_law(law), params=np.array([1e-5]),
                                    stderr=np.array([1e-9])),
        uncertainty=None, runs=[SimpleNamespace(samples=SimpleNamespace(flux=flux), name="r",
                                                estimate=SimpleNamespace(notes=()))] * 2,
        note_kinds=lambda: [],
        selection=SimpleNamespace(candidates=fitted, skipped=(("power", "why"),),
                                  best=SimpleNamespace(held_out=SimpleNamespace(rms=0.015))))
    lines = _calibration_summary(result, tmp_path, certificate=False)
    hint = [line for line in lines if "--laws flux" in line]
    assert hint == ([] if not hinted else [
        "  the iron saturates and the runs carry the flux: add the flux law, f = phi^2 / "
        "(mu0 A_eff), to the candidates with --laws flux k_i2_sfe2 k_i2_sfe2_sat power"])


def test_a_failed_command_leaves_the_old_outputs_and_no_staging(lab, model_json, short_run,
                                                                tmp_path, capsys):
    out = tmp_path / "out"
    assert cli("reconstruct", lab / "rig.toml", model_json, short_run, "-o", out) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    bad = tmp_path / "bad" / short_run.name
    bad.parent.mkdir()
    bad.write_text(short_run.read_text().replace("time,", "time,", 1) + "1e9,1,1,1,1,1,1,1\n")
    assert cli("reconstruct", lab / "rig.toml", model_json, bad, "-o", out) == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_leftovers_of_a_killed_command_are_cleaned_or_finished(tmp_path):
    import os

    from forcecal.io.staging import JOURNAL, STAGING_PREFIX, clean_stale

    out = tmp_path / "out"
    dead = out / f"{STAGING_PREFIX}999999999-x"          # no such process
    dead.mkdir(parents=True)
    (dead / "half.csv").write_text("partial")
    stopped = out / f"{STAGING_PREFIX}999999998-y"       # killed while moving its files
    stopped.mkdir()
    (stopped / "b.json").write_text("new b")
    (out / "a.csv").write_text("new a")                  # already moved
    (out / "b.json").write_text("old b")
    (out / JOURNAL).write_text(json.dumps({"staging": stopped.name,
                                           "files": ["a.csv", "b.json"]}))
    part = out / ".a.csv.abc.part"
    part.write_text("x")
    os.utime(part, (0, 0))
    clean_stale(out)
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", "b.json"]
    assert (out / "b.json").read_text() == "new b"


def test_outputs_say_where_they_come_from(paper_dir, tmp_path):
    """MODEL.json and every NAME.json carry the provenance: version, date, command line and
    the SHA-256 of each input file, as the files are."""
    import hashlib

    from forcecal import __version__
    from forcecal.model.spatial import load_model

    model = tmp_path / "model.json"
    run = paper_dir / "runs" / "paper.csv"
    assert main(["scan", str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"),
                 "-o", str(model)]) == 0
    assert main(["reconstruct", str(paper_dir / "rig.toml"), str(model), str(run),
                 "-o", str(tmp_path / "out")]) == 0
    for doc in (json.loads(model.read_text()),
                json.loads((tmp_path / "out" / "paper.json").read_text())):
        prov = doc["provenance"]
        assert prov["forcecal_version"] == __version__ and prov["created_utc"].endswith("+00:00")
        files = {f["path"]: f["sha256"] for f in prov["inputs"]}
        for path in (paper_dir / "rig.toml", *([run, model] if "series" in doc else
                                                [paper_dir / "scan.uff"])):
            assert files[str(path)] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert "reconstruct" in prov["command"]
    load_model(model)                                    # the provenance is not in the way


def test_quiet_and_verbose(paper_dir, tmp_path, capsys, monkeypatch):
    """-q: nothing on stdout or stderr on success; by default the paths on stdout and progress
    on a terminal only; -v: every force's uncertainty budget on stdout, as an aligned table."""
    rig, scan, run = (str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff"),
                      str(paper_dir / "runs" / "paper.csv"))
    copy = tmp_path / "again.csv"
    copy.write_bytes(Path(run).read_bytes())
    assert main(["reconstruct", rig, scan, run, str(copy), "-o", str(tmp_path / "a"), "-q"]) == 0
    out = capsys.readouterr()
    assert (out.out, out.err) == ("", "")
    assert sorted(p.name for p in (tmp_path / "a").iterdir())[:2] == ["again.forces.csv",
                                                                      "again.json"]
    assert main(["reconstruct", rig, scan, run, str(copy), "-o", str(tmp_path / "b")]) == 0
    out = capsys.readouterr()
    assert out.err == ""                              # stderr is not a terminal: no progress
    assert out.out.splitlines()[0].startswith(str(tmp_path / "b" / "paper.forces.csv"))
    monkeypatch.setattr(sys.modules["forcecal.cli.main"], "_interactive", lambda: True)
    assert main(["reconstruct", rig, scan, run, str(copy), "-o", str(tmp_path / "d")]) == 0
    assert "left)" in capsys.readouterr().err                      # progress with the time left
    assert main(["reconstruct", rig, scan, run, "-o", str(tmp_path / "c"), "-v"]) == 0
    text = capsys.readouterr().out
    assert "uncertainty budget" in text and "gauge noise" in text and "expanded k = 2" in text
    lines = text.splitlines()
    head = next(k for k, line in enumerate(lines) if "uncertainty budget" in line)
    table = lines[head + 1: lines.index(next(x for x in lines if "expanded k = 2" in x)) + 1]
    assert table[0].split() == ["F1", "F2", "total"]
    assert table[1].split() == ["source", *["DC", "n", "=", "1"] * 3]
    assert len(table) > 4 and len({len(line) for line in table}) == 1, text
    ends = {m.end() for line in table[1:]                # after each row's label, its cells
            for m in list(re.finditer(r"\S+(?= {2,}|$)", line))[1:]}
    assert len(ends) == 6, text                         # right-aligned: one end per column
