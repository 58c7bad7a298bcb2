"""Tests of the calibration's parameter uncertainty: propagation from the runs' phasors, the
type-B effects, and the budget in ``calibration.json``.

The synthetic campaign is built from phasors, as a reconstruction gives them: each run (three
static gaps x two DC currents) has the current's, the pole displacement's and the total force's
phasors (the force is the law ``k_i2_sfe2`` evaluated on the current and gaps, truncated to its
first harmonics), and its calibration samples are their Fourier series at ``n`` instants over
one period. The noise is drawn on the phasors: the force's and the current's own noise, a
coordinate of the probes that moves both the inertia force and the gaps, the DC deflection, a
tare offset common to every run and a scan-shape error common to every run's inertia.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from forcecal.actuator import K_I2_SFE2, ACOnlyLaw, Calibration, fit_law
from forcecal.actuator.gaps import PoleMotion, fourier_series
from forcecal.actuator.propagation import NoiseColumns, column_effects, covariance_of
from forcecal.campaign import (
    CalibrationSamples,
    RunNoise,
    RunResult,
    calibrate_runs,
    calibration_data,
    noise_columns,
    parameter_uncertainty,
    write_calibration,
)
from forcecal.campaign.noise import CoordinateNoise, SharedEffect
from forcecal.errors import DimensionError, InputError
from forcecal.io.manifest import ManifestEntry
from forcecal.rig import TypeB
from forcecal.simulate.presets import get_preset
from forcecal.simulate.virtual_rig import public_rig

F0 = 20.0  # [Hz]
H = 3  # harmonics kept
TRUTH = np.array([5.0e-6, 5.0e-5])  # K per pole [N m^2/A^2], s_fe [m]
GAPS = (0.8e-3, 1.0e-3, 1.2e-3)  # [m]
DCS = (0.4, 0.8)  # [A]
AC = 0.2  # [A]
DC_SHAPE = np.array([1.0e-5, 1.1e-5])  # [m] quasi-static shape at the two poles
MOTION = np.array([[1.0e-5], [1.2e-5]])  # [m] per unit coordinate of harmonic 1
INERTIA_SHARE = 0.1 * np.exp(0.3j)  # the inertia's share of the force's fundamental

# standard uncertainties of the phasors
SIGMA_F = 2e-3  # [N] each force phasor component
SIGMA_I = 2e-4  # [A] each current phasor component
SIGMA_Q = 0.05  # [1] the fundamental's coordinate (Re and Im)
FORCE_PER_Q = 0.05 + 0.02j  # [N] the inertia force per unit coordinate
SIGMA_DC = 0.05  # [1] the quasi-static amplitude
SIGMA_TARE = 1e-3  # [N] the tare's DC, common to every run
SIGMA_SHAPE = 0.02  # [1] the shapes' relative error of the inertia, common to every run

N_MONTE_CARLO = 400
MC_RTOL = 0.12  # stated standard uncertainty against the Monte Carlo's (sampling error ~3.5 %)


@dataclasses.dataclass(frozen=True)
class Phasors:
    """One run's phasors: current (H+1,), pole displacement (2, H+1), force (H+1,)."""

    current: np.ndarray
    motion: np.ndarray
    force: np.ndarray
    static_gap: float
    t0: float


def _true_runs() -> list[Phasors]:
    """The runs' phasors without noise; the force is the law's, truncated to H harmonics."""
    runs = []
    fine = np.arange(256) / (256 * F0)
    for k, (gap, dc) in enumerate((g, d) for g in GAPS for d in DCS):
        current = np.zeros(H + 1, dtype=complex)
        current[:2] = dc, AC * np.exp(0.4j * k)
        motion = np.zeros((2, H + 1), dtype=complex)
        motion[:, 0] = 2.0 * dc * DC_SHAPE
        motion[:, 1] = (MOTION[:, 0] * dc * np.exp(0.4j * k + 0.2j))
        i = fourier_series(current, F0, fine)
        s = gap - fourier_series(motion, F0, fine).T
        f = K_I2_SFE2.per_pole(TRUTH, i, s).sum(axis=1)
        spectrum = np.fft.rfft(f) / f.size
        force = np.concatenate([[spectrum[0].real], 2 * spectrum[1:H + 1]])
        runs.append(Phasors(current, motion, force, gap, t0=0.37 * k))
    return runs


