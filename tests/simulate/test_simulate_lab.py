"""The ``lab`` virtual rig: every imperfection at its stated level, the ideal option unchanged,
and an estimate from a ``lab`` run that agrees with the truth within its stated uncertainty.

Levels are measured on what the simulator writes (the run CSVs, the scan UFF, the truth), or,
for the spectra that need long records, on :func:`forcecal.simulate.lab.read_channel`, which
every ``lab`` channel goes through.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import welch

from forcecal.cli.main import main
from forcecal.forces.diagnostics import DRIFT_TOLERANCE, drift_notes
from forcecal.forces.steady import reconstruct
from forcecal.io.manifest import read_manifest
from forcecal.io.run_files import read_run
from forcecal.io.uff import read_scan_uff
from forcecal.model.spatial import build_spatial_model
from forcecal.rig import load_rig
from forcecal.signals.harmonics import fit_harmonics, refine_fundamental
from forcecal.simulate import presets
from forcecal.simulate.export import write_simulation
from forcecal.simulate.lab import (
    LabErrors,
    draw_errors,
    draw_run_drift,
    gravity_preload,
    measure_lab_run,
    read_channel,
    record_lab_scan,
)
from forcecal.simulate.magnet import Drive
from forcecal.simulate.presets import NoiseSpec, get_preset
from forcecal.simulate.realism import LAB_TYPE_B, Realism, resolve_realism
from forcecal.simulate.virtual_rig import (
    build_model,
    public_rig,
    record_run,
    scan_points,
    simulate_response,
)

FS = 10_000.0
LAB = Realism()
KINDS = {"R1": "gauge", "R2": "gauge", "s1": "probe", "s2": "probe", "i": "current",
         "phi": "flux", "v": "voltage"}
HUM_ABS = 0.1             # hum amplitude tolerance, in units of the channel's white sigma
PINK_SLOPE_TOL = 0.1      # the pink PSD's log-log slope: -1 within this
PINK_LEVEL_RTOL = 0.15    # the pink PSD at 1 Hz: (2 sigma^2 / fs) * corner within this
Z_MAX = 3.0               # end to end: |error| within this many combined standard uncertainties
_PAPER = presets.PRESETS["paper"]


def short_paper(n_points: int = 9, record: float = 0.2, duration: float = 0.3) -> presets.Preset:
    p = _PAPER()
    return dataclasses.replace(
        p, scan=dataclasses.replace(p.scan, n_points=n_points, record=record),
        runs=tuple(dataclasses.replace(r, duration=duration) for r in p.runs))


def sigma_of(kind: str) -> float:
    return float(getattr(NoiseSpec(), kind))


def step_of(kind: str) -> float:
    return float(getattr(LAB.adc, kind).step)


def hum_amplitudes(x: np.ndarray, fs: float, f0: float | None = None,
                   n_harm: int = 15) -> np.ndarray:
    """Least-squares amplitudes of the mains lines (50, 150, 250 Hz) of each record (rows),
    fitted jointly with a DC, a linear trend and, given f0, the drive's harmonics."""
    x = np.atleast_2d(x)
    t = np.arange(x.shape[1]) / fs
    cols = [np.ones_like(t), t - t.mean()]
    freqs = [h * LAB.mains for h, _ in LAB.hum]
    if f0 is not None:
        freqs += [n * f0 for n in range(1, n_harm + 1)]
    for f in freqs:
        cols += [np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)]
    a = np.column_stack(cols)
    coef = np.linalg.lstsq(a, x.T, rcond=None)[0]
    k = len(LAB.hum)
    return np.hypot(coef[2:2 + 2 * k:2], coef[3:3 + 2 * k:2]).T        # (n_records, 3)


def true_reactions(npz) -> np.ndarray:
    """The paper beam's gauge forces from the truth: R = J - Psi f (gauges at 0 and 0.6 m,
    poles at 0.25 and 0.35 m)."""
    x = np.array([0.25, 0.35])
    psi = np.stack([(0.6 - x) / 0.6, x / 0.6])
    return npz["inertia"] - psi @ npz["pole_force"]


# --------------------------------------------------------------------------------------------
# the ideal option is the default and has not changed


