"""The broadband model (:mod:`forcecal.model.broadband`): the span of a broadband scan's
shapes, its operating shapes over frequency and their stated uncertainty, the steady model it
gives a steady run, and the scan points it sets aside.

The scan is synthesised from the virtual rig's finite-element beam (its own modes, the paper's
pole pattern, its gauge springs): exact periodic responses to a band-limited random force, with
white noise on every channel. The beam, the scan and its model are session fixtures
(``tests/conftest.py``); the helpers that synthesise runs are in ``tests/fe_beam.py``.
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from fe_beam import FS, noisy_chirp, record_run

from forcecal.errors import InputError
from forcecal.model.broadband import (
    BroadbandModel,
    build_broadband_model,
    load_any_model,
    steady_model,
)


def test_broadband_span_shapes_and_couplings(beam, bb_model):
    """One pattern, one dominant shape (mode 1) and the weaker ones the quasi-static part of
    the modes above the band brings in, which one shape alone does not fit (reduced
    chi-square above 2) and the span does."""
    _preset, model, phi, _rig, _ = beam
    assert isinstance(bb_model, BroadbandModel)
    assert 2 <= bb_model.n_shapes <= 6
    assert bb_model.chi2[bb_model.n_shapes - 1] < 2.0 < bb_model.chi2[0]
    x = np.linspace(0.0, 0.6, 61)
    fe = model.row(x) @ phi[:, np.argmin(np.abs(model.modes[0] - model.modes[0][
        model.modes[0] > 0][0]))]
    span = bb_model.values(x)[:, 0]
    mac = np.abs(fe @ span) ** 2 / (fe @ fe * (span @ span))
    assert mac > 0.995
    back = BroadbandModel.from_json(bb_model.to_json())
    np.testing.assert_allclose(back.values(x), bb_model.values(x), rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(back.couplings, bb_model.couplings)


def test_steady_model_from_broadband(beam, bb_model):
    """Each harmonic of a steady run gets the operating shape of its own frequency: the ratio
    of its mass coupling to its value at a probe is the FE beam's own at that frequency
    (achieved within 0.057 % at 36-180 Hz with the smoothed ratios, 0.40 % with each line's
    own; test 0.17 %, where one shape for all is up to 7.2 % off)."""
    from forcecal.simulate.physics import _inertia

    preset, model, phi, rig, modal = beam
    sm = steady_model(bb_model, rig, 36.0, 6)
    assert list(sm.harmonics) == [1, 2, 3, 4, 5]
    assert 6 in sm.dropped
    probe = model.row(np.array([0.1]))
    errors, one_shape = [], []
    for k, n in enumerate(sm.harmonics):
        ods = phi @ modal(np.array([36.0 * n]), np.ones(1))[0]
        want = _inertia(model, preset, ods[:, None])[:, 0] / (probe @ ods)[0]
        got = sm.couplings[k] / sm.shapes[k].evaluate(np.array([0.1]))[0]
        first = bb_model.couplings[:, 0] / bb_model.values(np.array([0.1]))[0, 0]
        errors.append(np.max(np.abs(got / want - 1)))
        one_shape.append(np.max(np.abs(first / want - 1)))
    assert max(errors) < 1.7e-3, max(errors)
    assert max(one_shape) > 3e-2
    with pytest.raises(InputError, match="lies above the band"):
        steady_model(bb_model, rig, 250.0, 3)


def test_operating_shapes_are_smooth_over_frequency(beam, bb_model):
    """The operating shape from a probe to the poles against the FE beam's, at the midpoints
    of the scan's lines over the band: within 1 % with the smoothed ratios (achieved 0.48 %,
    at 198 Hz); each line's own ratio errs 3.0 % at 6-46 Hz, where the
    scan's velocity lines are weakest."""
    _preset, model, phi, _rig, modal = beam
    probe, poles = np.array([0.1]), np.array([0.25, 0.35])
    f = np.arange(6.0, 199.0, 4.0)
    ods = phi @ modal(f, np.ones(f.size)).T                          # (n_dof, n_f)
    want = (model.row(poles) @ ods) / (model.row(probe) @ ods)
    errors = {}
    for name, m in (("smooth", bb_model), ("lines", dataclasses.replace(bb_model, ratios=None))):
        shape = m.values(np.concatenate([probe, poles])) @ m.mixing(f)
        errors[name] = np.max(np.abs(shape[1:] / shape[:1] / want - 1), axis=0)
    assert np.max(errors["smooth"]) < 0.01, np.max(errors["smooth"])
    assert np.max(errors["lines"][f < 50.0]) > 0.01
    back = BroadbandModel.from_json(bb_model.to_json())
    np.testing.assert_allclose(back.mixing(f), bb_model.mixing(f), rtol=1e-12)