def _noise(p: Phasors) -> RunNoise:
    """The run's noise description, as :func:`forcecal.campaign.run_noise` gives it."""
    no_motion = np.zeros((2, H + 1), dtype=complex)
    tare = np.zeros(H + 1, dtype=complex)
    tare[0] = SIGMA_TARE
    shared = [SharedEffect("tare 'tare' R1", "tare record", tare, no_motion)]
    for part, unit in (("re", 1.0), ("im", 1j)):  # a common complex error of the inertia
        shape = np.zeros(H + 1, dtype=complex)
        shape[1] = unit * SIGMA_SHAPE * INERTIA_SHARE * p.force[1]
        shared.append(SharedEffect(f"shape {part}", "scan shapes", shape, no_motion))
    return RunNoise(
        force_std={"gauge noise": np.full(H + 1, SIGMA_F)},
        current_std=np.full(H + 1, SIGMA_I),
        coordinates=(CoordinateNoise(1, np.array([FORCE_PER_Q]), MOTION.astype(complex),
                                     np.array([[SIGMA_Q**2]])),),
        dc_shape=DC_SHAPE, dc_std=SIGMA_DC, shared=tuple(shared))


def _result(k: int, p: Phasors, n: int, type_b: tuple[SharedEffect, ...] = ()) -> RunResult:
    """A run's result with its calibration samples at ``n`` instants over one period."""
    t = p.t0 + np.arange(n) / (n * F0)
    motion = PoleMotion(f0=F0, phasors=p.motion, static_gap=np.full(2, p.static_gap),
                        dc_misfit=0.0)
    force = fourier_series(p.force, F0, t)
    samples = CalibrationSamples(
        time=t, current=fourier_series(p.current, F0, t), gaps=motion.gaps(t).T, force=force,
        static_force=0.9 * force, flux=None, motion=motion,
        noise=dataclasses.replace(_noise(p), type_b=type_b))
    name = f"run{k}"
    estimate = SimpleNamespace(f0=F0, total=p.force, inertia_share=0.1, notes=(),
                               run_name=name)
    entry = ManifestEntry(run=Path(f"{name}.csv"), gap=p.static_gap,
                          labels={"dc": f"{abs(p.current[0]):g}"})
    return RunResult(entry=entry, estimate=estimate, samples=samples, tare="tare")


def _results(runs: list[Phasors], n: int = 64, type_b: bool = False) -> list[RunResult]:
    effects: list[tuple[SharedEffect, ...]] = [() for _ in runs]
    if type_b:  # one gauge scale of 0.5 %: every run's force 0.5 % larger, systematic
        effects = [(SharedEffect("gauges[0].scale", "gauge sensitivity", 0.005 * p.force,
                                np.zeros((2, H + 1), dtype=complex)),) for p in runs]
    return [_result(k, p, n, e) for k, (p, e) in enumerate(zip(runs, effects, strict=True))]


def _drawn(runs: list[Phasors], rng: np.random.Generator) -> list[Phasors]:
    """The runs' phasors with one draw of every noise source."""
    def phasor_noise(sigma: float) -> np.ndarray:
        z = sigma * (rng.standard_normal(H + 1) + 1j * rng.standard_normal(H + 1))
        z[0] = z[0].real
        return z

    tare = SIGMA_TARE * rng.standard_normal()
    shape = SIGMA_SHAPE * complex(rng.standard_normal(), rng.standard_normal())
    out = []
    for p in runs:
        dq = SIGMA_Q * complex(rng.standard_normal(), rng.standard_normal())
        force = p.force + phasor_noise(SIGMA_F)
        force[0] += tare
        force[1] += FORCE_PER_Q * dq + shape * INERTIA_SHARE * p.force[1]
        motion = p.motion.copy()
        motion[:, 1] += MOTION[:, 0] * dq
        motion[:, 0] += DC_SHAPE * SIGMA_DC * rng.standard_normal()
        out.append(dataclasses.replace(p, current=p.current + phasor_noise(SIGMA_I),
                                       force=force, motion=motion))
    return out


def _rig(**type_b: float):
    values = dict.fromkeys(TypeB.KEYS, 0.0) | type_b
    return dataclasses.replace(public_rig(get_preset("campaign")),
                               type_b=TypeB(**values, declared=True))


@pytest.fixture(scope="module")
def runs() -> list[Phasors]:
    return _true_runs()


