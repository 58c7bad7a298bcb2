"""Tests of forcecal.signals.harmonics against synthetic signals of known Fourier series."""

from __future__ import annotations

import numpy as np
import pytest

from forcecal.errors import DataError
from forcecal.signals.harmonics import (
    design_matrix,
    fit_harmonics,
    fundamental_uncertainty,
    noise_bound,
    refine_fundamental,
    significant_harmonics,
)

FS = 2000.0  # [Hz]
F0 = 40.0  # [Hz]
# X_0 .. X_4 of the reference signal; harmonic 3 absent on purpose
PHASORS = np.array([0.3, 1.0 + 0.5j, -0.2 + 0.1j, 0.0, 0.04 - 0.03j])
H = PHASORS.size - 1


def synth(t: np.ndarray, f0: float = F0, phasors: np.ndarray = PHASORS) -> np.ndarray:
    """x(t) = X_0 + sum Re(X_n exp(j n w0 t)), the convention of the module."""
    n = np.arange(phasors.size)
    return (np.exp(1j * 2 * np.pi * f0 * np.multiply.outer(t, n)) @ phasors).real


def times(n_samples: int, t0: float = 0.0) -> np.ndarray:
    return t0 + np.arange(n_samples) / FS


def test_design_matrix_coefficients_are_re_and_im_of_the_phasors():
    t = times(137, t0=0.37)
    coef = np.array([0.3, 1.0, 0.5, -0.2, 0.1])  # X_0, Re X_1, Im X_1, Re X_2, Im X_2
    x = design_matrix(t, F0, 2) @ coef
    np.testing.assert_allclose(x, synth(t, phasors=PHASORS[:3]), rtol=0, atol=1e-13)


@pytest.mark.parametrize("n_periods", [20.0, 20.37])
@pytest.mark.parametrize("t0", [0.0, 0.123, 1234.5678])
def test_phasors_exact_for_whole_and_fractional_periods(n_periods, t0):
    n_samples = round(n_periods * FS / F0)
    x = synth(times(n_samples, t0))
    fit = fit_harmonics(x, FS, F0, H, t0=t0)
    np.testing.assert_allclose(fit.phasors, PHASORS, rtol=0, atol=1e-10 * np.abs(PHASORS).max())
    assert fit.phasors[0].imag == 0.0
    np.testing.assert_allclose(fit.amplitudes[1], abs(PHASORS[1]), rtol=1e-10)
    np.testing.assert_allclose(fit.phases[1], np.angle(PHASORS[1]), rtol=0, atol=1e-10)


def test_whole_and_fractional_records_give_identical_phasors():
    t0 = 0.123
    whole = fit_harmonics(synth(times(1000, t0)), FS, F0, H, t0=t0)  # 20 periods
    frac = fit_harmonics(synth(times(1019, t0)), FS, F0, H, t0=t0)  # 20.38 periods
    scale = np.abs(PHASORS).max()
    np.testing.assert_allclose(whole.phasors, frac.phasors, rtol=0, atol=1e-12 * scale)


def test_several_channels_share_one_fit_and_evaluate_reconstructs():
    rng = np.random.default_rng(7)
    t0 = 0.25
    t = times(1234, t0)
    gains = rng.normal(size=(2, 3)) + 1j * rng.normal(size=(2, 3))
    x = np.stack([[synth(t, phasors=g * PHASORS) for g in row] for row in gains]).real
    x = x + 0.01 * rng.standard_normal(x.shape)
    fit = fit_harmonics(x, FS, F0, H, t0=t0)
    assert fit.phasors.shape == (2, 3, H + 1)
    assert fit.residual_std.shape == (2, 3)
    assert fit.phasor_std.shape == (2, 3, H + 1)
    assert fit.covariance.shape == (2, 3, 2 * H + 1, 2 * H + 1)
    for i in range(2):
        for j in range(3):
            single = fit_harmonics(x[i, j], FS, F0, H, t0=t0)
            np.testing.assert_allclose(fit.phasors[i, j], single.phasors, rtol=1e-12)
    np.testing.assert_allclose(fit.evaluate(t) + fit.residuals, x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fit.residual_std, 0.01, rtol=0.1)