def test_the_dc_deflection_takes_the_scans_quasi_static_shape(beam, bb_model):
    """A steady run's DC deflection is fitted to the probes with one quasi-static shape: from a
    broadband model, the operating shape of the band's lowest line. Its ratio of pole to probe
    against the FE beam's static deflection: within 1 % (achieved 0.46 %) at 10, 36 and 100 Hz;
    the fundamental's own shape, which stands in for it after a steady scan, errs 3.7 % at
    100 Hz, above the first mode."""
    from forcecal.actuator.gaps import quasi_static_shape

    _preset, model, phi, rig, modal = beam
    probe, poles = np.array([0.1]), np.array([0.25, 0.35])
    static = phi @ modal(np.zeros(1), np.ones(1))[0]
    want = (model.row(poles) @ static) / (model.row(probe) @ static)

    def error(m):
        shape = quasi_static_shape(m, rig)
        return np.max(np.abs(shape(poles) / shape(probe) / want - 1))

    for f0 in (10.0, 36.0, 100.0):
        assert error(steady_model(bb_model, rig, f0, 2)) < 0.01
    fundamental = dataclasses.replace(steady_model(bb_model, rig, 100.0, 2), static_shape=None)
    assert error(fundamental) > 0.02


def test_a_scans_quasi_static_shape_is_not_moved_by_the_fundamentals_errors(beam, bb_model):
    """The campaign's scan-shape errors move a run's DC deflection through the fundamental's
    shape when that shape stands in for the quasi-static one; a broadband model's own
    quasi-static shape is not the fundamental's, so the fundamental's own errors do not move
    the DC: the quasi-static shape's error does, as errors of their own."""
    from forcecal.campaign.noise import run_noise
    from forcecal.forces.steady import reconstruct

    wave = np.sin(2 * np.pi * 36.0 * np.arange(int(2.0 * FS)) / FS)
    run, _ = record_run(beam, np.random.default_rng(3), 6.0 + 1.5 * wave, 0.6 + 0.1 * wave,
                     "steady")                                     # 6 N + 1.5 N at 36 Hz a pole
    rig = dataclasses.replace(beam[3], frequency=36.0, drive="steady")
    own = steady_model(bb_model, rig, 36.0, 4)
    moved, static = {}, {}
    for label, sm in (("own", own), ("fundamental's", dataclasses.replace(own, static_shape=None))):
        est = reconstruct(rig, sm, run)
        shapes = [e for e in run_noise(rig, sm, run, est, None).shared if e.source == "scan shapes"]
        harmonic = [e for e in shapes if e.name.startswith("shape n=")]
        assert harmonic
        moved[label] = max(float(np.max(np.abs(e.motion[:, 0]))) for e in harmonic)
        static[label] = [float(np.max(np.abs(e.motion[:, 0]))) for e in shapes
                         if e.name.startswith("quasi-static shape")]
    assert moved["own"] == 0.0 and moved["fundamental's"] > 0.0, moved
    assert static["fundamental's"] == [] and static["own"] and min(static["own"]) > 0, static


def test_the_ratios_stated_uncertainty_covers_their_error(beam, bb_model):
    """The operating shape's ratios a_k / a_1 against the FE beam's own (its operating shape
    projected on the span), over the scan's lines: error over stated standard uncertainty,
    Re and Im of every ratio, RMS 0.75-1.3 (achieved 1.00, 97 % within 2; with each line's
    covariance from its points' noise alone 2.0: near the mode a line is strong
    enough for the span's own misfit to exceed its noise, and it takes its Birge ratio)."""
    _preset, model, phi, _rig, modal = beam
    f = np.arange(8.0, 197.0, 4.0)
    x = np.linspace(0.0, 0.6, 121)
    ods = model.row(x) @ phi @ modal(f, np.ones(f.size)).T            # (n_x, n_f)
    coords = np.linalg.lstsq(bb_model.values(x), ods, rcond=None)[0]
    err = (bb_model.mixing(f) - coords / coords[:1])[1:]
    std = bb_model.mixing_std(f)[1:]
    z = np.concatenate([err.real / std, err.imag / std])
    rms = float(np.sqrt(np.mean(z**2)))
    assert 0.75 < rms < 1.3, rms


