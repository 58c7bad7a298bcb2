"""Several scans under different loads: a span of shapes per harmonic (forcecal.model.spatial),
the members each run needs (forcecal.forces.coordinates.choose_members), against the virtual
rig's truth.

The `two-coil` preset: the paper beam pulled by two magnets on their own coils, scanned with
coil A dominant and again with coil B dominant; its runs change coil B since the scans.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from forcecal.actuator.laws import get_law
from forcecal.actuator.prediction import Calibration
from forcecal.campaign.statistics import ParameterUncertainty
from forcecal.errors import InputError
from forcecal.forces.coordinates import choose_members, coordinate_map, member_fit, sensor_weights
from forcecal.forces.steady import channels_si, reconstruct
from forcecal.forces.uncertainty import combinations, inertia_variance, shape_operators
from forcecal.model.inertia import inertia_term
from forcecal.model.relaxation import force_matrix
from forcecal.model.spatial import SpatialModel, build_spatial_model, load_model
from forcecal.realtime.estimator import StreamEstimator
from forcecal.rig import TypeB
from forcecal.signals.harmonics import fit_harmonics
from forcecal.simulate.presets import get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    measure_scan,
    public_rig,
    run_truth,
    scan_response,
    simulate_response,
)


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


# ------------------------------------------------------------------------ choosing members

def _sensors(rng: np.random.Generator, n_s: int = 3) -> tuple[np.ndarray, np.ndarray]:
    phi = rng.standard_normal((n_s, 2)) + 1j * rng.standard_normal((n_s, 2))
    return phi, np.full((n_s, 2), 1e-9)


def test_one_member_when_the_load_matches():
    rng = np.random.default_rng(1)
    phi, std = _sensors(rng)
    noise = 1e-3
    s = phi[:, 0] * (2 - 1j) + noise * (rng.standard_normal(3) + 1j * rng.standard_normal(3))
    fit = choose_members(phi, std, s, np.full(3, noise**-2))
    assert fit.members == (0,)
    np.testing.assert_allclose(fit.q, [2 - 1j], atol=10 * noise)


def test_both_members_when_the_load_is_a_mix():
    rng = np.random.default_rng(2)
    phi, std = _sensors(rng)
    noise = 1e-3
    s = phi @ np.array([1.0, 0.5j]) + noise * rng.standard_normal(3)
    fit = choose_members(phi, std, s, np.full(3, noise**-2))
    assert fit.members == (0, 1)
    np.testing.assert_allclose(fit.q, [1.0, 0.5j], atol=10 * noise)
    # a single member misfits by far more than the two-parameter penalty
    alone = member_fit(phi, std, s, np.full(3, noise**-2), (0,))
    assert alone is not None and alone.chi2 > 100 * 4


def test_the_second_member_alone_when_the_load_is_the_second_scans():
    rng = np.random.default_rng(3)
    phi, std = _sensors(rng)
    noise = 1e-3
    s = phi[:, 1] * 3.0 + noise * rng.standard_normal(3)
    assert choose_members(phi, std, s, np.full(3, noise**-2)).members == (1,)


def test_never_more_coordinates_than_sensors():
    """METHOD.md eq. 16: Nq <= NS, whatever the span holds."""
    rng = np.random.default_rng(4)
    phi = rng.standard_normal((2, 3)) + 0j
    s = phi @ np.array([1.0, 1.0, 1.0])
    fit = choose_members(phi, np.zeros((2, 3)), s, np.ones(2))
    assert len(fit.members) <= 2


def test_members_the_sensors_cannot_tell_apart_are_not_combined():
    phi = np.array([[1.0, 2.0], [0.5, 1.0]], dtype=complex)       # proportional at the sensors
    s = np.array([1.0, 0.7], dtype=complex)
    fit = choose_members(phi, np.zeros((2, 2)), s, np.ones(2))
    assert len(fit.members) == 1


# ------------------------------------------------------------------------ the virtual rig

@pytest.fixture(scope="module")
def two_coil():
    """Two scans, and the runs `b_changed` (coil B doubled and shifted 1.5 rad since the scans)
    and `matched` (the first scan's load), with their truth; one noise seed."""
    p = get_preset("two-coil")
    fe = build_model(p)
    rig = public_rig(p)
    rng = np.random.default_rng(100)
    scans = [measure_scan(p, fe, scan_response(p, fe, which=i), rng, which=i)
             for i in range(len(p.scans))]
    runs = {}
    for name in ("b_changed", "matched"):
        spec = next(r for r in p.runs if r.name == name)
        r = simulate_response(p, spec.drives, spec.gap, spec.duration, fe)
        runs[name] = (measure_run(p, spec, fe, r, rng), run_truth(p, fe, r))
    one = build_spatial_model(rig, scans[0])
    two = build_spatial_model(rig, scans)
    return rig, scans, one, two, runs


def force_errors(est, truth) -> np.ndarray:
    """Each force's waveform error, % of its own true AC RMS."""
    out = []
    for k, tf in enumerate(truth.pole_force):
        e = est.series[k] - tf
        out.append(100 * rms(e - e.mean()) / rms(tf - tf.mean()))
    return np.array(out)


def test_two_scans_give_two_shapes_per_harmonic(two_coil):
    _, scans, one, two, _ = two_coil
    assert two.scans == tuple(s.source for s in scans) and len(two.scans) == 2
    assert all(len(two.members(k)) == 2 for k in range(len(two.harmonics)))
    assert all(len(one.members(k)) == 1 for k in range(len(one.harmonics)))
    assert two.member_couplings(0).shape == (2, 2)
    np.testing.assert_array_equal(two.member_couplings(0)[:, 0], two.couplings[0])


# seed 100: two scans FA 0.030 %, FB 0.022 % (tolerance 0.09 %); one scan 0.93 %, 0.68 %
def test_a_changed_coil_is_right_with_two_scans(two_coil):
    rig, _, one, two, runs = two_coil
    run, truth = runs["b_changed"]
    est_one, est_two = reconstruct(rig, one, run), reconstruct(rig, two, run)
    err_one, err_two = force_errors(est_one, truth), force_errors(est_two, truth)
    assert np.all(err_two < 0.09), err_two
    assert np.all(err_one > 0.4), err_one                   # what the second scan repairs
    assert est_two.coordinates.members[0] == (0, 1)
    assert any("disagree with the scan model's shape" in n for n in est_one.notes)
    assert not any("disagree" in n for n in est_two.notes), est_two.notes


# seed 100: FA 0.022 %, FB 0.159 % with either model (tolerance 0.06 %, 0.45 %)
def test_the_matched_load_uses_one_shape_and_is_unchanged(two_coil):
    rig, _, one, two, runs = two_coil
    run, truth = runs["matched"]
    est_one, est_two = reconstruct(rig, one, run), reconstruct(rig, two, run)
    assert all(m == (0,) for m in est_two.coordinates.members)
    np.testing.assert_allclose(est_two.force, est_one.force, rtol=1e-9, atol=1e-12)
    assert np.all(force_errors(est_two, truth) < [0.06, 0.45])


def test_the_span_stated_std_covers_the_error(two_coil):
    """The fundamental's error of each force with two members, in units of its stated std, is
    of order one (seed 100: 0.4, 0.6)."""
    rig, _, _, two, runs = two_coil
    run, truth = runs["b_changed"]
    est = reconstruct(rig, two, run)
    true = fit_harmonics(truth.pole_force, run.fs, est.f0, len(est.harmonics) - 1).phasors
    z = np.abs(est.force[:, 1] - true[:, 1]) / est.force_std[:, 1]
    assert np.all(z < 4), z


# 400 draws: Monte Carlo / stated 0.97-1.03 per force and part (tolerance 0.12)
def test_span_propagation_matches_monte_carlo(two_coil):
    """GUM Supplement 1 on the two-member fundamental: the probes' phasors and both members'
    shape coefficients drawn from their covariances, each draw through the estimate's own
    formulas (coordinate map over the span, inertia term, force solve)."""
    rig, _, _, two, runs = two_coil
    run, _ = runs["b_changed"]
    est = reconstruct(rig, two, run)
    members, _, _ = est.coordinates.span(0)
    assert members == (0, 1)
    sig = channels_si(rig, run)
    sensors = fit_harmonics(np.stack([sig[s] for s in rig.sensor_names]), run.fs, est.f0, 6)
    ops = shape_operators(two, rig)
    names, combo = combinations(rig)
    a_r = combo @ np.linalg.pinv(force_matrix(rig))
    w = 2 * np.pi * est.f0
    var = inertia_variance(two, ops, 0, sensors, a_r, w, est.coordinates)
    rng = np.random.default_rng(5)
    weights = sensor_weights(sensors.phasor_std[:, 1])
    draws = []
    for _ in range(400):
        phi, m = [], []
        for j in members:
            fit = two.members(0)[j]
            nf = len(fit.coefficients)
            dp = (rng.multivariate_normal(np.zeros(nf), fit.coefficient_covariance)
                  + 1j * rng.multivariate_normal(np.zeros(nf), fit.coefficient_covariance))
            p = fit.coefficients + dp
            phi.append(ops.at_sensors[0][j] @ p)
            m.append(ops.couplings[0][j] @ p)
        s = sensors.phasors[:, 1] + sensors.phasor_std[:, 1] * (
            rng.standard_normal(2) + 1j * rng.standard_normal(2))
        gain, _ = coordinate_map(np.column_stack(phi), weights)
        draws.append(a_r @ inertia_term(np.column_stack(m), gain @ s, w))
    draws = np.array(draws)
    ratio = np.column_stack([draws.real.std(axis=0), draws.imag.std(axis=0)]) / np.sqrt(var)
    assert np.all(np.abs(ratio - 1) < 0.12), dict(zip(names, ratio.round(3).tolist(),
                                                      strict=True))


def test_json_round_trip_keeps_the_span(two_coil, tmp_path):
    rig, _, _, two, runs = two_coil
    path = two.save(tmp_path / "model.json")
    back = load_model(path)
    assert back.scans == two.scans and back.member_scans == two.member_scans
    for k in range(len(two.harmonics)):
        np.testing.assert_array_equal(back.member_couplings(k), two.member_couplings(k))
    run = runs["b_changed"][0]
    np.testing.assert_allclose(reconstruct(rig, back, run).force,
                               reconstruct(rig, two, run).force, rtol=1e-12, atol=1e-12)


def test_a_damaged_span_entry_is_refused_by_key(two_coil, tmp_path):
    _, _, _, two, _ = two_coil
    doc = two.to_json()
    doc["span"][1]["harmonic"] = 5
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"span\[1\]\.harmonic"):
        load_model(path)
    doc = two.to_json()
    doc["span"][0]["couplings_re"] = doc["span"][0]["couplings_re"][:1]
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"span\[0\]\.couplings_re"):
        load_model(path)


