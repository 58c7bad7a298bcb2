"""Long records: chunked fits against one-shot fits, memory flat in the record length, the
fundamental refined on a subset against the whole record, series evaluated by chunks."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import forcecal.signals.fundamental as fundamental
from forcecal.errors import DataError
from forcecal.signals.fourier_sums import GridBasis, design_matrix, grid_series, series_at
from forcecal.signals.harmonics import fit_harmonics, fundamental_uncertainty, refine_fundamental

FS = 2000.0  # [Hz]
F0 = 40.0  # [Hz]
PHASORS = np.array([0.3, 1.0 + 0.5j, -0.2 + 0.1j, 0.0, 0.04 - 0.03j])
H = PHASORS.size - 1


def synth(t: np.ndarray, f0: float = F0, phasors: np.ndarray = PHASORS) -> np.ndarray:
    """x(t) = X_0 + sum Re(X_n exp(j n w0 t)), the convention of forcecal.signals.harmonics."""
    return (np.exp(1j * 2 * np.pi * f0 * np.multiply.outer(t, np.arange(phasors.size)))
            @ phasors).real


def channels(n: int, f0: float, seed: int, t0: float = 0.0,
             noise: tuple[float, ...] = (0.01, 0.03, 0.01)) -> np.ndarray:
    """(3, n) records of one fundamental: own gains, phases, offsets and white noise."""
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(n) / FS
    out = np.empty((len(noise), n))
    for k, sigma in enumerate(noise):
        turn = np.exp(1j * np.arange(H + 1) * rng.uniform(0, 2 * np.pi))
        gain = rng.uniform(0.5, 2.0) * turn
        gain[0] = rng.uniform(-3.0, 3.0)
        out[k] = synth(t, f0, PHASORS * gain) + sigma * rng.standard_normal(n)
    return out


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("chunk", [317, 1000, 4096, 8192])
@pytest.mark.parametrize("t0", [0.0, 12.3])
def test_chunked_fit_equals_one_shot_fit(chunk, t0):
    rng = np.random.default_rng(chunk)
    x = rng.standard_normal((2, 3, 5003)) + synth(t0 + np.arange(5003) / FS)
    one = fit_harmonics(x, FS, F0 * 1.001, H, t0=t0)
    by_chunks = fit_harmonics(x, FS, F0 * 1.001, H, t0=t0, chunk=chunk)
    assert relative(by_chunks.phasors, one.phasors) < 1e-10
    assert relative(by_chunks.residual_std, one.residual_std) < 1e-10
    assert relative(by_chunks.phasor_std, one.phasor_std) < 1e-10
    assert relative(by_chunks.unscaled_covariance, one.unscaled_covariance) < 1e-10
    assert relative(by_chunks.residuals, one.residuals) < 1e-10
    assert by_chunks.phasors.shape == one.phasors.shape == (2, 3, H + 1)


def test_chunked_fit_of_noise_free_record_is_exact():
    t = 3.0 + np.arange(20011) / FS
    fit = fit_harmonics(synth(t), FS, F0, H, t0=3.0, chunk=1024)
    np.testing.assert_allclose(fit.phasors, PHASORS, rtol=0, atol=1e-12)
    assert float(fit.residual_std) < 1e-12


def test_grams_and_series_by_chunks_equal_the_whole_design_matrix():
    t0, n = 7.25, 10_007
    t = t0 + np.arange(n) / FS
    x = design_matrix(t, F0, H)
    basis = GridBasis(n, FS, t0, F0, H, chunk=999)
    t_mid = t0 + 0.4 * n / FS
    for q, gram in enumerate(basis.moment_grams(t_mid, 2)):
        expected = x.T @ (x * ((t - t_mid) ** q)[:, None])
        assert relative(gram, expected) < 1e-12
    y = np.random.default_rng(2).standard_normal(n)
    assert relative(basis.project(y), x.T @ y) < 1e-12
    phasors = np.stack([PHASORS, 2j * PHASORS])
    coef = np.column_stack([phasors[:, 0].real, np.stack([phasors[:, 1:].real,
                                                          phasors[:, 1:].imag], -1)
                            .reshape(2, -1)])
    exact = coef @ x.T                  # the phases reduced modulo a cycle, as in the fits
    # phases of ~1e3 cycles carry ~1e-13 cycle of rounding either way
    np.testing.assert_allclose(grid_series(phasors, F0, FS, t0, n, chunk=999), exact,
                               rtol=0, atol=1e-11)
    np.testing.assert_allclose(series_at(phasors, F0, t), exact, rtol=0, atol=1e-11)
    scattered = np.sort(np.random.default_rng(3).uniform(t0, t0 + 1.0, 500))
    np.testing.assert_allclose(series_at(phasors, F0, scattered),
                               coef @ design_matrix(scattered, F0, H).T, rtol=0, atol=1e-12)


def traced_peak(run) -> int:
    """Peak of the memory allocated while ``run()`` runs [bytes]."""
    tracemalloc.start()
    try:
        run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("stage", ["fit", "refine", "uncertainty"])
def test_memory_does_not_grow_with_the_record(stage):
    f_true = F0 * 1.0007
    peaks = []
    for n in (1 << 18, 1 << 19):            # both above LONG_RECORD: the chunked paths
        x = channels(n, f_true, seed=5)
        run = {"fit": lambda x=x: fit_harmonics(x, FS, f_true, H),
               "refine": lambda x=x: refine_fundamental(x, FS, F0, H),
               "uncertainty": lambda x=x: fundamental_uncertainty(x, FS, f_true, H)}[stage]
        peaks.append(traced_peak(run))
    assert peaks[1] < 1.3 * peaks[0]
    assert peaks[1] < 0.5 * x.nbytes            # never a copy of the records


@pytest.fixture
def short_long_record(monkeypatch):
    """Records of 12 000 samples count as long: refined on their first 2048 samples."""
    def use_subset():
        monkeypatch.setattr(fundamental, "LONG_RECORD", 2048)
    return use_subset


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_refinement_on_a_subset_agrees_with_the_whole_record(short_long_record, seed):
    f_true = F0 * (1 + 0.003 * (seed - 1))
    x = channels(12_000, f_true, seed, t0=12.5, noise=(*(0.01, 0.1, 0.001)[seed:], 0.02))
    whole = refine_fundamental(x, FS, F0, H, t0=12.5)
    u_whole = fundamental_uncertainty(x, FS, whole, H, t0=12.5)
    short_long_record()
    subset = refine_fundamental(x, FS, F0, H, t0=12.5)
    assert abs(subset - whole) < 1e-9 * whole
    assert abs(subset - whole) < 0.01 * u_whole
    assert abs(whole - f_true) < 5 * u_whole
    u_subset = fundamental_uncertainty(x, FS, subset, H, t0=12.5)
    assert u_subset == pytest.approx(u_whole, rel=1e-6)


def test_subset_refinement_falls_back_to_doubling_segments(short_long_record, monkeypatch):
    """When the whole record's minimum is not next to the subset's, the search doubles its
    segments from the subset up to the whole record and still finds it."""
    x = channels(12_000, F0 * 1.002, seed=4, t0=1.0)
    whole = refine_fundamental(x, FS, F0, H, t0=1.0)
    short_long_record()
    monkeypatch.setattr(fundamental, "_check_whole", lambda *args: None)
    assert refine_fundamental(x, FS, F0, H, t0=1.0) == pytest.approx(whole, rel=1e-9)


def test_long_record_errors_are_those_of_short_ones(short_long_record):
    short_long_record()
    x = channels(12_000, F0, seed=6)
    x[1] = 2.5
    with pytest.raises(DataError, match="record 1 is constant"):
        refine_fundamental(x, FS, F0, H)
    rng = np.random.default_rng(7)
    with pytest.raises(DataError, match="contradict the nominal drive frequency"):
        refine_fundamental(rng.standard_normal((2, 12_000)), FS, F0, H)