def test_rough_patterns_stay_in_the_span_but_do_not_choose_its_order(beam):
    """Over 41 points of the beam: a strong smooth pattern (its noise 1 a point), a rough one
    of norm 100 (noise the points' statement misses, far above the singular values' edge), a
    weak smooth one of norm 30 and a pattern of noise alone. The smooth ones are told from
    the rough and the noise (F 1.2e8 and 154 against 0.32 and 2.4; the 1e-3 quantiles
    4.3-12.6), whatever their place among the columns."""
    from forcecal.model.broadband import _smooth_patterns

    rig = beam[3]
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 0.6, 41)
    points = rig.structure.coordinates(x, source="test")
    strong = 1e4 * np.sin(np.pi * x / 0.6) ** 2 + rng.standard_normal(41)
    rough = 100.0 * rng.standard_normal(41) / np.sqrt(41)
    weak = 30.0 * np.cos(2 * np.pi * x / 0.6) / np.sqrt(41 / 2) + rng.standard_normal(41)
    alone = rng.standard_normal(41)
    weights = np.ones(41)
    patterns = np.column_stack([strong, rough, weak, alone])
    assert _smooth_patterns(rig.structure, points, patterns, weights, "gcv") == [0, 2]
    assert _smooth_patterns(rig.structure, points, patterns[:, [0, 2, 1]], weights,
                            "gcv") == [0, 1]


def test_a_dead_scan_point_is_set_aside_and_noted(beam, chirp):
    """A point whose channel died (its response zero over the whole record, or its FRF zero
    and its coherence 0) is set aside with a note naming it, in the time records' path and
    the FRFs' alike: the first shape's mass coupling over its value at a probe stays within
    1e-3 of the whole scan's (achieved 6e-5 and 1e-4; its zeros read as a motion known
    exactly had made the ratios' spline fail). A point without response on part of the band
    only (a dropout: no noise is stated for its zeros), or more than a fifth of the points
    dead, is refused."""
    from forcecal.simulate.sldv_frf import frf_export

    rig = beam[3]
    scan = noisy_chirp(chirp, 50e-6, 7)
    probe = np.array([0.1])

    def lead(m):
        return m.couplings[:, 0] / m.values(probe)[0, 0]

    frfs, averages = frf_export(scan, rig.band, 400.0)
    frf_rig = dataclasses.replace(rig, scan_averages=averages)
    response = scan.response.copy()
    response[10] = 0.0
    values, coherence = frfs.values.copy(), frfs.coherence.copy()
    values[10], coherence[10] = 0.0, 0.0
    for whole, dead, on in (
            (scan, dataclasses.replace(scan, response=response), rig),
            (frfs, dataclasses.replace(frfs, values=values, coherence=coherence), frf_rig)):
        want, got = build_broadband_model(on, whole), build_broadband_model(on, dead)
        assert got.n_points == 40
        assert any("record 11 at (0.15) m set aside: no response on any line" in note
                   for note in got.notes), got.notes
        np.testing.assert_allclose(lead(got), lead(want), rtol=1e-3)
    values[5, 3:40] = 0.0                                 # a dropout over part of the band
    with pytest.raises(InputError, match=r"record 6 at \(0.075\) m holds no response on 37 "
                                         r"of the band's 49 lines but holds one on the others"):
        build_broadband_model(frf_rig, dataclasses.replace(frfs, values=values))
    response[:9] = 0.0
    with pytest.raises(InputError, match="10 of its 41 points hold no response"):
        build_broadband_model(rig, dataclasses.replace(scan, response=response))


def test_a_line_whose_noise_reads_zero_does_not_take_the_ratios():
    """:func:`forcecal.model.ratios.smooth_ratios` with one line's covariance zero, one line's
    1e200 and every line's 1e-300 times its size: the smoothed ratio stays within 1e-2 of the
    lines (achieved 1.0e-3, their noise's size; a zero-variance line had taken the spline to
    1e132), with finite uncertainties."""
    from forcecal.model.ratios import smooth_ratios

    rng = np.random.default_rng(43)
    f = np.arange(8.0, 201.0, 4.0)
    coords = np.vstack([np.full(f.size, 1.0 + 0.1j),
                        0.01 * np.sin(f / 30.0) + 1e-4 * rng.standard_normal(f.size) + 0j])
    for change in ("zero", "huge", "tiny"):
        cov = np.zeros((f.size, 2, 2))
        cov[:, 0, 0] = cov[:, 1, 1] = 1e-8
        cov[3] = 0.0 if change == "zero" else cov[3]
        cov[5, 1, 1] = 1e200 if change == "huge" else cov[5, 1, 1]
        cov = cov * (1e-300 if change == "tiny" else 1.0)
        ratios, std = smooth_ratios(f, coords, cov)
        assert np.all(np.isfinite(ratios)) and np.all(np.isfinite(std)), change
        assert np.max(np.abs(ratios[1] - coords[1] / coords[0])) < 1e-2, change