@pytest.fixture(scope="module")
def saved_files(two_coil, tmp_path_factory):
    """The two-scan model saved, and a calibration with a campaign's uncertainty block, each
    written once: the documents the tests below damage."""
    folder = tmp_path_factory.mktemp("saved")
    law = get_law("k_i2_sfe2")
    cov = np.diag([1e-14, 1e-12])
    cal = Calibration(law=law.name, params=np.array([2e-5, 2e-4]), covariance=cov, n_poles=2,
                      current_range=(0.0, 2.0), gap_range=(5e-4, 1.5e-3))
    unc = ParameterUncertainty(param_names=law.param_names, statistical=cov / 2, type_b=cov / 2,
                               budget={"gauges": np.sqrt(np.diag(cov / 2))}, residual=cov,
                               run_scatter=None, n_runs=3, type_b_used=TypeB())
    calibration = folder / "calibration.json"
    calibration.write_text(json.dumps({**cal.to_json(), "uncertainty": unc.to_json(2)}))
    return {"model": two_coil[3].save(folder / "model.json"), "calibration": calibration}


@pytest.mark.parametrize(("kind", "table", "old", "new", "key", "near"), [
    ("model", (), "notes", "note", "note", "notes"),
    ("model", ("shapes", 0), "order", "ordr", "shapes[0].ordr", "order"),
    ("model", ("span", 1, "shapes", 0), "basis", "bases", "span[1].shapes[0].bases", "basis"),
    ("calibration", ("uncertainty",), "coverage_factor", "coverage_facter",
     "uncertainty.coverage_facter", "coverage_factor"),
    ("calibration", ("uncertainty", "budget", "gauges"), "K", "Kx",
     "uncertainty.budget.gauges.Kx", "K"),
    ("calibration", ("params",), "K", "k", "params.k", "K"),
    ("calibration", ("uncertainty", "stderr"), "s_fe", "sfe", "uncertainty.stderr.sfe", "s_fe"),
])
def test_an_unknown_key_is_refused_naming_it_and_the_nearest_key(saved_files, tmp_path, kind,
                                                                 table, old, new, key, near):
    doc = json.loads(saved_files[kind].read_text())
    load = load_model if kind == "model" else Calibration.load
    load(saved_files[kind])                                      # the file as written reads
    where = doc
    for part in table:
        where = where[part]
    where[new] = where.pop(old)
    path = tmp_path / f"{kind}.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as refused:
        load(path)
    assert str(refused.value).startswith(f"{kind} '{path}': key '{key}' is not "), refused.value
    assert str(refused.value).endswith(f"; did you mean '{near}'?"), refused.value


