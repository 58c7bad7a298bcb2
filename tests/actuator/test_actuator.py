"""Tests of the actuator calibration: laws, fits, selection, prediction and the calibration file.

The synthetic campaigns are built from closed-form laws: three static gaps (or one), several
current levels with a ripple, and a sinusoidal gap variation at each of two poles (different
amplitude and phase per pole), as the structure's vibration would give.
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcecal.actuator import (
    ALL_LAWS,
    FLUX,
    K_I0_SFE2,
    K_I2_S2,
    K_I2_SFE2,
    LAWS,
    MU0,
    POWER,
    Calibration,
    CalibrationData,
    ExtrapolationWarning,
    fit_law,
    ideal_k,
    predict,
    predict_flux,
    report_text,
    select_law,
)
from forcecal.actuator.laws import SATURATING
from forcecal.actuator.selection import held_out_error
from forcecal.errors import FitError, InputError

TURNS = 400
POLE_AREA = 4.0e-4  # [m^2]
K_TRUE = ideal_k(TURNS, POLE_AREA)  # [N m^2/A^2]
TRUTH = {
    "k_i2_s2": (K_TRUE,),
    "k_i2_sfe2": (K_TRUE, 0.2e-3),
    "k_i0_sfe2": (K_TRUE, 0.05, 0.2e-3),
    "power": (4.0 * K_TRUE, 1.9, 1.8, 0.1e-3),
    "k_i2_sfe2_sat": (K_TRUE, 0.2e-3, 1500.0, 4.0),
    "flux": (4.2e-4,),
}
GAPS3 = (0.8e-3, 1.0e-3, 1.3e-3)  # [m]
NOISE = 0.002  # relative standard deviation of the force noise

EXACT_RTOL = 1e-8  # noise-free recovery
COVERAGE = 3.0  # noisy recovery: within this many standard uncertainties
MC_RTOL = 0.10  # delta method against Monte Carlo


def campaign(
    law,
    params,
    rng=None,
    noise=0.0,
    static_gaps=GAPS3,
    currents=(0.5, 1.0, 1.5, 2.0),
    runs_per_gap=2,
    n_samples=10,
):
    """A synthetic two-pole campaign following ``law`` with ``params``.

    Each (static gap, run) is one group; within a run every current level is held for
    ``n_samples`` samples of one vibration period, with a 10 % current ripple.
    """
    amp = np.array([0.05e-3, 0.08e-3])  # [m] vibration amplitude at each pole
    phase = np.array([0.0, 1.1])  # [rad]
    cur, gaps, group, static = [], [], [], []
    run = 0
    for g in static_gaps:
        for r in range(runs_per_gap):
            for c in currents:
                t = np.arange(n_samples) / n_samples
                cur.append(c * (1.0 + 0.1 * np.cos(2 * np.pi * t + 0.3 * r)))
                gaps.append(g - amp * np.sin(2 * np.pi * t[:, None] + phase + 0.5 * r))
                group.append(np.full(n_samples, run))
                static.append(np.full(n_samples, g))
            run += 1
    i = np.concatenate(cur)
    s = np.concatenate(gaps)
    phi = MU0 * TURNS * POLE_AREA * i / (2.0 * s.mean(axis=1))  # [Wb]
    force = law.per_pole(np.array(params), i, s, phi).sum(axis=1)
    if noise:
        force = force * (1.0 + noise * rng.standard_normal(force.size))
    return CalibrationData(
        current=i,
        gaps=s,
        force=force,
        static_gap=np.concatenate(static),
        flux=phi if law.needs_flux else None,
        group=np.concatenate(group),
    )


LAW_IDS = [law.name for law in ALL_LAWS]


def test_ideal_k_closed_form():
    assert ideal_k(TURNS, POLE_AREA) == pytest.approx(4e-7 * np.pi * 400**2 * 4e-4 / 4, rel=1e-15)
    with pytest.raises(InputError, match="turns"):
        ideal_k(0, POLE_AREA)


@pytest.mark.parametrize("law", ALL_LAWS, ids=LAW_IDS)
def test_analytic_jacobian_matches_finite_differences(law):
    rng = np.random.default_rng(11)
    i = rng.uniform(0.3, 2.0, 7)
    s = rng.uniform(0.7e-3, 1.4e-3, (7, 2))
    phi = rng.uniform(1e-4, 3e-4, 7)
    p = np.array(TRUTH[law.name])
    jac = law.jacobian(p, i, s, phi)
    for j in range(law.n_params):
        h = 1e-6 * max(abs(p[j]), 1e-4)
        dp = np.zeros_like(p)
        dp[j] = h
        fd = (law.per_pole(p + dp, i, s, phi) - law.per_pole(p - dp, i, s, phi)) / (2 * h)
        np.testing.assert_allclose(jac[..., j], fd, rtol=1e-6, err_msg=law.param_names[j])


@pytest.mark.parametrize("law", ALL_LAWS, ids=LAW_IDS)
def test_law_recovers_its_parameters_from_noise_free_data(law):
    data = campaign(law, TRUTH[law.name])
    fit = fit_law(law, data)
    np.testing.assert_allclose(fit.params, TRUTH[law.name], rtol=EXACT_RTOL)
    assert fit.rms_residual < 1e-10
    assert fit.n_poles == 2


@pytest.mark.parametrize("law", ALL_LAWS, ids=LAW_IDS)
def test_noisy_parameters_lie_within_their_uncertainty(law):
    rng = np.random.default_rng(2024)
    data = campaign(law, TRUTH[law.name], rng, NOISE)
    fit = fit_law(law, data)
    z = (fit.params - TRUTH[law.name]) / fit.stderr
    assert np.all(np.abs(z) < COVERAGE), dict(zip(law.param_names, z, strict=True))
    assert fit.rms_residual == pytest.approx(NOISE, rel=0.2)
    assert np.all(np.abs(fit.correlation) <= 1.0 + 1e-12)
    np.testing.assert_allclose(np.diag(fit.correlation), 1.0)


def _z_scores(law, seeds):
    z = []
    for seed in seeds:
        data = campaign(law, TRUTH[law.name], np.random.default_rng(seed), NOISE)
        fit = fit_law(law, data)
        z.append((fit.params - TRUTH[law.name]) / fit.stderr)
    return np.array(z)


@pytest.mark.parametrize("law", [K_I2_S2, K_I2_SFE2, K_I0_SFE2], ids=lambda law: law.name)
def test_uncertainties_are_calibrated_quick(law):
    z = _z_scores(law, range(30))
    assert np.all((z.std(axis=0) > 0.6) & (z.std(axis=0) < 1.5)), z.std(axis=0)


@pytest.mark.slow
@pytest.mark.parametrize("law", ALL_LAWS, ids=LAW_IDS)
def test_uncertainties_are_calibrated_200_seeds(law):
    z = _z_scores(law, range(200))
    assert np.all((z.std(axis=0) > 0.8) & (z.std(axis=0) < 1.25)), z.std(axis=0)
    assert np.all(np.abs(z.mean(axis=0)) < 0.25), z.mean(axis=0)


@pytest.mark.parametrize(
    ("truth", "params", "expected"),
    [
        (K_I2_S2, TRUTH["k_i2_s2"], "k_i2_s2"),
        (K_I2_SFE2, TRUTH["k_i2_sfe2"], "k_i2_sfe2"),
        (K_I0_SFE2, TRUTH["k_i0_sfe2"], "k_i0_sfe2"),
        # an offset of 2 mA on 0.5-2 A raises the held-out error of k_i2_sfe2 by about 60 %,
        # well beyond the 10 % margin: the simpler law must not be preferred
        (K_I0_SFE2, (K_TRUE, 0.002, 0.2e-3), "k_i0_sfe2"),
        # the iron saturating: the flux density bends over near 1500 A/m of i / (s + s_fe)
        (SATURATING, TRUTH["k_i2_sfe2_sat"], "k_i2_sfe2_sat"),
    ],
    ids=["ideal", "iron-path", "current-offset", "small-current-offset", "saturating"],
)
def test_selection_picks_the_true_law(truth, params, expected):
    data = campaign(truth, params, np.random.default_rng(7), NOISE)
    selection = select_law(data)
    assert selection.chosen == expected, selection.reason
    names = [c.name for c in selection.candidates]
    skipped = dict(selection.skipped)
    # the empirical power law may not converge on a saturating magnet's data
    assert names == [law for law in ("k_i2_s2", "k_i2_sfe2", "k_i0_sfe2", "power",
                                     "k_i2_sfe2_sat") if law not in skipped]
    assert set(skipped) - {"power", "k_i2_sfe2_sat"} == {"flux"}   # unsaturated: no knee
    assert "flux" in skipped["flux"]
    best = selection.best
    assert best.held_out.scheme == "leave-one-group-out"
    assert best.held_out.rms == pytest.approx(NOISE, rel=0.25)


def test_selection_prefers_the_simplest_law_over_a_marginally_better_one():
    data = campaign(K_I2_S2, TRUTH["k_i2_s2"], np.random.default_rng(2), NOISE)
    selection = select_law(data)
    best = min(selection.candidates, key=lambda c: c.held_out.rms)
    assert best.name != "k_i2_s2"  # this seed makes a richer law marginally better
    assert selection.chosen == "k_i2_s2"
    assert selection.best.held_out.rms <= best.held_out.rms + selection.tolerance


def test_held_out_error_refits_without_each_group():
    data = campaign(K_I2_SFE2, TRUTH["k_i2_sfe2"], np.random.default_rng(3), NOISE)
    held = held_out_error(K_I2_SFE2, data)
    np.testing.assert_array_equal(held.labels, np.arange(6))
    assert float(held) == pytest.approx(np.sqrt(np.mean(held.per_group**2)), rel=1e-14)
    out = data.group == 4
    fit = fit_law(K_I2_SFE2, data.subset(~out))
    pred = fit.total(data.subset(out))
    rel = (pred - data.force[out]) / np.maximum(np.abs(data.force[out]), data.force_floor)
    assert held.per_group[4] == pytest.approx(np.sqrt(np.mean(rel**2)), rel=1e-10)


def test_single_static_gap_is_refused_for_laws_with_s_fe():
    data = campaign(
        K_I2_S2, TRUTH["k_i2_s2"], np.random.default_rng(5), NOISE, static_gaps=(1.0e-3,)
    )
    with pytest.raises(FitError, match=r"at least 2 distinct static gaps.*has 1 \(1\.000 mm\)"):
        fit_law(K_I2_SFE2, data)
    selection = select_law(data)
    assert selection.chosen == "k_i2_s2"
    skipped = dict(selection.skipped)
    assert set(skipped) == {"k_i2_sfe2", "k_i0_sfe2", "power", "k_i2_sfe2_sat", "flux"}
    for name in ("k_i2_sfe2", "k_i0_sfe2", "power", "k_i2_sfe2_sat"):
        assert "static gaps" in skipped[name] and "1.000 mm" in skipped[name]
    assert selection.best.held_out.scheme == "k-fold"
    text = report_text(selection)
    assert "k_i2_sfe2: skipped" in text and "static gaps" in text


def test_flux_law_needs_flux():
    data = campaign(K_I2_S2, TRUTH["k_i2_s2"])
    with pytest.raises(FitError, match="flux"):
        fit_law(FLUX, data)


def test_report_lists_every_candidate_and_the_ideal_k():
    data = campaign(K_I2_SFE2, TRUTH["k_i2_sfe2"], np.random.default_rng(8), NOISE)
    text = report_text(select_law(data), k_ideal=K_TRUE)
    lines = text.splitlines()
    chosen = [line for line in lines if line.endswith("<- chosen")]
    assert len(chosen) == 1 and chosen[0].startswith("k_i2_sfe2")
    for name in ("k_i2_s2", "k_i0_sfe2", "power"):
        assert any(line.startswith(name) for line in lines)
    assert "ideal K" in text and "flux: skipped" in text


@pytest.fixture(scope="module")
def calibration():
    data = campaign(K_I0_SFE2, TRUTH["k_i0_sfe2"], np.random.default_rng(9), NOISE)
    return select_law(data).calibration()


def test_delta_method_matches_monte_carlo(calibration):
    assert calibration.law == "k_i0_sfe2"
    current = np.array([0.5, 1.2, 2.0])
    gaps = np.array([[0.8e-3, 0.9e-3], [1.0e-3, 1.05e-3], [1.3e-3, 1.2e-3]])
    pred = predict(calibration, current, gaps)
    rng = np.random.default_rng(10)
    draws = rng.multivariate_normal(calibration.params, calibration.covariance, 20000)
    law = LAWS[calibration.law]
    totals = np.array([law.per_pole(p, current, gaps).sum(axis=1) for p in draws])
    np.testing.assert_allclose(pred.std, totals.std(axis=0), rtol=MC_RTOL)
    np.testing.assert_allclose(pred.total, pred.per_pole.sum(axis=1), rtol=1e-15)
    assert pred.per_pole.shape == (3, 2)


def test_scalar_gap_means_every_pole_at_that_gap(calibration):
    a = predict(calibration, [0.8, 1.6], 1.0e-3)
    b = predict(calibration, [0.8, 1.6], np.full((2, 2), 1.0e-3))
    np.testing.assert_array_equal(a.total, b.total)
    np.testing.assert_array_equal(a.per_pole[:, 0], a.per_pole[:, 1])


def test_prediction_outside_the_calibrated_range_warns(calibration):
    with pytest.warns(ExtrapolationWarning, match="current"):
        predict(calibration, 5.0, 1.0e-3)
    with pytest.warns(ExtrapolationWarning, match="gap"):
        predict(calibration, 1.0, 3.0e-3)


def test_flux_calibration_predicts_from_flux():
    data = campaign(FLUX, TRUTH["flux"], np.random.default_rng(12), NOISE)
    cal = Calibration.from_fit(fit_law(FLUX, data))
    phi = np.quantile(data.flux, [0.2, 0.8])
    pred = predict_flux(cal, phi)
    np.testing.assert_allclose(pred.total, 2 * phi**2 / (MU0 * TRUTH["flux"][0]), rtol=3e-3)
    np.testing.assert_allclose(pred.std / pred.total, cal.stderr[0] / cal.params[0], rtol=1e-12)
    with pytest.raises(InputError, match="predict_flux"):
        predict(cal, 1.0, 1.0e-3)


def _assert_same(a: Calibration, b: Calibration) -> None:
    assert a.law == b.law and a.n_poles == b.n_poles
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_array_equal(a.covariance, b.covariance)
    assert a.current_range == b.current_range and a.gap_range == b.gap_range
    assert a.flux_range == b.flux_range and a.candidates == b.candidates
    assert a.to_json() == b.to_json()


def test_calibration_json_round_trip_is_exact(calibration, tmp_path):
    text = json.dumps(calibration.to_json())
    _assert_same(calibration, Calibration.from_json(json.loads(text)))
    path = calibration.save(tmp_path / "cal" / "calibration.json")
    _assert_same(calibration, Calibration.load(path))
    rows = {row["law"]: row for row in calibration.to_json()["candidates"]}
    assert rows["flux"]["skipped"].startswith("law 'flux' needs the flux")
    assert set(rows["k_i0_sfe2"]["params"]) == {"K", "i0", "s_fe"}


def test_load_names_the_file_at_fault(calibration, tmp_path):
    missing = tmp_path / "nothing.json"
    with pytest.raises(InputError, match=re.escape(str(missing)) + ".*not found"):
        Calibration.load(missing)
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text('{"law": "k_i2_s2", ', encoding="utf-8")
    with pytest.raises(InputError, match=re.escape(str(corrupt)) + ".*not valid JSON"):
        Calibration.load(corrupt)
    lacking = tmp_path / "lacking.json"
    obj = calibration.to_json()
    del obj["covariance"]
    lacking.write_text(json.dumps(obj), encoding="utf-8")
    with pytest.raises(InputError, match=re.escape(str(lacking)) + ".*key 'covariance' is missing"):
        Calibration.load(lacking)


@settings(max_examples=15, deadline=None, database=None)
@given(factor=st.floats(min_value=1e-3, max_value=1e3))
def test_scaling_the_forces_scales_only_k(factor):
    data = campaign(K_I2_SFE2, TRUTH["k_i2_sfe2"], np.random.default_rng(13), NOISE)
    scaled = CalibrationData(
        current=data.current,
        gaps=data.gaps,
        force=factor * data.force,
        static_gap=data.static_gap,
        group=data.group,
    )
    a = fit_law(K_I2_SFE2, data)
    b = fit_law(K_I2_SFE2, scaled)
    np.testing.assert_allclose(b.params, a.params * [factor, 1.0], rtol=1e-7)
    np.testing.assert_allclose(b.stderr, a.stderr * [factor, 1.0], rtol=1e-5)


def test_power_law_contains_the_ideal_law():
    data = campaign(K_I2_S2, TRUTH["k_i2_s2"])
    fit = fit_law(POWER, data)
    np.testing.assert_allclose(fit.params, [K_TRUE, 2.0, 2.0, 0.0], rtol=1e-7, atol=1e-12)


def test_a_saturating_magnet_takes_the_saturating_law():
    """The forces of the virtual rig's saturating magnet (its own B-H curve, solved in the
    magnetic circuit: not the law's formula), 0.4-1.5 A at 0.8-1.2 mm, 0.2 % noise: the
    saturating law is chosen, its held-out error within 2.5x of the noise (achieved 1.8x: the
    law's soft limit is not the magnet's B-H curve), ``k_i2_sfe2``'s beyond 10x (achieved 21x:
    up to 22 % of the pull is lost); its predictions at points between the campaign's within
    0.8 % of the magnet's (achieved 0.39 %)."""
    from forcecal.simulate.presets import get_preset

    magnet = get_preset("saturation").magnets[0]
    law = K_I2_SFE2
    data = campaign(law, TRUTH[law.name], static_gaps=(0.8e-3, 1.0e-3, 1.2e-3),
                    currents=(0.4, 0.7, 1.0, 1.3))
    rng = np.random.default_rng(3)
    force = np.array([magnet.pole_force(magnet.flux_from_current(i, s)).sum()
                      for i, s in zip(data.current, data.gaps, strict=True)])
    data = dataclasses.replace(data, force=force * (1 + NOISE * rng.standard_normal(force.size)))
    selection = select_law(data)
    assert selection.chosen == "k_i2_sfe2_sat", selection.reason
    held = {c.name: c.held_out.rms for c in selection.candidates}
    assert held["k_i2_sfe2_sat"] < 2.5 * NOISE and held["k_i2_sfe2"] > 10 * NOISE, held
    i, s = np.meshgrid(np.linspace(0.45, 1.25, 9), np.linspace(0.85e-3, 1.15e-3, 5))
    gaps = np.repeat(s.ravel()[:, None], 2, axis=1)
    truth = np.array([magnet.pole_force(magnet.flux_from_current(a, b)).sum()
                      for a, b in zip(i.ravel(), gaps, strict=True)])
    fit = selection.best.fit
    predicted = SATURATING.per_pole(fit.params, i.ravel(), gaps).sum(axis=1)
    assert np.abs(predicted / truth - 1).max() < 0.008


def test_a_knee_the_data_do_not_show_is_refused_ac_only_too():
    from forcecal.actuator import ACOnlyLaw

    data = campaign(K_I2_SFE2, TRUTH["k_i2_sfe2"], np.random.default_rng(4), NOISE)
    hi = SATURATING.bounds(data)[1]
    for law in (SATURATING, ACOnlyLaw.wrap(SATURATING, 10)):
        law.check_fitted(np.array([K_TRUE, 0.2e-3, 0.5 * hi[2], 4.0]), data)     # a knee
        for beyond in ([K_TRUE, 0.2e-3, hi[2], 4.0], [K_TRUE, 0.2e-3, 0.5 * hi[2], hi[3]]):
            with pytest.raises(FitError, match="the data show no saturation"):
                law.check_fitted(np.array(beyond), data)