def test_phasor_std_equals_noise_bound_for_whole_periods():
    rng = np.random.default_rng(3)
    n_samples = 2000  # 40 periods
    x = synth(times(n_samples)) + 0.05 * rng.standard_normal(n_samples)
    fit = fit_harmonics(x, FS, F0, H)
    sigma = float(fit.residual_std)
    # each harmonic's level is read off the 32 or so lines of the residual's spectrum around it
    # (a median over 32 exponential lines scatters about 18 % in power; tests/
    # test_harmonic_noise.py checks its mean over 400 records to 2 %): within 25 % of the
    # broadband one here (largest deviation 23 %, at n = 1)
    np.testing.assert_allclose(fit.phasor_std[1:], np.sqrt(2 * sigma**2 / n_samples), rtol=0.25)
    np.testing.assert_allclose(fit.phasor_std[1:], noise_bound(sigma, n_samples), rtol=0.25)
    np.testing.assert_allclose(fit.phasor_std[0], sigma / np.sqrt(n_samples), rtol=0.25)
    assert fit.dof == n_samples - (2 * H + 1)


@pytest.mark.parametrize("n_samples", [1000, 1019])
def test_stated_phasor_std_matches_observed_scatter(n_samples):
    sigma = 0.05
    n_seeds = 300
    clean = synth(times(n_samples, 0.4))
    noise = np.stack(
        [np.random.default_rng(seed).standard_normal(n_samples) for seed in range(n_seeds)]
    )
    fit = fit_harmonics(clean + sigma * noise, FS, F0, H, t0=0.4)
    stated = fit.phasor_std.mean(axis=0)
    observed_re = fit.phasors.real.std(axis=0, ddof=1)
    observed_im = fit.phasors.imag.std(axis=0, ddof=1)
    assert np.all((observed_re / stated > 0.85) & (observed_re / stated < 1.15))
    assert np.all((observed_im[1:] / stated[1:] > 0.85) & (observed_im[1:] / stated[1:] < 1.15))
    # and the statement sits on the white-noise bound of METHOD.md section 6
    np.testing.assert_allclose(stated[1:], noise_bound(sigma, n_samples), rtol=0.03)


def test_refine_fundamental_recovers_offset_frequency():
    rng = np.random.default_rng(11)
    f_true = F0 * 1.003
    records = []
    for n_samples in (4000, 4000, 3500, 4000):  # e.g. scan reference records, random phases
        t = times(n_samples, rng.uniform(0, 100))
        phasors = PHASORS * np.exp(1j * np.arange(H + 1) * rng.uniform(0, 2 * np.pi))
        records.append(synth(t, f_true, phasors) + 0.002 * rng.standard_normal(n_samples))
    f_est = refine_fundamental(records, FS, F0, H)
    assert abs(f_est / f_true - 1) < 1e-6
    u = fundamental_uncertainty(records, FS, f_est, H)
    assert abs(f_est - f_true) < 5 * u
    # a (n_records, n_samples) array is accepted too
    f_arr = refine_fundamental(np.stack([r[:3500] for r in records]), FS, F0, H)
    assert abs(f_arr / f_true - 1) < 1e-6


@pytest.mark.parametrize("ratio", [0.955, 0.9647, 1.0365])
def test_refine_fundamental_does_not_miss_a_narrow_valley(ratio):
    # 4 s records: the valley of the residual is about 1 / (4 H) Hz wide, far narrower than
    # the +-2 Hz searched, and the side lobes of the objective must not catch the search
    rng = np.random.default_rng(5)
    f_true = F0 * ratio
    t = times(8000)
    x = synth(t, f_true) + 0.01 * rng.standard_normal(t.size)
    f_est = refine_fundamental([x], FS, F0, H, search=0.05)
    assert abs(f_est / f_true - 1) < 1e-6


def test_refine_fundamental_does_not_depend_on_t0():
    t = times(3000)
    x = synth(t, F0 * 1.01)
    f_a = refine_fundamental([x], FS, F0, H, t0=0.0)
    f_b = refine_fundamental([x], FS, F0, H, t0=987.654)
    assert abs(f_a / (F0 * 1.01) - 1) < 1e-9
    assert abs(f_a / f_b - 1) < 1e-9