def test_a_scan_repeated_at_the_same_load_adds_nothing(two_coil):
    rig, scans, _, _, _ = two_coil
    p = get_preset("two-coil")
    fe = build_model(p)
    again = measure_scan(p, fe, scan_response(p, fe), np.random.default_rng(7))
    model = build_spatial_model(rig, [scans[0], again])
    assert all(len(model.members(k)) == 1 for k in range(len(model.harmonics)))
    assert any("adds nothing" in n for n in model.notes)


def test_scans_at_different_frequencies_are_refused(two_coil):
    import dataclasses

    rig, scans, _, _, _ = two_coil
    other = build_spatial_model(rig, scans[1])
    shifted = dataclasses.replace(other, f0=other.f0 * 1.05)
    from forcecal.model.spatial import merge_models

    with pytest.raises(InputError, match="share the drive frequency"):
        merge_models(rig, [build_spatial_model(rig, scans[0]), shifted])


def test_the_stream_chooses_the_members_too(two_coil):
    """The streaming readout starts on the first shape and switches to both once the window
    shows the probes need them; its forces at the end agree with the batch estimate (seed 100:
    fundamental within 0.05 % of the batch's)."""
    rig, _, _, two, runs = two_coil
    run, _ = runs["b_changed"]
    est = StreamEstimator(rig, two, two.f0, run.fs, t0=run.t0)
    assert est.members[1] == (0,)
    raw = np.stack([run.channel(name) for name in est.channel_names])
    for start in range(0, raw.shape[1], 512):
        est.process(raw[:, start:start + 512])
    assert est.members[1] == (0, 1)
    batch = reconstruct(rig, two, run)
    last = est.force_phasors(est.phasors)
    rel = np.abs(last[:, 1] - batch.force[:, 1]) / np.abs(batch.force[:, 1])
    assert np.all(rel < 3e-3), rel


