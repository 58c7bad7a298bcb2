"""A steady rig (``acquisition.frequency``) given records under a sweep says that the drive
sweeps, over which band, and which keys to declare, instead of "the data contradict the
nominal drive frequency"; steady records (noise, hum, harmonics, drift, a nominal frequency a
little or far off) keep their behaviour.

The simulated 'sweep' rig, made small: its scan (15 points, 1 s records of a periodic chirp
5-200 Hz every 0.25 s), the first 2 s of its sweep run (10 -> 150 Hz over 4 s: 10-80 Hz) and
one stepped-sine run at 46.42 Hz.
"""

from __future__ import annotations

import dataclasses
import re
import tomllib

import numpy as np
import pytest
import tomli_w

from forcecal.cli.main import main
from forcecal.signals.sweeps import swept_drive
from forcecal.simulate import presets
from forcecal.simulate.export import write_simulation

STEADY = "g1000_f46p42"
"""The stepped-sine run kept: 46.42 Hz (the generator 0.07 % fast)."""
FS = 2000.0
BAND = re.compile(r"acquisition\.band = \[([\d.]+), ([\d.]+)\]")
SWEEPS = re.compile(r"sweeps from about ([\d.]+) to ([\d.]+) Hz")


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    full = presets.get_preset("sweep")
    small = dataclasses.replace(
        full, scan=dataclasses.replace(full.scan, n_points=15),
        runs=(dataclasses.replace(full.runs[0], duration=2.0),
              next(r for r in full.runs if r.name == STEADY)))
    out = tmp_path_factory.mktemp("sweep")
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(presets.PRESETS, "sweep", lambda: small)
        write_simulation(out, "sweep", seed=0)
    return out


def rig_with(sweep_dir, folder, name="rig.toml", **acquisition):
    """The simulated rig with ``acquisition`` in place of its own (band, drive 'any')."""
    doc = tomllib.loads((sweep_dir / "rig.toml").read_text(encoding="utf-8"))
    doc["acquisition"] = acquisition
    path = folder / name
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def model_json(sweep_dir, tmp_path_factory):
    """The broadband model of the chirp scan (its rig declares the band)."""
    folder = tmp_path_factory.mktemp("model")
    rig = rig_with(sweep_dir, folder, frequency=46.42, band=[5.0, 200.0])
    assert main(["scan", str(rig), str(sweep_dir / "scan.uff"), "-o",
                 str(folder / "model.json")]) == 0
    return folder / "model.json"


def refused(code, capsys, out):
    """The one line on stderr of a refusal (exit 2, nothing written)."""
    assert code == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert not out.exists()
    return lines[0]


# --------------------------------------------------------------------------------------------
# through the command line


def test_a_swept_scan_on_a_steady_rig_names_the_band_to_declare(sweep_dir, tmp_path, capsys):
    rig = rig_with(sweep_dir, tmp_path, frequency=122.384)
    scan = sweep_dir / "scan.uff"
    out = tmp_path / "out"
    line = refused(main(["scan", str(rig), str(scan), "-o", str(out / "model.json")]),
                   capsys, out)
    assert f"scan '{scan}'" in line and "reference (the coil current)" in line, line
    assert "in each record" in line and "not a steady drive" in line, line
    assert "'acquisition.frequency' = 122.384 Hz" in line, line
    assert "acquisition.drive = 'any'" in line and "contradict" not in line, line
    said = [float(v) for v in SWEEPS.search(line).groups()]
    band = [float(v) for v in BAND.search(line).groups()]
    assert said == band
    assert 2.0 <= band[0] <= 7.0 and 198.0 <= band[1] <= 212.0, band   # the chirp: 5-200 Hz
    # the band it names builds the model
    fixed = rig_with(sweep_dir, tmp_path, "fixed.toml", frequency=122.384, band=band)
    capsys.readouterr()
    assert main(["scan", str(fixed), str(scan), "-o", str(out / "model.json")]) == 0
    assert (out / "model.json").is_file()


def test_a_swept_run_on_a_steady_rig_names_the_run(sweep_dir, model_json, tmp_path, capsys):
    rig = rig_with(sweep_dir, tmp_path, frequency=46.42)
    run = sweep_dir / "runs" / "sweep.csv"
    out = tmp_path / "out"
    line = refused(main(["reconstruct", str(rig), str(model_json), str(run), "-o", str(out)]),
                   capsys, out)
    assert f"run '{run}'" in line and "coil current 'i'" in line, line
    assert f"rig '{rig}' key 'acquisition.frequency' = 46.42 Hz" in line, line
    assert "acquisition.drive = 'any'" in line and "contradict" not in line, line
    low, high = (float(v) for v in SWEEPS.search(line).groups())
    assert 6.0 <= low <= 11.0 and 78.0 <= high <= 88.0, (low, high)  # 10 -> 80 Hz in 2 s