def _rename(table: dict, old: str, new: str) -> None:
    table[new] = table.pop(old)


def _twice(table: dict, key: str) -> None:
    """``key`` of ``table`` written twice (the same value) once the document is dumped."""
    table[f"{TWICE}{key}"] = table[key]


TWICE = "__written_twice__"


@pytest.mark.parametrize(("change", "said"), [
    (lambda d: d.update(comment="by hand"),
     r"key 'comment' is not a broadband model key"),
    (lambda d: d["coordinates"].update(scale=1.0),
     r"key 'coordinates\.scale' is not a complex array key"),
    (lambda d: d["shapes"][1].update(weight=1.0), r"key 'shapes\[1\]\.weight' is not a shape key"),
    (lambda d: _rename(d, "coordinates", "coordinate"),
     r"key 'coordinate' is not a broadband model key; did you mean 'coordinates'\?"),
    (lambda d: _rename(d, "kind", "Kind"),
     r"key 'Kind' is not a broadband model key; did you mean 'kind'\?"),
    (lambda d: _rename(d["shapes"][0], "residual_std", "residual_sd"),
     r"key 'shapes\[0\]\.residual_sd' is not a shape key; did you mean 'residual_std'\?"),
    (lambda d: _twice(d, "n_points"), r"key 'n_points' is written twice"),
    (lambda d: _twice(d["coordinates"], "im"), r"key 'coordinates\.im' is written twice"),
], ids=["unknown", "unknown-in-table", "unknown-in-entry", "misspelt", "misspelt-kind",
        "misspelt-in-entry", "twice", "twice-in-table"])
def test_a_broadband_model_file_refuses_every_key_it_does_not_declare(bb_model, tmp_path,
                                                                     change, said):
    """An unknown key (at the top level, in a table, in an entry of an array), a misspelt one
    (a required key, ``kind`` itself, a shape's key) and one written twice (``json.loads``
    would keep one value without a word): each refused in one line naming the file and the
    dotted key, a misspelt one with the key meant (issue 33)."""
    doc = bb_model.to_json()
    change(doc)
    path = tmp_path / "model.json"
    path.write_text(re.sub(rf'"{TWICE}(\w+)"', r'"\1"', json.dumps(doc)))
    with pytest.raises(InputError, match=rf"^model '{re.escape(str(path))}': {said}") as err:
        load_any_model(path)
    assert "\n" not in str(err.value)


def test_the_ratios_come_from_the_lines_that_carry_the_drive():
    """A chirp of period 0.25 s in 0.5 s records: every other line (2 Hz apart) holds no drive.
    One such line carrying a spurious first coordinate as strong as a drive line's, with a
    ratio of 4 and a covariance as small as theirs, took the splines over every line there
    (the lab scans whose estimate erred by tens of %); the ratios come from the drive's lines
    alone and are interpolated onto the others (achieved: within 1e-12 of the true 0.01-0.012
    at every line between the drive's first and last; over every line, 0.2 or more off at the
    spurious one)."""
    from forcecal.model.ratios import choose_ratios, drive_line_ratios

    f = np.arange(10.0, 200.1, 2.0)
    good = (np.round(f) % 4) == 0
    rng = np.random.default_rng(3)
    c0 = np.where(good, 1.0 / (1.0 + 1j * f / 70.0), 1e-4 * rng.standard_normal(f.size))
    true = 0.01 * (1.0 + 1e-3 * f)
    coords = np.vstack([c0, true * c0, 0.005 * c0]).astype(complex)
    spurious = int(np.flatnonzero(~good & (f > 140))[0])
    coords[:, spurious] = [0.5, 2.0, 0.1]
    cov = np.einsum("l,kj->lkj", 1e-8 * np.maximum(np.abs(coords[0]), 1e-2) ** 2, np.eye(3))
    ratios, std, _, _ = drive_line_ratios(f, coords, cov, good)
    inside = (f >= f[good][0]) & (f <= f[good][-1])      # beyond, the end's ratio is held
    off = np.abs(ratios[1] - true)[inside]
    assert np.max(off) < 1e-6, np.max(off)
    assert np.all(np.isfinite(std)) and std.shape == ratios.shape
    every, _, _, _ = choose_ratios(f, coords, cov)
    assert abs(every[1, spurious] - true[spurious]) > 0.2