@pytest.mark.parametrize("ac_only", [False, True], ids=["dc-coupled", "ac-only"])
def test_propagated_covariance_matches_a_monte_carlo_of_the_fit(runs, ac_only):
    law = ACOnlyLaw.wrap(K_I2_SFE2, 64) if ac_only else K_I2_SFE2
    results = _results(runs)
    data = calibration_data(results, ac_only=ac_only)
    fit = fit_law(law, data, start=TRUTH)
    stated = parameter_uncertainty(fit, data, results, _rig())
    rng = np.random.default_rng(7)
    drawn = []
    for _ in range(N_MONTE_CARLO):
        noisy = calibration_data(_results(_drawn(runs, rng)), ac_only=ac_only)
        # the weights are the noise-free data's, as in the propagation
        noisy = dataclasses.replace(noisy, sigma=data.sigma, force_floor=data.force_floor)
        drawn.append(fit_law(law, noisy, start=fit.params).params)
    mc = np.cov(np.array(drawn).T)
    np.testing.assert_allclose(stated.stderr, np.sqrt(np.diag(mc)), rtol=MC_RTOL)
    corr = mc[0, 1] / np.sqrt(mc[0, 0] * mc[1, 1])
    assert stated.correlation[0, 1] == pytest.approx(corr, abs=0.03)
    assert set(stated.budget) == {"gauge noise", "probe noise", "current noise", "tare record",
                                  "scan shapes"}


def test_noise_columns_reproduce_the_phasor_noise(runs):
    columns = noise_columns(_results(runs[:1]), 2)
    labels = np.array(columns.labels)
    # the force of one run: DC and three harmonics (Re, Im) of its own noise
    own = columns.force[:, labels == "gauge noise"]
    assert own.shape[1] == 2 * H + 1
    np.testing.assert_allclose(np.sum(own**2, axis=1), SIGMA_F**2 * (1 + H), rtol=1e-9)
    # the DC deflection and the coordinate both move the gaps; one error of the coordinate
    # moves the force and the gaps together: their covariance at every instant is
    # -SIGMA_Q^2 Re(dF/dQ conj(dw/dQ)) (the gap is the static gap minus w)
    probe = labels == "probe noise"
    gaps = columns.gaps[:, :, probe]
    assert gaps.shape[2] == 3 and np.all(np.abs(gaps).max(axis=(0, 1)) > 0)
    cross = np.einsum("nc,npc->np", columns.force[:, probe], gaps)
    expected = -SIGMA_Q**2 * np.real(FORCE_PER_Q * np.conj(MOTION[:, 0]))
    np.testing.assert_allclose(cross, np.broadcast_to(expected, cross.shape), rtol=1e-9)


def test_duplicated_samples_do_not_shrink_the_statistical_uncertainty(runs):
    one = _results(runs, n=32)
    two = []
    for r in one:  # every instant twice, in the same run
        s = r.samples
        two.append(dataclasses.replace(r, samples=dataclasses.replace(
            s, time=np.repeat(s.time, 2), current=np.repeat(s.current, 2),
            gaps=np.repeat(s.gaps, 2, axis=0), force=np.repeat(s.force, 2),
            static_force=np.repeat(s.static_force, 2))))
    stds, residual = [], []
    for results in (one, two):
        data = calibration_data(results)
        fit = fit_law(K_I2_SFE2, data, start=TRUTH)
        stds.append(parameter_uncertainty(fit, data, results, _rig()).stderr)
        residual.append(fit.stderr)
    np.testing.assert_allclose(stds[1], stds[0], rtol=1e-6)
    # the residual covariance counts every sample: it shrinks by about sqrt(2)
    np.testing.assert_allclose(residual[1] / residual[0], 1 / np.sqrt(2), rtol=0.02)


def test_finer_sampling_of_the_same_runs_does_not_shrink_it(runs):
    stds = []
    for n in (32, 128):
        results = _results(runs, n=n)
        data = calibration_data(results)
        fit = fit_law(K_I2_SFE2, data, start=TRUTH)
        stds.append(parameter_uncertainty(fit, data, results, _rig()).stderr)
    np.testing.assert_allclose(stds[1], stds[0], rtol=0.02)