@pytest.mark.parametrize(("nominal", "accepted"), [(46.42, True), (45.5, True), (40.0, False)])
def test_a_steady_run_keeps_its_behaviour(sweep_dir, model_json, tmp_path, capsys, nominal,
                                          accepted):
    """Exact, 2 % off (within the search) or 14 % off (contradicted, as before)."""
    rig = rig_with(sweep_dir, tmp_path, frequency=nominal)
    out = tmp_path / "out"
    code = main(["reconstruct", str(rig), str(model_json),
                 str(sweep_dir / "runs" / f"{STEADY}.csv"), "-o", str(out)])
    if accepted:
        assert code == 0 and (out / f"{STEADY}.forces.csv").is_file()
        return
    line = refused(code, capsys, out)
    assert "contradict the nominal drive frequency of 40 Hz" in line and "sweeps" not in line


# --------------------------------------------------------------------------------------------
# the recognition itself, on synthetic records


def chirp(t, f_start, f_stop, log=False):
    """A sine swept from f_start to f_stop [Hz] over t."""
    span = t[-1]
    if log:
        k = np.log(f_stop / f_start) / span
        return np.sin(2 * np.pi * f_start * np.expm1(k * t) / k)
    return np.sin(2 * np.pi * (f_start * t + (f_stop - f_start) * t**2 / (2 * span)))


@pytest.fixture(scope="module")
def t():
    return np.arange(int(4 * FS)) / FS


@pytest.mark.parametrize(("case", "low", "high"), [
    ("linear", 20.0, 200.0), ("logarithmic", 10.0, 150.0), ("stepped", 20.0, 110.0)])
def test_sweeps_are_recognised_with_their_band(t, case, low, high):
    rng = np.random.default_rng(3)
    if case == "stepped":
        steps = np.repeat(np.arange(20.0, 111.0, 10.0), t.size // 10 + 1)[:t.size]
        x = np.sin(2 * np.pi * np.cumsum(steps) / FS)
    else:
        x = chirp(t, low, high, log=case == "logarithmic")
    sweep = swept_drive([0.6 + 0.1 * x + 1e-3 * rng.standard_normal(t.size)], FS)
    assert sweep is not None and sweep.where == "over the record"
    assert low * 0.5 <= sweep.low <= low * 1.1, sweep
    assert high * 0.9 <= sweep.high <= high * 1.15, sweep


def test_several_records_say_how_many_sweep(t):
    swept = [chirp(t, 20.0, 200.0)] * 3
    steady = [np.sin(2 * np.pi * 40.0 * t)] * 2
    sweep = swept_drive(swept + steady, FS)
    assert sweep is not None and sweep.where == "in 3 of its 5 records"
    assert swept_drive(swept[:2] + steady + steady, FS) is None    # fewer than half


STEADY_RECORDS = {
    "noisy": lambda t, rng: np.sin(2 * np.pi * 40 * t) + 0.3 * rng.standard_normal(t.size),
    "hum": lambda t, rng: np.sin(2 * np.pi * 40 * t) + 0.9 * np.sin(2 * np.pi * 50 * t),
    "harmonics": lambda t, rng: (np.sin(2 * np.pi * 40 * t) + 0.3 * np.sin(4 * np.pi * 40 * t)
                                 + 0.2 * np.sin(6 * np.pi * 40 * t)),
    "drift 2 %": lambda t, rng: chirp(t, 40.0, 40.8),
    "modulated": lambda t, rng: (1 + 0.2 * np.sin(2 * np.pi * 0.5 * t))
    * np.sin(2 * np.pi * 40 * t),
    "another frequency": lambda t, rng: 0.6 + 0.1 * np.sin(2 * np.pi * 55 * t),
    "noise alone": lambda t, rng: rng.standard_normal(t.size),
    "constant": lambda t, rng: np.full(t.size, 0.6),
}


@pytest.mark.parametrize("case", list(STEADY_RECORDS))
def test_steady_records_and_noise_are_not_sweeps(t, case):
    x = STEADY_RECORDS[case](t, np.random.default_rng(5))
    assert swept_drive([x], FS) is None
    assert swept_drive([x[:40]], FS) is None                        # too short to tell