def test_ideal_is_the_default():
    assert resolve_realism("ideal") is None and resolve_realism(None) is None
    assert get_preset("paper") == get_preset("paper", "ideal")
    assert get_preset("paper").realism is None
    assert public_rig(get_preset("paper")).type_b.gauge_scale == 0.0
    lab = get_preset("paper", "lab")
    assert lab.name == "paper" and lab.realism == Realism()
    assert [r.name for r in lab.runs] == ["paper", "tare"] and lab.runs[1].tare
    campaign = get_preset("campaign", "lab")                  # keeps its own tare
    assert [r.name for r in campaign.runs] == [r.name for r in get_preset("campaign").runs]


def test_ideal_files_are_bit_identical_to_the_default(tmp_path, monkeypatch):
    monkeypatch.setitem(presets.PRESETS, "paper", short_paper)
    a = write_simulation(tmp_path / "a", "paper", seed=5)
    b = write_simulation(tmp_path / "b", "paper", seed=5, realism="ideal")
    names = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for name in names:
        if name.suffix == ".npz":
            with np.load(a / name) as x, np.load(b / name) as y:
                assert sorted(x.files) == sorted(y.files)
                for key in x.files:
                    np.testing.assert_array_equal(x[key], y[key])
        else:
            assert (a / name).read_bytes() == (b / name).read_bytes(), str(name)
    assert "realism" not in json.loads((a / "truth" / "simulator.json").read_text())


def test_ideal_run_is_white_noise_drawn_as_it_always_was():
    """An ideal run recomputed the way it has always been drawn: every gauge, every probe, then
    each magnet's current, flux and voltage, each with its white noise in that order."""
    preset = short_paper(duration=0.1)
    model = build_model(preset)
    spec = preset.runs[0]
    run, _ = record_run(preset, spec, np.random.default_rng(11), model)
    r = simulate_response(preset, spec.drives, spec.gap, spec.duration, model)
    rng = np.random.default_rng(11)
    noise = preset.noise
    gx = np.array([x for _, x in preset.beam.gauges])
    rows = model.row(gx)
    gauges = -preset.beam.gauge_stiffness * (rows @ r.u + model.beta * (rows @ r.v))
    probes = model.row(np.array([x for _, x in preset.sensors])) @ r.u
    n = len(r.t)
    expected = {"R1": gauges[0] + noise.gauge * rng.standard_normal(n),
                "R2": gauges[1] + noise.gauge * rng.standard_normal(n),
                "s1": probes[0] + noise.probe * rng.standard_normal(n),
                "s2": probes[1] + noise.probe * rng.standard_normal(n),
                "i": r.current[0] + noise.current * rng.standard_normal(n),
                "phi": r.flux[0] + noise.flux * rng.standard_normal(n),
                "v": r.voltage[0] + noise.voltage * rng.standard_normal(n)}
    assert list(run.channels) == list(expected)
    for name, values in expected.items():
        np.testing.assert_array_equal(run.channels[name], values)


# --------------------------------------------------------------------------------------------
# the noise of every channel: pink, hum, quantization