@pytest.mark.parametrize("n_samples", [6000, 70_000])     # QR fits; chunked sums
def test_the_refinement_ends_at_the_residuals_minimum(n_samples):
    # the scoring steps stop where the fit's residual sum of squares is least: the vertex of
    # the parabola through the RSS at seven frequencies 1e-6 apart (one record: no weights)
    rng = np.random.default_rng(23)
    t = times(n_samples, 3.2)
    x = synth(t, F0 * 1.0021) + 0.05 * rng.standard_normal(t.size)
    f_est = refine_fundamental([x], FS, F0, H, t0=3.2)
    grid = f_est * (1.0 + 1e-6 * np.arange(-3, 4))
    rss = [float(fit_harmonics(x, FS, f, H, t0=3.2).residual_std) ** 2 for f in grid]
    a, b, _ = np.polyfit(grid - f_est, rss, 2)
    vertex = f_est - b / (2.0 * a)
    assert abs(f_est / vertex - 1) < 2e-11      # achieved: 3e-12 (QR), 6e-12 (chunked)


def test_fundamental_uncertainty_matches_cramer_rao_of_a_sinusoid():
    rng = np.random.default_rng(21)
    amp, sigma, n_samples = 1.0, 0.1, 4000
    t = times(n_samples)
    x = amp * np.cos(2 * np.pi * F0 * t + 0.3) + sigma * rng.standard_normal(n_samples)
    u = fundamental_uncertainty([x], FS, F0, 1)
    # Kay's bound for a real sinusoid: var(f) = 12 fs^2 / ((2 pi)^2 SNR N^3), SNR = A^2 / 2 s^2
    snr = amp**2 / (2 * sigma**2)
    crb = np.sqrt(12 * FS**2 / ((2 * np.pi) ** 2 * snr * n_samples**3))
    np.testing.assert_allclose(u, crb, rtol=0.05)


def test_too_few_periods_raise():
    x = synth(times(200))  # 4 periods of 40 Hz at 2 kHz
    with pytest.raises(DataError, match=r"4\.0 periods.*at least 5"):
        refine_fundamental([x], FS, F0, H)


def test_contradicting_nominal_frequency_raises():
    rng = np.random.default_rng(2)
    t = times(4000)
    x = np.sin(2 * np.pi * 55.0 * t) + 0.01 * rng.standard_normal(t.size)
    with pytest.raises(
        DataError, match=r"contradict the nominal drive frequency of 40 Hz.*explains only"
    ):
        refine_fundamental([x], FS, F0, 3)


def test_harmonics_above_nyquist_raise():
    with pytest.raises(DataError, match="Nyquist"):
        fit_harmonics(np.zeros(1000), 200.0, F0, 3)


def test_significant_harmonics_flags_only_supported_harmonics():
    rng = np.random.default_rng(9)
    x = synth(times(4000)) + 0.05 * rng.standard_normal(4000)
    mask = significant_harmonics(fit_harmonics(x, FS, F0, H + 2), k=5.0)
    np.testing.assert_array_equal(mask, [True, True, True, False, True, False, False])


@pytest.mark.slow
def test_refined_fundamental_scatter_matches_its_uncertainty():
    sigma, n_samples, n_seeds = 0.05, 2000, 200
    f_true = F0 * 1.002
    errors, stated = [], []
    for seed in range(n_seeds):
        rng = np.random.default_rng(seed)
        x = synth(times(n_samples), f_true) + sigma * rng.standard_normal(n_samples)
        f_est = refine_fundamental([x], FS, F0, H)
        errors.append(f_est - f_true)
        stated.append(fundamental_uncertainty([x], FS, f_est, H))
    ratio = np.std(errors, ddof=1) / np.mean(stated)
    assert 0.85 < ratio < 1.15


def test_a_noisy_record_does_not_pull_the_joint_fundamental():
    """Records are weighted by their noise (maximum likelihood), not by their RMS."""
    f_true = F0 * 1.002
    t = times(4000)
    for seed in range(5):
        rng = np.random.default_rng(100 + seed)
        clean = np.cos(2 * np.pi * f_true * t + 0.4) + 1e-3 * rng.standard_normal(t.size)
        noisy = np.cos(2 * np.pi * f_true * t - 1.0) + 3.0 * rng.standard_normal(t.size)
        f = refine_fundamental([clean, noisy], FS, F0, 1)
        bound = fundamental_uncertainty([clean, noisy], FS, f, 1)
        assert abs(f - f_true) < 4 * bound