def test_one_scan_models_have_no_span_in_json(two_coil):
    _, _, one, _, _ = two_coil
    doc = one.to_json()
    assert "span" not in doc and "scans" not in doc
    assert isinstance(SpatialModel.from_json(doc), SpatialModel)


def test_the_commands_take_several_scans(tmp_path, capsys):
    """`forcecal scan RIG SCAN1 SCAN2 -o MODEL.json`, then `reconstruct` with that model:
    the notes name the scans whose shapes a changed load combines."""
    from forcecal.cli.main import main

    lab = tmp_path / "lab"
    assert main(["simulate", str(lab), "--preset", "two-coil", "--seed", "3"]) == 0
    model = tmp_path / "model.json"
    assert main(["scan", str(lab / "rig.toml"), str(lab / "scan.uff"), str(lab / "scan2.uff"),
                 "-o", str(model)]) == 0
    out = capsys.readouterr().out
    assert "2 scans: shapes per harmonic 1: 2" in out
    doc = json.loads(model.read_text())
    assert doc["scans"] == [str(lab / "scan.uff"), str(lab / "scan2.uff")]
    assert main(["reconstruct", str(lab / "rig.toml"), str(model),
                 str(lab / "runs" / "b_changed.csv"), "-o", str(tmp_path / "out")]) == 0
    result = json.loads((tmp_path / "out" / "b_changed.json").read_text())
    first = result["generalized_coordinates"][0]
    assert first["shapes"] == [0, 1] and len(first["span"]) == 2
    assert any("combines the shapes of scans" in n for n in result["notes"])
    assert not any("disagree" in n for n in result["notes"])


def test_the_report_takes_a_multi_scan_model(two_coil, tmp_path):
    """`report` with a MODEL.json built from two scans: the model section says so and counts
    each harmonic's shapes; fig. 3 draws the other scan's shape beside the first's."""
    from forcecal.model.scan import harmonic_shapes
    from forcecal.report.figures import fig_shapes
    from forcecal.report.pipeline import run_report

    rig, scans, _, two, runs = two_coil
    path = run_report(rig, two, [runs["b_changed"][0]], tmp_path)
    html = path.read_text()
    assert "Built from 2 scans" in html and "combines the shapes of scans" in html
    assert "Provenance" in html and "SHA-256" in html
    fig = fig_shapes(harmonic_shapes(scans[0], rig.drive_frequency, 6), two)
    labels = [t.get_text() for ax in fig.axes if ax.get_legend()
              for t in ax.get_legend().get_texts()]
    assert any("(scaled)" in t for t in labels), labels
