"""Virtual rigs scanned under more than one load: the ``two-coil`` and ``tilt`` presets, per-pole
static gaps, and the files ``write_simulation`` writes for them.

Each check compares the simulator with something it does not compute itself: the magnetic
circuit's closed form, the scans' own records, the files read back by the public readers, or the
first scan recomputed here the way it has always been drawn.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from forcecal.io.manifest import read_manifest
from forcecal.io.uff import read_scan_uff
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate import presets
from forcecal.simulate.export import write_simulation
from forcecal.simulate.integrate import integrate
from forcecal.simulate.magnet import MU0, Drive
from forcecal.simulate.presets import get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_scan,
    public_rig,
    record_run,
    record_scan,
    run_truth,
    scan_response,
    simulate_response,
)

UFF_RTOL = 5e-12          # pyuff ASCII values: %20.11e, half a unit in the 12th digit
MAC_DIFFERENT = 0.999     # below this the scans' first-harmonic shapes are different loads
MAC_SAME = 0.9999         # the same load scanned twice, other noise
FORCE_RTOL = 1e-12        # a pole's force vs the closed form at its simulated gap


def shortened(preset: presets.Preset, n_points: int = 21, record: float = 0.2,
              duration: float = 0.1) -> presets.Preset:
    """The preset with short scans (fewer points, shorter records) and short runs."""
    scans = [dataclasses.replace(s, n_points=n_points, record=record) for s in preset.scans]
    runs = tuple(dataclasses.replace(r, duration=duration) for r in preset.runs)
    return dataclasses.replace(preset, scan=scans[0], more_scans=tuple(scans[1:]), runs=runs)


def first_harmonic_shape(scan, f0: float) -> np.ndarray:
    """(n_points,) complex: each point's first harmonic over its reference's."""
    fit = fit_harmonics(np.vstack([scan.response, scan.reference]), scan.fs, f0, 2)
    n = len(scan.points)
    return fit.phasors[:n, 1] / fit.phasors[n:, 1]


def mac(a: np.ndarray, b: np.ndarray) -> float:
    return float(abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


# --------------------------------------------------------------------------------------------
# two-coil: two scans at different loads, each with its own reference coil


@pytest.fixture(scope="module")
def two_coil():
    preset = shortened(get_preset("two-coil"))
    fe = build_model(preset)
    responses = [scan_response(preset, fe, which) for which in range(len(preset.scans))]
    rng = np.random.default_rng(21)
    scans = [measure_scan(preset, fe, r, rng, which) for which, r in enumerate(responses)]
    return preset, fe, responses, scans


def test_two_coil_scans_pull_in_different_ratios(two_coil):
    preset, _, responses, _ = two_coil
    assert len(preset.scans) == 2
    f0 = preset.scan.drives[0].frequency
    ratios = []
    for r in responses:
        fit = fit_harmonics(r.pole_force, preset.fs, f0, 2)
        ratios.append(abs(fit.phasors[0, 1]) / abs(fit.phasors[1, 1]))     # |FA_1| / |FB_1|
    assert ratios[0] > 3.0 and ratios[1] < 1 / 3.0, ratios


def test_two_coil_scans_measure_different_shapes(two_coil):
    preset, _, _, scans = two_coil
    f0 = preset.scan.drives[0].frequency
    shapes = [first_harmonic_shape(s, f0) for s in scans]
    assert mac(*shapes) < MAC_DIFFERENT
    # the same load measured twice (other noise) agrees: the threshold separates loads
    again = measure_scan(preset, two_coil[1], two_coil[2][0], np.random.default_rng(22), 0)
    assert mac(shapes[0], first_harmonic_shape(again, f0)) > MAC_SAME


def test_each_scan_references_its_own_coil(two_coil):
    """Scan 1's reference is coil A's current (DC 0.5 A), scan 2's coil B's (DC 0.5 A), the
    other coil carrying 0.2 A in each."""
    preset, _, responses, scans = two_coil
    for which, (spec, r, scan) in enumerate(zip(preset.scans, responses, scans, strict=True)):
        coil = spec.reference
        assert coil == which
        assert np.mean(scan.reference) == pytest.approx(spec.drives[coil].dc, abs=0.01)
        assert abs(np.mean(r.current[1 - coil]) - np.mean(scan.reference)) > 0.25
    assert scans[1].source == "scan2.uff" and scans[0].source == "scan.uff"


# --------------------------------------------------------------------------------------------
# per-pole static gaps


def test_the_closer_pole_pulls_harder():
    """Two one-pole magnets at equal DC currents, FA at 0.8 mm and FB at 1.2 mm, then swapped:
    each force is the magnetic circuit's at its own deflected gap, about 1/gap^2."""
    preset = get_preset("two-coil")
    fe = build_model(preset)
    drives = tuple(Drive("current", 0.6, 0.0, 20.0) for _ in preset.magnets)
    forces = []
    for gaps in ({"FA": 0.8e-3, "FB": 1.2e-3}, {"FA": 1.2e-3, "FB": 0.8e-3}):
        r = simulate_response(preset, drives, None, 0.05, fe, gaps=gaps)
        np.testing.assert_allclose(r.gap[:, 0] + fe.row(np.array([0.2, 0.42])) @ r.u[:, 0],
                                   [gaps["FA"], gaps["FB"]], rtol=1e-12)
        for k, m in enumerate(preset.magnets):
            closed = MU0 * m.turns**2 * m.pole_area * 0.6**2 / (2 * (r.gap[k] + m.iron_gap) ** 2)
            np.testing.assert_allclose(r.pole_force[k], closed, rtol=FORCE_RTOL)
        forces.append(r.pole_force[:, 0])
    (fa, fb), (fa_swapped, fb_swapped) = forces
    assert fa / fb == pytest.approx((1.2 / 0.8) ** 2, rel=0.15)
    assert fb_swapped / fa_swapped == pytest.approx((1.2 / 0.8) ** 2, rel=0.15)