def pink_psd(kind: str, n_records: int, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(f, PSD less the white floor, the floor) of a silent channel of ``kind``: Welch over
    ``n_records`` records of 2**20 samples (105 s)."""
    sigma = sigma_of(kind)
    x = read_channel(np.zeros((n_records, 2**20)), kind, sigma, LAB, FS,
                     np.random.default_rng(seed))
    f, psd = welch(x - x.mean(axis=-1, keepdims=True), fs=FS, nperseg=2**16, axis=-1)
    psd = psd.mean(axis=0)
    floor = float(np.median(psd[(f > 2000) & (f < 4000)]))          # white and quantization
    return f, psd - floor, floor


def test_pink_noise_falls_as_one_over_f():
    f, pink, _ = pink_psd("gauge", 4, 3)
    band = (f >= 0.1) & (f <= 3.0)
    slope, intercept = np.polyfit(np.log(f[band]), np.log(pink[band]), 1)
    assert abs(slope + 1) < PINK_SLOPE_TOL
    sigma = sigma_of("gauge")
    assert math.exp(intercept) == pytest.approx(2 * sigma**2 / FS * LAB.flicker_corner,
                                                rel=PINK_LEVEL_RTOL)


@pytest.mark.parametrize("kind", ["gauge", "probe", "current", "flux", "voltage", "ldv"])
def test_pink_noise_level_of_every_kind(kind):
    """f * PSD of the pink part is flat at (2 sigma^2 / fs) * corner; the floor is the white
    noise's and the quantization's."""
    sigma = sigma_of(kind)
    f, pink, floor = pink_psd(kind, 1, 4)
    np.testing.assert_allclose(floor, 2 * sigma**2 / FS + 2 * step_of(kind) ** 2 / 12 / FS,
                               rtol=0.05)
    band = (f >= 0.1) & (f <= 3.0)
    assert np.mean(f[band] * pink[band]) == pytest.approx(
        2 * sigma**2 / FS * LAB.flicker_corner, rel=PINK_LEVEL_RTOL)


@pytest.mark.parametrize("kind", ["gauge", "probe", "current", "flux", "voltage", "ldv"])
def test_hum_lines_at_their_levels(kind):
    sigma = sigma_of(kind)
    x = read_channel(np.zeros((8, 2**15)), kind, sigma, LAB, FS, np.random.default_rng(4))
    amps = hum_amplitudes(x, FS) / sigma
    np.testing.assert_allclose(amps, np.tile([a for _, a in LAB.hum], (8, 1)), atol=HUM_ABS)


def test_adc_quantizes_and_saturates():
    adc = LAB.adc.gauge
    assert adc.step == 400.0 / 2**16
    x = np.array([0.0, 0.4 * adc.step, 0.6 * adc.step, -1e9, 1e9])
    np.testing.assert_array_equal(adc.quantize(x), [0.0, 0.0, adc.step, -200.0,
                                                    200.0 - adc.step])


# --------------------------------------------------------------------------------------------
# a lab 'paper' rig written in the public formats


@pytest.fixture(scope="module")
def lab_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("lab")
    return write_simulation(out, "paper", seed=1, realism="lab")


@pytest.fixture(scope="module")
def facts(lab_dir):
    return json.loads((lab_dir / "truth" / "simulator.json").read_text())["realism"]


def test_rig_file_declares_the_type_b_and_the_truth_states_every_error(lab_dir, facts):
    assert load_rig(lab_dir / "rig.toml").type_b == LAB_TYPE_B
    assert set(facts["sensitivity"]) == {"R1", "R2", "s1", "s2", "i"}
    assert set(facts["gauge_offset_N"]) == set(facts["gravity_preload_N"]) == {"R1", "R2"}
    assert set(facts["runs"]) == {"paper", "tare"}
    assert facts["settings"]["type_b"]["gauge_scale"] == LAB_TYPE_B.gauge_scale
    [walk] = facts["scans"]
    assert len(walk["drive_level"]) == len(walk["frequency_Hz"]) == 61
    with np.load(lab_dir / "truth" / "paper.npz") as npz:
        assert float(npz["drive_drift"]) == facts["runs"]["paper"]["drive_drift_per_s"]
        gains = dict(zip(npz["sensitivity_channels"].tolist(), npz["sensitivity"].tolist(),
                         strict=True))
    assert {k: gains[k] for k in facts["sensitivity"]} == facts["sensitivity"]
    entries = read_manifest(lab_dir / "manifest.csv")
    assert [(e.run.name, e.tare) for e in entries] == [("paper.csv", False), ("tare.csv", True)]


def test_every_run_channel_is_quantized_and_hums(lab_dir):
    run = read_run(lab_dir / "runs" / "paper.csv")
    f0 = refine_fundamental(run.channels["i"], run.fs, 20.0, 4)
    for name, kind in KINDS.items():
        x = np.asarray(run.channels[name])
        codes = x / step_of(kind)
        np.testing.assert_allclose(codes, np.round(codes), rtol=0, atol=1e-6)
        amps = hum_amplitudes(x, run.fs, f0)[0] / sigma_of(kind)
        np.testing.assert_allclose(amps, [a for _, a in LAB.hum], atol=HUM_ABS, err_msg=name)


def test_every_scan_record_is_quantized_and_hums_with_its_own_phase(lab_dir):
    scan = read_scan_uff(lab_dir / "scan.uff")
    for records, kind in ((scan.response, "ldv"), (scan.reference, "current")):
        codes = records / step_of(kind)
        np.testing.assert_allclose(codes, np.round(codes), rtol=0, atol=1e-5)
        amps = hum_amplitudes(records, scan.fs, 20.014) / sigma_of(kind)
        np.testing.assert_allclose(amps.mean(axis=0), [a for _, a in LAB.hum], atol=HUM_ABS)
    t = np.arange(scan.response.shape[1]) / scan.fs
    phases = np.angle(scan.response @ np.exp(-2j * np.pi * LAB.mains * t))
    assert np.abs(np.mean(np.exp(1j * phases))) < 0.5                 # spread, not one phase


# --------------------------------------------------------------------------------------------
# the rig's errors: sensitivities, gravity preload, offsets, tare


def test_sensitivities_scale_what_each_sensor_reads(lab_dir, facts):
    run = read_run(lab_dir / "runs" / "paper.csv")
    with np.load(lab_dir / "truth" / "paper.npz") as npz:
        truth = {"R1": true_reactions(npz)[0], "R2": true_reactions(npz)[1],
                 "s1": npz["w"][10].astype(float), "s2": npz["w"][50].astype(float),
                 "i": npz["current"][0]}
        np.testing.assert_allclose(npz["nodes"][[10, 50]], [0.1, 0.5], atol=1e-12)
    f0 = refine_fundamental(run.channels["i"], run.fs, 20.0, 4)
    for name, true in truth.items():
        measured = fit_harmonics(np.asarray(run.channels[name]), run.fs, f0, 4).phasors[1]
        expected = fit_harmonics(true, run.fs, f0, 4).phasors[1]
        ratio = abs(measured) / abs(expected)
        gain = facts["sensitivity"][name]
        assert ratio == pytest.approx(gain, abs=1e-3 if name[0] == "s" else 3e-4), name
    gains = np.array(list(facts["sensitivity"].values()))
    assert np.all(np.abs(gains - 1) > 1e-5)                        # every one was drawn


def test_sensitivity_errors_follow_the_declared_uncertainty():
    preset = get_preset("paper", "lab")
    model = build_model(preset)
    rng = np.random.default_rng(7)
    draws = [draw_errors(preset, model, rng) for _ in range(2000)]
    for name, u in (("R1", LAB_TYPE_B.gauge_scale), ("s2", LAB_TYPE_B.probe_scale),
                    ("i", LAB_TYPE_B.current_scale)):
        e = np.array([d.sensitivity[name] - 1 for d in draws])
        assert np.std(e) == pytest.approx(u, rel=0.08) and abs(np.mean(e)) < 4 * u / 44
    offsets = np.array([d.offset["R2"] for d in draws])
    assert np.std(offsets) == pytest.approx(LAB.gauge_offset, rel=0.08)


def test_gravity_preload_carries_the_whole_weight():
    preset = get_preset("paper", "lab")
    b = preset.beam
    weight = (b.mass_per_length * b.length + sum(m for _, m in b.masses)) * LAB.gravity
    preload = gravity_preload(preset, build_model(preset), LAB.gravity)
    assert preload.sum() == pytest.approx(weight, rel=1e-9)
    # the armature at 0.3 m of a 0.6 m span: symmetric, each gauge half the weight
    np.testing.assert_allclose(preload, weight / 2, rtol=1e-9)


def test_tare_carries_the_preload_and_offsets(lab_dir, facts):
    tare = read_run(lab_dir / "runs" / "tare.csv")
    for g in ("R1", "R2"):
        expected = (facts["sensitivity"][g] * facts["gravity_preload_N"][g]
                    + facts["gauge_offset_N"][g])
        assert expected == pytest.approx(facts["gauge_zero_reading_N"][g], rel=1e-12)
        assert abs(expected) > 5.0                                   # a real tare
        assert np.mean(tare.channels[g]) == pytest.approx(expected, abs=0.01)
    with np.load(lab_dir / "truth" / "tare.npz") as npz:
        assert np.max(np.abs(npz["pole_force"])) == 0.0


# --------------------------------------------------------------------------------------------
# the drive's drifts


def test_run_drift_levels():
    rng = np.random.default_rng(9)
    draws = np.array([draw_run_drift(LAB, rng) for _ in range(4000)])
    assert np.std(draws[:, 0]) == pytest.approx(LAB.run_level_drift, rel=0.05)
    assert np.std(draws[:, 1]) == pytest.approx(LAB.run_frequency_drift, rel=0.05)
    # a drive 5 sigma off in both stays clear of the drift note (1e-3 of f0 over a record)
    t = np.arange(int(FS)) / FS
    current = Drive("current", 0.6, 0.2, 20.014, drift=5 * LAB.run_level_drift,
                    chirp=5 * LAB.run_frequency_drift).value(t)
    assert drift_notes(np.asarray(current), FS, 20.014, "x") == []
    spread = 0.75 * 5 * LAB.run_frequency_drift          # between the first and last quarter
    assert spread < 0.2 * DRIFT_TOLERANCE


def test_a_run_is_driven_by_its_drifting_drive():
    base = get_preset("campaign", "lab")
    spec = dataclasses.replace(base.runs[0], duration=0.2)
    preset = dataclasses.replace(base, runs=(spec,))
    model = build_model(preset)
    _, truth = record_run(preset, spec, np.random.default_rng(2), model)
    drift, chirp = float(truth.imperfections["drive_drift"]), float(
        truth.imperfections["drive_chirp"])
    assert drift != 0.0 and chirp != 0.0
    d = spec.drives[0]
    drifting = Drive(d.source, d.dc, d.ac, d.frequency, d.phase, drift=drift, chirp=chirp)
    np.testing.assert_allclose(truth.current[0], drifting.value(truth.t), rtol=1e-12, atol=0)


def test_scan_drive_walks_from_point_to_point(lab_dir, facts):
    walk = facts["scans"][0]
    level = np.array(walk["drive_level"])
    freq = np.array(walk["frequency_Hz"])
    assert np.std(np.diff(level)) == pytest.approx(LAB.scan_level_step, rel=0.35)
    assert np.std(np.diff(freq / 20.014)) == pytest.approx(LAB.scan_frequency_step, rel=0.35)
    scan = read_scan_uff(lab_dir / "scan.uff")
    f0 = refine_fundamental(scan.reference, scan.fs, 20.0, 4)
    amp = np.abs(fit_harmonics(scan.reference, scan.fs, f0, 4).phasors[:, 1])
    assert np.ptp(level) > 1e-3                                     # a walk worth seeing
    # the reference follows the walk; a voltage-driven coil's current with a slope below 1
    # (its inductance grows as the DC pull closes the gap)
    assert np.corrcoef(amp, level)[0, 1] > 0.9


def test_scan_records_are_the_steady_state_under_each_points_drive():
    """A noise-free lab scan: each record is the rig's response to that point's own drive (a
    direct simulation), to within one ADC step."""
    preset = dataclasses.replace(short_paper(n_points=4, record=0.1), realism=Realism(
        scan_level_step=2e-3, scan_frequency_step=5e-5),
        noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    model = build_model(preset)
    errors = LabErrors(sensitivity={"i": 1.003}, offset={"R1": 0.0, "R2": 0.0},
                       preload={"R1": 0.0, "R2": 0.0})
    scan, walk = record_lab_scan(preset, np.random.default_rng(1), model, errors=errors)
    n_rec = scan.response.shape[1]
    rows = model.row(scan_points(preset))
    for k in (3,):
        drives = tuple(d.scaled(walk.level[k], walk.frequency[k]) for d in preset.scan.drives)
        r = simulate_response(preset, drives, None, (walk.start[k] + n_rec) / FS, model)
        window = slice(int(walk.start[k]), int(walk.start[k]) + n_rec)
        np.testing.assert_allclose(scan.response[k], (rows @ r.v)[k, window], rtol=0,
                                   atol=step_of("ldv"))
        np.testing.assert_allclose(scan.reference[k], 1.003 * r.current[0, window], rtol=0,
                                   atol=step_of("current"))


def test_a_lab_channel_without_errors_reads_the_truth():
    """measure_lab_run with unit gains and no preload: the gauges read the simulated forces
    (noise and quantization aside)."""
    preset = dataclasses.replace(short_paper(duration=0.1), realism=Realism(),
                                 noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    model = build_model(preset)
    spec = preset.runs[0]
    r = simulate_response(preset, spec.drives, None, spec.duration, model)
    errors = LabErrors(sensitivity={}, offset={"R1": 0.5, "R2": 0.0},
                       preload={"R1": 0.0, "R2": 0.0})
    run = measure_lab_run(preset, spec, model, r, np.random.default_rng(0), errors)
    rows = model.row(np.array([0.0, 0.6]))
    gauges = -preset.beam.gauge_stiffness * (rows @ r.u + model.beta * (rows @ r.v))
    np.testing.assert_allclose(run.channels["R1"], gauges[0] + 0.5, atol=step_of("gauge") / 2)
    np.testing.assert_allclose(run.channels["i"], r.current[0], atol=step_of("current") / 2)


# --------------------------------------------------------------------------------------------
# end to end: the estimate of a lab run against the truth


@pytest.fixture(scope="module")
def estimate(lab_dir):
    rig = load_rig(lab_dir / "rig.toml")
    model = build_spatial_model(rig, read_scan_uff(lab_dir / "scan.uff"))
    run = read_run(lab_dir / "runs" / "paper.csv", rig)
    tare = read_run(lab_dir / "runs" / "tare.csv", rig)
    return reconstruct(rig, model, run, tare=tare)


def test_estimate_agrees_with_the_truth_within_its_uncertainty(lab_dir, estimate):
    """DC and fundamental of every force and of the total within Z_MAX combined standard
    uncertainties (a phasor's: the root sum of its Re and Im variances)."""
    est = estimate
    with np.load(lab_dir / "truth" / "paper.npz") as npz:
        forces = npz["pole_force"]
    truth = fit_harmonics(forces, FS, est.f0, len(est.harmonics) - 1).phasors
    truth = np.vstack([truth, truth.sum(axis=0)])
    names = [*est.force_names, "total"]
    assert est.combination_std is not None
    rows = [list(est.combination_names).index(n) for n in names]
    values = np.vstack([est.force, est.total])
    std = est.combination_std[rows]
    z_dc = np.abs(values[:, 0] - truth[:, 0]) / std[:, 0]
    z_1 = np.abs(values[:, 1] - truth[:, 1]) / (math.sqrt(2) * std[:, 1])
    assert np.all(z_dc < Z_MAX), dict(zip(names, z_dc.round(2), strict=True))
    assert np.all(z_1 < Z_MAX), dict(zip(names, z_1.round(2), strict=True))
    assert not any("drifts within the record" in note for note in est.notes)


def test_the_error_is_what_the_drawn_gauge_sensitivities_predict(lab_dir, facts, estimate):
    """Less the error that the drawn gauge sensitivities predict, -Psi^-1 (e R), the estimate
    agrees with the truth within the rest of its uncertainty budget."""
    est = estimate
    h = len(est.harmonics) - 1
    with np.load(lab_dir / "truth" / "paper.npz") as npz:
        truth = fit_harmonics(npz["pole_force"], FS, est.f0, h).phasors
        reactions = fit_harmonics(true_reactions(npz), FS, est.f0, h).phasors
    x = np.array([0.25, 0.35])
    psi = np.stack([(0.6 - x) / 0.6, x / 0.6])
    e = np.array([facts["sensitivity"][g] - 1 for g in est.gauge_names])
    predicted = -np.linalg.solve(psi, e[:, None] * reactions)
    assert est.combination_std is not None
    rows = [list(est.combination_names).index(n) for n in est.force_names]
    rest = np.sqrt(est.combination_std[rows] ** 2 - est.budget["gauge sensitivity"][rows] ** 2)
    residual = est.force - truth - predicted
    assert np.all(np.abs(residual[:, 0]) < Z_MAX * rest[:, 0])
    assert np.all(np.abs(residual[:, 1]) < Z_MAX * math.sqrt(2) * rest[:, 1])


def test_the_cli_passes_the_realism_on(tmp_path, monkeypatch):
    """``forcecal simulate OUT --realism lab`` asks for a lab rig (whose files the fixture above
    checks); the default is ideal; another name is refused."""
    import forcecal.simulate.export as export

    calls = []

    def fake(out, preset_name, **kw):
        calls.append(kw["realism"])
        Path(out).mkdir(parents=True, exist_ok=True)
        return Path(out)

    monkeypatch.setattr(export, "write_simulation", fake)
    assert main(["simulate", str(tmp_path / "a"), "--preset", "paper", "--realism", "lab"]) == 0
    assert main(["simulate", str(tmp_path / "b"), "--preset", "paper"]) == 0
    assert calls == ["lab", "ideal"]
    assert main(["simulate", str(tmp_path / "c"), "--realism", "dirty"]) != 0


def test_a_lab_rig_draws_no_false_self_check(estimate):
    """1 % probe gain errors (declared) make the probes miss the shapes by about 1 %: that is
    no load change, so no probe-misfit note (the chi-square counts the declared probe
    sensitivity uncertainty; without it the paper lab run reads 100-440)."""
    assert not any("disagree" in n for n in estimate.notes), estimate.notes
    finite = estimate.coordinates.chi2[np.isfinite(estimate.coordinates.chi2)]
    assert np.all(finite < 10), finite