def test_the_ratios_error_shared_between_lines_is_split_off_not_added(beam, bb_model, tmp_path):
    """The splines' noise through the smoother is shared by neighbouring lines: the model keeps
    it as error directions over the lines (the first shape none), each ratio's variance at a
    line at least their sum. A steady run's model carries them as errors of every run, one
    change of every harmonic's and the quasi-static shape's coefficients each; the shapes'
    own covariances keep the rest, so that the two add up to the ratios' whole stated
    variance at every harmonic (to 1e-9 of it) and at the lowest line. The ratio of the first
    pair errs alike at 20 and 40 Hz (correlation of its error 0.65 there, test above 0.5).
    The directions survive the model file; one of the wrong length, or holding more than its
    ratio's whole variance at a line, is refused naming it."""
    rig = dataclasses.replace(beam[3], frequency=20.0, drive="steady")
    dirs = bb_model.ratio_directions
    assert dirs is not None and len(dirs[0]) == 0 and all(len(d) for d in dirs[1:])
    for k, d in enumerate(dirs):
        assert np.all(np.sum(d**2, axis=0) <= bb_model.ratio_std[k] ** 2 * (1 + 1e-9))
    sm = steady_model(bb_model, rig, 20.0, 4)
    first = bb_model.shapes[0]
    real = np.column_stack([s.coefficients for s in bb_model.shapes]).real
    at = np.concatenate([sm.harmonics * 20.0, bb_model.frequencies[:1]])
    whole = [first.coefficient_covariance + (real * bb_model.mixing_std(at)[:, j] ** 2) @ real.T
             for j in range(len(at))]
    own = [s.coefficient_covariance for s in sm.shapes] + [sm.static_shape.coefficient_covariance]
    for j in range(len(at)):
        shared = sum(np.outer(c.real, c.real) for name, changes, dc in sm.shared_errors
                     if name.endswith(" re")
                     for c in [changes[j] if j < len(sm.shapes) else dc])
        np.testing.assert_allclose(own[j] + shared, whole[j], rtol=1e-9,
                                   atol=1e-9 * np.abs(whole[j]).max())
    (_, d1), *_ = bb_model.mixing_directions(np.array([20.0, 40.0]))
    corr = float(d1[:, 0] @ d1[:, 1] / np.sqrt((d1[:, 0] @ d1[:, 0]) * (d1[:, 1] @ d1[:, 1])))
    assert corr > 0.5, corr
    back = BroadbandModel.from_json(json.loads(json.dumps(bb_model.to_json())))
    for a, b in zip(back.ratio_directions, dirs, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    doc = bb_model.to_json()
    doc["ratio_directions"][1][0] = doc["ratio_directions"][1][0][:-1]
    path = tmp_path / "model.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"key 'ratio_directions\[1\]\[0\]' has \d+ values"):
        load_any_model(path)
    doc = bb_model.to_json()                  # a shared part beyond the whole variance
    doc["ratio_directions"][1][0] = [10 * x for x in doc["ratio_directions"][1][0]]
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"key 'ratio_directions\[1\]' holds a variance .* "
                                         r"beyond its ratio's whole"):
        load_any_model(path)


def test_a_lab_scans_model_reads_back_with_its_shared_ratio_errors(tmp_path):
    """The modal ratios' variance and the factor of their errors are computed apart (and lines
    between the drive's interpolated), so a ratio's shared errors could exceed its whole
    variance by a few parts in 1e4, which the model file's reader refuses: the lab rig's
    random preset at seed 2 wrote a model its own ``reconstruct`` refused (line 47 of shape
    1). Every ratio's standard uncertainty now holds its shared errors, and the model reads
    back."""
    from forcecal.cli.main import main
    from forcecal.model.broadband import load_any_model
    from forcecal.simulate.export import write_simulation

    write_simulation(tmp_path, "random", seed=2, realism="lab")
    assert main(["scan", "-q", str(tmp_path / "rig.toml"), str(tmp_path / "scan.uff"), "-o",
                 str(tmp_path / "model.json")]) == 0
    model = load_any_model(tmp_path / "model.json")
    assert model.ratio_directions is not None and model.ratio_std is not None
    for std, dirs in zip(model.ratio_std, model.ratio_directions, strict=True):
        if len(dirs):
            assert np.all(np.sum(np.square(dirs), axis=0) <= std**2 * (1 + 1e-9))