def test_an_unknown_pole_is_refused():
    preset = get_preset("tilt")
    with pytest.raises(ValueError, match="no pole 'F3'"):
        simulate_response(preset, preset.runs[0].drives, None, 0.01, gaps={"F3": 1e-3})


# --------------------------------------------------------------------------------------------
# tilt: two one-pole magnets on one current, their gaps changed unequally


@pytest.fixture(scope="module")
def tilt():
    preset = shortened(get_preset("tilt"))
    fe = build_model(preset)
    responses = [scan_response(preset, fe, which) for which in range(len(preset.scans))]
    rng = np.random.default_rng(31)
    scans = [measure_scan(preset, fe, r, rng, which) for which, r in enumerate(responses)]
    return preset, fe, responses, scans


def test_tilt_coils_carry_one_current():
    """Two one-pole magnets at the campaign's pole positions, each on its own channels, driven
    alike in every scan and run; the rig file's actuator is coil 1."""
    preset = get_preset("tilt")
    assert [[(p.name, p.x) for p in m.poles] for m in preset.magnets] == [
        [("F1", 0.25)], [("F2", 0.35)]]
    assert [(m.current_channel, m.flux_channel, m.voltage_channel) for m in preset.magnets] == [
        ("i1", "phi1", "v1"), ("i2", "phi2", "v2")]
    for spec in (*preset.scans, *preset.runs):
        first, second = spec.drives
        assert first == second and first.source == "current"
    assert public_rig(preset).actuator.current == "i1"
    assert [s.reference for s in preset.scans] == [0, 0]


def test_tilt_scans_pull_in_different_ratios(tilt):
    """Scan 1 at equal gaps pulls F1 and F2 alike; scan 2 (F1 0.8 mm, F2 1.2 mm) pulls F1
    about (1.2 / 0.8)^2 times harder; their gaps are the scans' static gaps, deflected."""
    preset, _, responses, _ = tilt
    f0 = preset.scan.drives[0].frequency
    ratios = []
    for r in responses:
        fit = fit_harmonics(r.pole_force, preset.fs, f0, 2)
        ratios.append(abs(fit.phasors[0, 1]) / abs(fit.phasors[1, 1]))     # |F1_1| / |F2_1|
        np.testing.assert_allclose(r.current[0], r.current[1], rtol=0, atol=0)
    assert ratios[0] == pytest.approx(1.0, rel=1e-9)
    assert ratios[1] / ratios[0] > 1.5 and ratios[1] == pytest.approx(2.25, rel=0.15), ratios
    gaps = [r.gap[:, 0] for r in responses]
    assert gaps[1][0] < gaps[0][0] < gaps[1][1]                         # scan 2 is tilted


