"""The virtual rig against closed-form truths, its own balance laws and its files.

Every check here compares the simulator with something it does not compute itself: the
Euler-Bernoulli formulas, the magnetic-circuit formula, a second time step, a quadrature of the
inertia term written below, or the files read back by the public readers.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from forcecal.io.manifest import read_manifest
from forcecal.io.run_files import read_run, read_table_csv
from forcecal.io.uff import read_scan_uff
from forcecal.rig import load_rig
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate import presets
from forcecal.simulate.beam import (
    assemble_beam,
    hermite_row,
    natural_frequencies,
    pinned_pinned_frequencies,
    pinned_static_deflection,
)
from forcecal.simulate.export import write_simulation
from forcecal.simulate.integrate import (
    INERTIA_TOLERANCE,
    drive_oversample,
    integrate,
    steady_oversample,
)
from forcecal.simulate.magnet import MU0, Drive, Magnet, Pole
from forcecal.simulate.physics import relaxation_modes
from forcecal.simulate.presets import NoiseSpec, get_preset
from forcecal.simulate.virtual_rig import build_model, public_rig, record_run, record_scan

# Named tolerances.
FREQ_RTOL = 1e-3          # FE eigenfrequencies vs Euler-Bernoulli (60 elements: ~4e-7)
NODAL_RTOL = 1e-10        # Hermite elements are nodally exact under point loads
HALVING_RTOL = 1e-4       # harmonic change from halving dt, relative to the fundamental
BALANCE_RTOL = 1e-6       # rigid-body balance residual relative to the reaction RMS
INERTIA_SHARE = 0.05      # the inertia term must matter (paper's rig: ~10 % of the AC RMS)
QUADRATURE_RTOL = 1e-9    # our quadrature of J vs Psi^T M a (both exact: rounding only)
FORCE_RTOL = 1e-12        # magnetic force vs its closed form at the simulated gap
UFF_RTOL = 5e-12          # pyuff ASCII values: %20.11e, half a unit in the 12th digit
SHORT = 0.25              # s, record length of the dynamic checks


def harmonics(x, t, f0, n_harm=4):
    """Complex amplitudes (n_signals, n_harm) of harmonics 1..n_harm by least squares."""
    fit = fit_harmonics(np.atleast_2d(x), 1.0 / (t[1] - t[0]), f0, n_harm, t0=t[0])
    return fit.phasors[:, 1:]


def psi_matrix(xa: float, xb: float, x: np.ndarray) -> np.ndarray:
    """Relaxation shapes of a beam on gauges at xa, xb, evaluated at x: (2, len(x))."""
    x = np.asarray(x, dtype=float)
    return np.stack([(xb - x) / (xb - xa), (x - xa) / (xb - xa)])


def gauge_reactions(model, preset, u, v) -> np.ndarray:
    """Noise-free force each gauge exerts on the beam: spring plus its internal dashpot."""
    rows = hermite_row(model.nodes, np.array([x for _, x in preset.beam.gauges]))
    k = preset.beam.gauge_stiffness
    return -k * (rows @ u + model.beta * (rows @ v))


def quiet(preset):
    """The preset without measurement noise."""
    return dataclasses.replace(preset, noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def paper():
    preset = get_preset("paper")
    return preset, build_model(preset)


# --------------------------------------------------------------------------------------------
# 1, 2: the beam against Euler-Bernoulli


def euler_bernoulli_pinned(beam, n_modes=3) -> np.ndarray:
    n = np.arange(1, n_modes + 1)
    return (n * np.pi / beam.length) ** 2 * np.sqrt(beam.ei / beam.mass_per_length) / (2 * np.pi)


def test_pinned_pinned_frequencies_match_euler_bernoulli():
    beam = get_preset("paper").beam
    exact = euler_bernoulli_pinned(beam)
    f = pinned_pinned_frequencies(beam.length, beam.ei, beam.mass_per_length, 60)
    np.testing.assert_allclose(f, exact, rtol=FREQ_RTOL)


def test_pinned_pinned_error_falls_with_mesh_refinement():
    beam = get_preset("paper").beam
    exact = euler_bernoulli_pinned(beam)
    errors = np.array([
        np.abs(pinned_pinned_frequencies(beam.length, beam.ei, beam.mass_per_length, n) / exact - 1)
        for n in (6, 12, 24)
    ])
    assert np.all(errors[1:] < errors[:-1])
    # cubic Hermite elements converge as h^4 in frequency: halving h gains a factor near 16
    assert np.all(errors[:-1] / errors[1:] > 10)


@pytest.mark.parametrize("x_load", [0.3, 0.15])
def test_static_deflection_is_nodally_exact(x_load):
    beam = get_preset("paper").beam
    length, ei, load = beam.length, beam.ei, 250.0
    a, b = x_load, length - x_load
    w = pinned_static_deflection(length, ei, load, x_load, x_load, n_elements=60)
    exact = load * a**2 * b**2 / (3 * ei * length)          # = F L^3 / (48 EI) at mid-span
    assert w == pytest.approx(exact, rel=NODAL_RTOL)


def test_static_deflection_mid_span_formula():
    beam = get_preset("paper").beam
    w = pinned_static_deflection(beam.length, beam.ei, 100.0, beam.length / 2, beam.length / 2)
    assert w == pytest.approx(100.0 * beam.length**3 / (48 * beam.ei), rel=NODAL_RTOL)


# --------------------------------------------------------------------------------------------
# 3: time-step convergence


def test_halving_the_time_step_keeps_the_harmonics(paper):
    preset, model = paper
    drives = preset.runs[0].drives
    f0 = drives[0].frequency
    probes = hermite_row(model.nodes, np.array([x for _, x in preset.sensors]))
    amps = []
    for oversample in (1, 2):
        r = integrate(model, preset.magnets, drives, preset.fs, SHORT, oversample=oversample)
        signals = (r.pole_force, gauge_reactions(model, preset, r.u, r.v), probes @ r.u)
        amps.append([harmonics(s, r.t, f0) for s in signals])
    changes = [np.max(np.abs(a - b), axis=1) / np.abs(a[:, 0]) for a, b in zip(*amps, strict=True)]
    worst = max(float(np.max(c)) for c in changes)
    assert worst < HALVING_RTOL
    assert worst > 1e-10, "oversample had no effect: the time step was not halved"


def _inertia_mismatch(preset, model, drives, oversample):
    """Largest relative difference, over the gauges, between the simulated inertia term
    Psi^T M a at the second harmonic and -(2 w0)^2 Psi^T M u: the continuous physics the
    estimator assumes."""
    r = integrate(model, preset.magnets, drives, preset.fs, SHORT, oversample=oversample)
    f0 = drives[0].frequency
    u = fit_harmonics(r.u, preset.fs, f0, 2).phasors[:, 2]
    a = fit_harmonics(r.a, preset.fs, f0, 2).phasors[:, 2]
    psi_m = relaxation_modes(model, preset) @ model.mass
    j_a, j_u = psi_m @ a, -((4 * math.pi * f0) ** 2) * (psi_m @ u)
    return float(np.max(np.abs(j_a - j_u)) / np.max(np.abs(j_a)))


def test_a_steady_drive_is_stepped_finely_enough_for_its_inertia():
    """The trapezoidal rule weighs a sine as if at (2/dt) tan(w dt/2): the body driven at
    150 Hz and sampled at 10 kHz would carry, at 300 Hz, an inertia 0.59 % off the continuous
    physics the estimator assumes (measured 5.9e-3 with one step per sample). The default
    step keeps it within INERTIA_TOLERANCE (measured 6.3e-4 with three)."""
    preset = get_preset("body")
    model = build_model(preset)
    drives = preset.runs[0].drives
    assert steady_oversample(drives[0].frequency, preset.fs) == 3
    assert steady_oversample(20.0, preset.fs) == 1
    assert _inertia_mismatch(preset, model, drives, None) < INERTIA_TOLERANCE
    assert _inertia_mismatch(preset, model, drives, 1) > 4 * INERTIA_TOLERANCE


def test_a_broadband_drive_is_stepped_for_the_top_of_its_band():
    """A sweep to 150 Hz and a chirp to 200 Hz at 10 kHz: stepped as a steady sine at their
    band's top would be, 3 and 4 steps a sample, so that the rig's inertia at twice that
    frequency is within INERTIA_TOLERANCE of its mass's ((w dt)^2 / 6; with one step, 0.26 %
    at 200 Hz and 1.05 % at 400 Hz)."""
    preset = get_preset("sweep")
    sweep = next(r for r in preset.runs if r.name == "sweep").drives
    for drives, steps, top in ((sweep, 3, 150.0), (preset.scan.drives, 4, 200.0)):
        n = drive_oversample(drives, preset.fs)
        assert n == steps
        assert (2 * math.pi * 2 * top / (preset.fs * n)) ** 2 / 6 <= INERTIA_TOLERANCE
    assert drive_oversample(preset.runs[1].drives, preset.fs) == 1       # a steady 10 Hz step


# --------------------------------------------------------------------------------------------
# 4: rigid-body balance in the truth (METHOD.md eq. 6)


@pytest.fixture(scope="module")
def quiet_run(paper):
    preset, model = paper
    p0 = quiet(preset)
    spec = dataclasses.replace(preset.runs[0], duration=SHORT)
    run, truth = record_run(p0, spec, np.random.default_rng(11), model)
    response = integrate(model, preset.magnets, spec.drives, preset.fs, SHORT)
    return p0, model, run, truth, response


def test_truth_balances_reactions_inertia_and_forces(quiet_run):
    preset, model, run, truth, response = quiet_run
    np.testing.assert_array_equal(truth.w, response.u[0::2])          # the same trajectory
    (_, xa), (_, xb) = preset.beam.gauges
    psi = psi_matrix(xa, xb, [p.x for m in preset.magnets for p in m.poles])
    reactions = gauge_reactions(model, preset, response.u, response.v)
    recorded = np.stack([run.channels[name] for name, _ in preset.beam.gauges])
    np.testing.assert_array_equal(recorded, reactions)                 # noise-free channels
    rms = np.sqrt(np.mean(reactions**2, axis=1))
    residual = truth.inertia - reactions - psi @ truth.pole_force
    assert np.max(np.abs(residual) / rms[:, None]) < BALANCE_RTOL


def test_reactions_alone_do_not_balance_the_forces(quiet_run):
    preset, model, _, truth, response = quiet_run
    reactions = gauge_reactions(model, preset, response.u, response.v)
    ac_rms = np.std(reactions, axis=1)
    share = np.sqrt(np.mean(truth.inertia**2, axis=1)) / ac_rms
    assert np.all(share > INERTIA_SHARE)


def test_inertia_equals_an_independent_quadrature(quiet_run):
    preset, model, _, truth, response = quiet_run
    beam = preset.beam
    (_, xa), (_, xb) = beam.gauges
    gx, gw = np.polynomial.legendre.leggauss(4)              # exact for psi (1) * w (3)
    lo, hi = model.nodes[:-1], model.nodes[1:]
    x = ((lo + hi) / 2 + np.outer(gx, hi - lo) / 2).ravel()
    weights = (np.outer(gw, hi - lo) / 2).ravel()
    w_tt = hermite_row(model.nodes, x) @ response.a          # (n_points, n_samples)
    j = (beam.mass_per_length * psi_matrix(xa, xb, x) * weights) @ w_tt
    for xm, mass in beam.masses:
        j += mass * psi_matrix(xa, xb, [xm]) * (hermite_row(model.nodes, xm) @ response.a)
    scale = np.sqrt(np.mean(j**2, axis=1))[:, None]
    assert np.max(np.abs(truth.inertia - j) / scale) < QUADRATURE_RTOL


# --------------------------------------------------------------------------------------------
# 5: the magnet's static force at the deflected gap


def pole_force_closed_form(magnet: Magnet, current: float, gaps: np.ndarray) -> np.ndarray:
    """Per-pole force Phi^2 / (2 mu0 A), Phi = N i mu0 A / (sum of gaps + l_fe / mu_r)."""
    flux = magnet.turns * current * MU0 * magnet.pole_area / (
        np.sum(gaps, axis=0) + magnet.iron_length / magnet.mu_r)
    return flux**2 / (2 * MU0 * magnet.pole_area) * np.ones_like(gaps)


def test_static_force_symmetric_poles(paper):
    preset, model = paper
    magnet, current = preset.magnets[0], 0.8
    r = integrate(model, preset.magnets, (Drive("current", current, 0.0, 20.0),), preset.fs, 0.05)
    s = np.mean(r.gap, axis=0)                               # the deflected mean gap
    assert np.max(np.abs(r.gap[0] - r.gap[1])) < 1e-9 * s[0]   # symmetric up to rounding
    total = r.pole_force.sum(axis=0)
    n, a, offset = magnet.turns, magnet.pole_area, magnet.iron_length / (2 * magnet.mu_r)
    expected = MU0 * n**2 * a * current**2 / (4 * (s + offset) ** 2)
    np.testing.assert_allclose(total, expected, rtol=FORCE_RTOL)
    np.testing.assert_allclose(2 * magnet.static_force(current, float(s[0])), total[0],
                               rtol=FORCE_RTOL)
    # the beam really moved: at the static gap the formula would be far off
    at_static = MU0 * n**2 * a * current**2 / (4 * (magnet.poles[0].gap + offset) ** 2)
    assert abs(at_static / total[0] - 1) > 0.01
    assert np.std(total) < 1e-12 * np.mean(total)            # a DC steady state


def test_static_force_asymmetric_poles(paper):
    preset, model = paper
    magnet = dataclasses.replace(preset.magnets[0],
                                 poles=(Pole("F1", 0.18, 1.1e-3), Pole("F2", 0.33, 0.9e-3)))
    current = 0.7
    r = integrate(model, (magnet,), (Drive("current", current, 0.0, 20.0),), preset.fs, 0.05)
    assert abs(r.gap[0, 0] - r.gap[1, 0]) > 1e-5                # the gaps differ
    expected = pole_force_closed_form(magnet, current, r.gap)
    np.testing.assert_allclose(r.pole_force, expected, rtol=FORCE_RTOL)


def test_magnet_static_force_closed_form():
    magnet = Magnet(poles=(Pole("F1", 0.25, 1e-3), Pole("F2", 0.35, 1e-3)))
    for current, gap in ((0.5, 1e-3), (1.2, 0.7e-3)):
        per_pole = pole_force_closed_form(magnet, current, np.array([gap, gap]))[0]
        assert magnet.static_force(current, gap) == pytest.approx(per_pole, rel=1e-14)
        flux = magnet.flux_from_current(current, np.array([gap, gap]))
        assert magnet.pole_force(flux) == pytest.approx(per_pole, rel=1e-14)
        ideal = magnet.ideal_k * current**2 / (gap + magnet.gap_offset) ** 2
        assert 2 * magnet.static_force(current, gap) == pytest.approx(ideal, rel=1e-14)


def test_dc_voltage_drive_settles_to_v_over_r(paper):
    preset, model = paper
    magnet = preset.magnets[0]
    r = integrate(model, preset.magnets, (Drive("voltage", 1.5, 0.0, 20.0),), preset.fs, 0.05)
    np.testing.assert_allclose(r.current, 1.5 / magnet.resistance, rtol=1e-9)
    np.testing.assert_allclose(r.voltage, 1.5, rtol=1e-14)


# --------------------------------------------------------------------------------------------
# 7: damping and rigid motion


def test_damping_exerts_no_net_force_on_rigid_motion(paper):
    preset, model = paper
    rng = np.random.default_rng(7)
    kb = model.bending_stiffness
    springs = model.stiffness - kb
    np.testing.assert_allclose(model.damping, model.beta * model.stiffness, rtol=0, atol=0)
    for a, b in rng.normal(size=(3, 2)) * (1e-3, 1e-2):
        rigid = model.rigid_mode(a, b)
        x = rng.uniform(0, preset.beam.length, 25)
        np.testing.assert_allclose(model.row(x) @ rigid, a + b * x, rtol=1e-13, atol=1e-18)
        scale = np.max(np.abs(kb)) * np.max(np.abs(rigid))
        assert np.max(np.abs(kb @ rigid)) < 1e-12 * scale
        beam_damping = model.damping - model.beta * springs
        assert np.max(np.abs(beam_damping @ rigid)) < 1e-12 * model.beta * scale
    # on the rigid-body equations the damping acts only through the gauges' own dashpots,
    # whose force the gauges measure: psi_r^T C v = beta k v(g_r)
    (_, xa), (_, xb) = preset.beam.gauges
    span = xb - xa
    psi = np.stack([model.rigid_mode(xb / span, -1 / span), model.rigid_mode(-xa / span, 1 / span)])
    v = rng.standard_normal(model.n_dof)
    rows = model.row(np.array([xa, xb]))
    expected = model.beta * preset.beam.gauge_stiffness * (rows @ v)
    np.testing.assert_allclose(psi @ model.damping @ v, expected,
                               rtol=1e-9, atol=1e-12 * np.max(np.abs(model.damping)))


def test_free_beam_has_two_rigid_modes():
    beam = get_preset("paper").beam
    free = assemble_beam(beam.length, beam.ei, beam.mass_per_length, 30)
    f = natural_frequencies(free, 3)
    assert np.all(f[:2] < 1e-4 * f[2])


# --------------------------------------------------------------------------------------------
# 6, 8: files written by write_simulation


@pytest.fixture(scope="module")
def paper_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper") / "sim"
    write_simulation(out, "paper", seed=5)
    return out


def test_files_read_back_identical(paper_files):
    out = paper_files
    preset = get_preset("paper")
    rng = np.random.default_rng(5)             # the same draws, in write_simulation's order
    model = build_model(preset)
    scan = record_scan(preset, rng, model)
    runs = [record_run(preset, spec, rng, model) for spec in preset.runs]

    rig = load_rig(out / "rig.toml")
    assert rig.source == str(out / "rig.toml")
    assert dataclasses.replace(rig, source="<rig>") == public_rig(preset)

    back = read_scan_uff(out / "scan.uff")
    np.testing.assert_array_equal(back.points, scan.points)
    assert back.fs == scan.fs and back.quantity == scan.quantity == "velocity"
    np.testing.assert_allclose(back.response, scan.response, rtol=UFF_RTOL, atol=0)
    np.testing.assert_allclose(back.reference, scan.reference, rtol=UFF_RTOL, atol=0)

    for spec, (run, truth) in zip(preset.runs, runs, strict=True):
        got = read_run(out / "runs" / f"{spec.name}.csv")
        assert list(got.channels) == list(run.channels)
        for name, values in run.channels.items():
            np.testing.assert_array_equal(got.channels[name], values)   # shortest repr: exact
        assert got.fs == pytest.approx(preset.fs, rel=1e-12) and got.t0 == 0.0
        t, cols = read_table_csv(out / "truth" / f"{spec.name}.forces.csv")
        np.testing.assert_array_equal(t, truth.t)
        assert list(cols) == [*truth.pole_names, "total"]
        for k, name in enumerate(truth.pole_names):
            np.testing.assert_array_equal(cols[name], truth.pole_force[k])
        np.testing.assert_array_equal(cols["total"], truth.pole_force.sum(axis=0))
        with np.load(out / "truth" / f"{spec.name}.npz") as npz:
            np.testing.assert_array_equal(npz["inertia"], truth.inertia)
            np.testing.assert_array_equal(npz["gap"], truth.gap)

    entries = read_manifest(out / "manifest.csv")
    assert [e.run for e in entries] == [(out / "runs" / f"{s.name}.csv").resolve()
                                        for s in preset.runs]
    assert all(e.gap is None and not e.tare for e in entries)
    facts = json.loads((out / "truth" / "simulator.json").read_text())
    assert facts["preset"] == "paper"
    np.testing.assert_allclose(facts["natural_frequencies_Hz"], natural_frequencies(model, 4))


_CAMPAIGN = presets.PRESETS["campaign"]


def small_campaign() -> presets.Preset:
    """The campaign preset cut to two gaps, a tare and a short scan (for the manifest)."""
    full = _CAMPAIGN()
    keep = [r for r in full.runs if r.name.startswith("g0800_dc04_ac01")
            or r.name.startswith("g1200_dc08_ac02") or r.tare]
    runs = tuple(dataclasses.replace(r, duration=0.05) for r in keep)
    scan = dataclasses.replace(full.scan, n_points=4, record=0.05)
    return dataclasses.replace(full, runs=runs, scan=scan)


def test_manifest_rows_carry_gap_and_tare(tmp_path, monkeypatch):
    monkeypatch.setitem(presets.PRESETS, "campaign", small_campaign)
    out = write_simulation(tmp_path / "sim", "campaign", seed=2)
    entries = read_manifest(out / "manifest.csv")
    assert [(e.run.name, e.gap, e.tare) for e in entries] == [
        ("g0800_dc04_ac01.csv", 0.8e-3, False),
        ("g1200_dc08_ac02.csv", 1.2e-3, False),
        ("tare.csv", 1.0e-3, True),
    ]
    assert entries[0].labels == {"dc": "0.4", "ac": "0.1", "repeat": "1"}
    tare = read_run(out / "runs" / "tare.csv")
    assert np.std(tare.channels["i"]) < 3 * presets.NoiseSpec().current  # noise only
    _, cols = read_table_csv(out / "truth" / "tare.forces.csv")
    assert np.max(np.abs(cols["total"])) == 0.0


def _same_files(a: Path, b: Path) -> None:
    names = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for name in names:
        if name.suffix == ".npz":                         # zip members carry a time stamp
            with np.load(a / name) as x, np.load(b / name) as y:
                assert sorted(x.files) == sorted(y.files)
                for key in x.files:
                    np.testing.assert_array_equal(x[key], y[key])
        else:
            assert (a / name).read_bytes() == (b / name).read_bytes(), str(name)


def test_same_seed_same_files(paper_files, tmp_path):
    again = write_simulation(tmp_path / "again", "paper", seed=5)
    _same_files(paper_files, again)


def test_other_seed_other_noise_same_truth(paper_files):
    preset = get_preset("paper")
    rng = np.random.default_rng(6)
    model = build_model(preset)
    scan = record_scan(preset, rng, model)
    run, truth = record_run(preset, preset.runs[0], rng, model)
    written = read_run(paper_files / "runs" / "paper.csv")
    for name, values in written.channels.items():
        assert np.std(values - run.channels[name]) > 0, name    # new noise on every channel
    # ... and nothing but noise: the spread of two independent draws of the gauge noise
    assert np.std(written.channels["R1"] - run.channels["R1"]) == pytest.approx(
        math.sqrt(2) * preset.noise.gauge, rel=0.05)
    _, forces = read_table_csv(paper_files / "truth" / "paper.forces.csv")
    for k, name in enumerate(truth.pole_names):                 # the truth ignores the seed
        np.testing.assert_array_equal(forces[name], truth.pole_force[k])
    old_scan = read_scan_uff(paper_files / "scan.uff")
    assert np.max(np.abs(old_scan.response - scan.response)) > 10 * preset.noise.ldv


def test_two_independent_magnets_act_with_different_forces(paper):
    """A second magnet with its own coil: two different forces, one rigid-body balance."""
    preset, model = paper
    left = Magnet(poles=(Pole("FA", 0.2, 1.0e-3),), current_channel="ia",
                  flux_channel="phia", voltage_channel="va")
    right = Magnet(poles=(Pole("FB", 0.42, 1.2e-3),), current_channel="ib",
                   flux_channel="phib", voltage_channel="vb")
    f0 = preset.runs[0].drives[0].frequency
    # one gap per circuit: four times the force of a U-core pole at the same current
    drives = (Drive("current", 0.3, 0.1, f0), Drive("voltage", 0.8, 0.5, f0, phase=2.5))
    r = integrate(model, (left, right), drives, preset.fs, SHORT)
    fa, fb = r.pole_force
    # different forces, not one scaled copy of the other
    assert np.corrcoef(fa - fa.mean(), fb - fb.mean())[0, 1] < 0.95
    # each coil follows its own drive
    np.testing.assert_allclose(r.current[0], drives[0].value(r.t), rtol=1e-12)
    np.testing.assert_allclose(r.voltage[1], drives[1].value(r.t), rtol=1e-12)
    # the rigid-body balance with both forces
    (_, xa), (_, xb) = preset.beam.gauges
    psi = psi_matrix(xa, xb, [0.2, 0.42])
    reactions = gauge_reactions(model, preset, r.u, r.v)
    span = xb - xa
    modes = np.stack([model.rigid_mode(xb / span, -1 / span), model.rigid_mode(-xa / span,
                                                                               1 / span)])
    j = modes @ (model.mass @ r.a)
    residual = j - reactions - psi @ r.pole_force
    rms = np.sqrt(np.mean(reactions**2, axis=1))
    assert np.max(np.abs(residual) / rms[:, None]) < BALANCE_RTOL