def test_current_scale_gives_k_twice_its_relative_uncertainty(runs):
    u = 0.002
    results = _results(runs)
    data = calibration_data(results)
    fit = fit_law(K_I2_SFE2, data, start=TRUTH)
    unc = parameter_uncertainty(fit, data, results, _rig(current_scale=u))
    k_rel = unc.budget["current scale"][0] / fit.params[0]
    assert k_rel == pytest.approx(2 * u, rel=0.05)
    assert unc.budget["current scale"][1] < 1e-3 * unc.budget["gauge noise"][1]
    # systematic: the type-B covariance is the current scale's alone, added to the noise's
    np.testing.assert_allclose(unc.covariance, unc.statistical + unc.type_b)
    assert unc.stderr[0] ** 2 == pytest.approx(
        unc.statistical[0, 0] + unc.budget["current scale"][0] ** 2, rel=1e-9)


def test_gap_uncertainty_moves_s_fe_by_about_u(runs):
    u = 10e-6
    results = _results(runs)
    data = calibration_data(results)
    fit = fit_law(K_I2_SFE2, data, start=TRUTH)
    unc = parameter_uncertainty(fit, data, results, _rig(gap=u))
    assert unc.budget["static gaps"][1] == pytest.approx(u, rel=0.05)
    assert unc.budget["static gaps"][0] < 1e-3 * fit.params[0]
    assert np.sqrt(unc.stderr[1] ** 2 - unc.statistical[1, 1]) == pytest.approx(u, rel=0.05)


def test_force_type_b_is_systematic_not_averaged_over_runs(runs):
    results = _results(runs, type_b=True)
    data = calibration_data(results)
    fit = fit_law(K_I2_SFE2, data, start=TRUTH)
    unc = parameter_uncertainty(fit, data, results, _rig(gauge_scale=0.005))
    # every run's force 0.5 % larger: K 0.5 % larger, not 0.5 % / sqrt(6)
    assert unc.budget["gauge sensitivity"][0] / fit.params[0] == pytest.approx(0.005, rel=0.02)
    assert unc.budget["gauge sensitivity"][1] < 0.01 * unc.stderr[1]


def test_column_effects_refuse_columns_of_another_size(runs):
    data = calibration_data(_results(runs))
    with pytest.raises(DimensionError, match="rows for"):
        column_effects(K_I2_SFE2, TRUTH, data, NoiseColumns(force=np.zeros((3, 1))))
    assert covariance_of(np.zeros((2, 0))).shape == (2, 2)


def test_calibration_file_carries_the_budget(runs, tmp_path):
    results = _results(runs)
    rig = _rig(current_scale=0.002, gap=10e-6)
    result = calibrate_runs(rig, results, manifest="synthetic.csv")
    assert result.law == "k_i2_sfe2"
    path = write_calibration(result, tmp_path)
    doc = json.loads(path.read_text())
    cal = Calibration.load(path)  # the schema check accepts the new keys
    unc = doc["uncertainty"]
    np.testing.assert_allclose(cal.covariance, result.uncertainty.covariance)
    assert doc["stderr"]["K"] == pytest.approx(unc["stderr"]["K"])
    assert unc["expanded"]["s_fe"] == pytest.approx(2 * unc["stderr"]["s_fe"])
    assert {"gauge noise", "current noise", "current scale", "static gaps"} <= set(unc["budget"])
    assert unc["budget"]["current scale"]["kind"] == "type B"
    assert doc["k_total"]["expanded"] == pytest.approx(2 * doc["k_total"]["stderr"])
    assert doc["k_total"]["stderr"] == pytest.approx(2 * unc["stderr"]["K"])
    assert unc["run_scatter_stderr"]["K"] > 0 and unc["residual_stderr"]["K"] > 0
    row = next(r for r in doc["candidates"] if r["law"] == "k_i2_sfe2")
    assert row["stderr_statistical"]["K"] == pytest.approx(unc["statistical"]["stderr"]["K"])
    text = result.uncertainty.to_json(2)["k_total"]
    assert text["budget"]["current scale"] == pytest.approx(
        2 * unc["budget"]["current scale"]["K"])
    bad = dict(doc, uncertainty=dict(unc, stderr={"K": -1.0, "s_fe": 1e-6}))
    with pytest.raises(InputError, match=r"uncertainty\.stderr\.K"):
        Calibration.from_json(bad, "bad.json")
    bad = dict(doc, uncertainty=dict(unc, param_names=["K"]))
    with pytest.raises(InputError, match=r"uncertainty\.param_names"):
        Calibration.from_json(bad, "bad.json")