def test_tilt_scans_measure_different_shapes(tilt):
    preset, fe, responses, scans = tilt
    f0 = preset.scan.drives[0].frequency
    shapes = [first_harmonic_shape(s, f0) for s in scans]
    assert mac(*shapes) < MAC_SAME
    again = measure_scan(preset, fe, responses[0], np.random.default_rng(32), 0)
    assert mac(shapes[0], first_harmonic_shape(again, f0)) > MAC_SAME


def test_tilt_gap_swap_swaps_the_force_ratio():
    """F1 at 0.8 mm and F2 at 1.2 mm, then swapped: each pole pulls as the magnetic circuit at
    its own deflected gap, F1 / F2 about (g2 / g1)^2, and the swap inverts the ratio; every
    run's truth keeps its static gaps and no pole comes near closing its gap."""
    preset = get_preset("tilt")
    fe = build_model(preset)
    ratios = {}
    for spec in preset.runs:
        if spec.tare or not spec.name.endswith("dc08_ac02"):
            continue
        r = simulate_response(preset, spec.drives, None, 0.1, fe, gaps=spec.gaps)
        g1, g2 = spec.gaps["F1"], spec.gaps["F2"]
        np.testing.assert_allclose(r.gap[:, 0] + fe.row(np.array([0.25, 0.35])) @ r.u[:, 0],
                                   [g1, g2], rtol=1e-12)
        for k, m in enumerate(preset.magnets):
            closed = (MU0 * m.turns**2 * m.pole_area * r.current[k] ** 2
                      / (2 * (r.gap[k] + m.iron_gap) ** 2))
            np.testing.assert_allclose(r.pole_force[k], closed, rtol=FORCE_RTOL)
        assert np.all(r.gap > 0.8 * np.array([[g1], [g2]]))
        mean = r.pole_force.mean(axis=1)
        ratios[(g1, g2)] = mean[0] / mean[1]
        assert ratios[(g1, g2)] == pytest.approx((g2 / g1) ** 2, rel=0.15)
        np.testing.assert_array_equal(run_truth(preset, fe, r, spec).static_gap, [g1, g2])
    assert ratios[(0.8e-3, 1.2e-3)] == pytest.approx(1 / ratios[(1.2e-3, 0.8e-3)], rel=1e-9)
    assert ratios[(1.0e-3, 1.0e-3)] == pytest.approx(1.0, rel=1e-9)
    assert len(set(np.round(list(ratios.values()), 2))) == 5


# --------------------------------------------------------------------------------------------
# files


_TILT = presets.PRESETS["tilt"]
_TWO_COIL = presets.PRESETS["two-coil"]
_PAPER = presets.PRESETS["paper"]


def small_tilt() -> presets.Preset:
    full = _TILT()
    keep = tuple(r for r in full.runs if r.name.startswith("g0800_1200_dc04") or r.tare)
    return shortened(dataclasses.replace(full, runs=keep), n_points=4, record=0.05,
                     duration=0.05)


def test_export_writes_every_scan_and_per_pole_gaps(tmp_path, monkeypatch):
    monkeypatch.setitem(presets.PRESETS, "tilt", small_tilt)
    out = write_simulation(tmp_path / "sim", "tilt", seed=3)
    preset = small_tilt()
    rng = np.random.default_rng(3)              # the draws in write_simulation's order
    fe = build_model(preset)
    first = record_scan(preset, rng, fe)
    for spec in preset.runs:
        record_run(preset, spec, rng, fe)
    second = record_scan(preset, rng, fe, which=1)
    for name, scan in (("scan.uff", first), ("scan2.uff", second)):
        back = read_scan_uff(out / name)
        np.testing.assert_allclose(back.response, scan.response, rtol=UFF_RTOL, atol=0)
        np.testing.assert_allclose(back.reference, scan.reference, rtol=UFF_RTOL, atol=0)
    assert not (out / "scan3.uff").exists()

    entries = read_manifest(out / "manifest.csv")
    assert [(e.run.name, e.gap, e.gaps, e.tare) for e in entries] == [
        ("g0800_1200_dc04_ac02.csv", None, {"F1": 0.8e-3, "F2": 1.2e-3}, False),
        ("tare.csv", None, {"F1": 1.0e-3, "F2": 1.0e-3}, True),
    ]
    assert entries[0].labels == {"dc": "0.4", "ac": "0.2", "repeat": "1"}
    with np.load(out / "truth" / "g0800_1200_dc04_ac02.npz") as npz:
        np.testing.assert_array_equal(npz["static_gap"], [0.8e-3, 1.2e-3])
    facts = json.loads((out / "truth" / "simulator.json").read_text())
    assert [s["file"] for s in facts["scans"]] == ["scan.uff", "scan2.uff"]
    assert facts["scans"][1]["static_gap_m"] == {"F1": 0.8e-3, "F2": 1.2e-3}
    assert facts["runs"]["tare"]["static_gap_m"] == {"F1": 1.0e-3, "F2": 1.0e-3}
    assert [d["coil"] for d in facts["runs"]["tare"]["drives"]] == ["i1", "i2"]
    header = (out / "runs" / "tare.csv").read_text().splitlines()[0].split(",")
    assert {"i1", "phi1", "v1", "i2", "phi2", "v2"} <= set(header)


def test_two_coil_facts_name_each_scans_reference(tmp_path, monkeypatch):
    def small():
        full = _TWO_COIL()
        return shortened(dataclasses.replace(full, runs=full.runs[:1]), n_points=3,
                         record=0.05, duration=0.05)

    monkeypatch.setitem(presets.PRESETS, "two-coil", small)
    out = write_simulation(tmp_path / "sim", "two-coil", seed=1, binary_uff=True)
    facts = json.loads((out / "truth" / "simulator.json").read_text())
    assert [(s["file"], s["reference"]) for s in facts["scans"]] == [
        ("scan.uff", "ia"), ("scan2.uff", "ib")]
    assert facts["runs"]["matched"]["drives"][1]["coil"] == "ib"
    assert read_scan_uff(out / "scan2.uff").reference.shape == (3, 500)


# --------------------------------------------------------------------------------------------
# the existing presets are unchanged


def test_the_first_scan_is_drawn_as_it_always_was():
    """The paper preset's scan recomputed the way it has always been drawn: the windows' start
    samples, the vibration noise, then the reference noise, the reference being the (only)
    coil's current."""
    preset = shortened(get_preset("paper"), n_points=9, record=0.1)
    fe = build_model(preset)
    scan = record_scan(preset, np.random.default_rng(8), fe)

    spec, fs = preset.scan, preset.fs
    n_rec = int(round(spec.record * fs))
    per_period = int(np.ceil(fs / spec.drives[0].frequency))
    r = integrate(fe, preset.magnets, spec.drives, fs, (n_rec + per_period) / fs)
    rng = np.random.default_rng(8)
    starts = rng.integers(0, per_period, size=spec.n_points)
    idx = starts[:, None] + np.arange(n_rec)[None, :]
    rng.standard_normal((spec.n_points, n_rec))                       # the vibration noise
    reference = r.current[0][idx] + preset.noise.current * rng.standard_normal(idx.shape)
    np.testing.assert_array_equal(scan.reference, reference)
    np.testing.assert_array_equal(scan.points[:, 0], np.linspace(0, preset.beam.length, 9))


def test_more_scans_leave_the_first_scan_and_the_runs_alone(tmp_path, monkeypatch):
    def base():
        return shortened(_PAPER(), n_points=3, record=0.05, duration=0.05)

    def rescanned():
        p = base()
        return dataclasses.replace(p, more_scans=(dataclasses.replace(p.scan, gap=1.2e-3),))

    monkeypatch.setitem(presets.PRESETS, "base", base)
    monkeypatch.setitem(presets.PRESETS, "rescanned", rescanned)
    a = write_simulation(tmp_path / "a", "base", seed=4)
    b = write_simulation(tmp_path / "b", "rescanned", seed=4)
    assert sorted(p.name for p in b.iterdir()) == sorted([*(p.name for p in a.iterdir()),
                                                          "scan2.uff"])
    for name in ("rig.toml", "scan.uff", "manifest.csv", "runs/paper.csv",
                 "truth/paper.forces.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert (b / "scan2.uff").read_bytes() != (b / "scan.uff").read_bytes()
