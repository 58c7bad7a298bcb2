"""Fourier series of steady periodic signals, fitted by linear least squares (METHOD.md
section 3, step 1, and section 6).

A steady periodic signal of fundamental f0 = w0 / (2 pi) is written
x(t) = X_0 + sum_{n=1..H} Re(X_n exp(j n w0 t)), with t the *absolute* time stamp of each
sample, t = t0 + k / fs, so that records taken at different times keep their relative phase.
X_0 is real (the mean) and X_n = A_n exp(j phi_n) carries the amplitude A_n and the phase phi_n
of harmonic n (one-sided amplitude: a unit cosine has X_1 = 1).

The fit is ordinary least squares on the design matrix of :func:`design_matrix`; it neither
needs nor assumes a whole number of periods in the record. Time is on the last axis: every
channel of ``x`` (..., n_samples) is fitted with one shared QR factorization; records longer
than :data:`~forcecal.signals.fundamental.LONG_RECORD` samples are fitted chunk by chunk from
the normal equations (:mod:`forcecal.signals.fourier_sums`). The fundamental itself is refined
by :func:`refine_fundamental` (:mod:`forcecal.signals.fundamental`).

For white noise of std sigma over N samples spanning whole periods, Re and Im of every harmonic
n >= 1 have variance 2 sigma^2 / N and the mean sigma^2 / N (:func:`noise_bound`); otherwise
the exact diagonal of (A^T A)^-1 is used, and for coloured noise sigma is the level at each
harmonic's own frequency, tones leaking in counted (:mod:`forcecal.signals.noise`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_triangular

from ..errors import DataError
from .fourier_sums import (
    CHUNK,
    checked_samples,
    design_matrix,
    fit_chunked,
    grid_series,
    qr_fit,
    series_at,
)
from .fundamental import LONG_RECORD, fundamental_uncertainty, refine_fundamental
from .noise import phasor_noise

__all__ = ["HarmonicFit", "fit_harmonics", "fundamental_uncertainty", "refine_fundamental"]

@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares Fourier series of one or several records sharing one time base.

    Attributes
    ----------
    f0 : float [Hz]
        Fundamental frequency used in the fit.
    phasors : (..., H+1) complex array [unit of x]
        X_0 .. X_H in the convention of the module docstring (X_0 real).
    residual_std : (...) array [unit of x]
        Unbiased residual standard deviation, sqrt(RSS / (N - (2H+1))).
    phasor_std : (..., H+1) array [unit of x]
        Standard uncertainty of Re X_n and of Im X_n. For n = 0 it is the uncertainty of the
        mean; for n >= 1 the root mean square of the two exact values
        sigma_n * sqrt(diag (A^T A)^-1), which are equal (sqrt(2 / N) sigma_n) for a whole
        number of periods; sigma_n is the noise level at n f0 from the residual's spectrum
        around it (:mod:`forcecal.signals.noise`): coloured noise and hum lines away from n f0 do
        not count, as they do not disturb X_n.
    unscaled_covariance : (2H+1, 2H+1) array [1]
        (A^T A)^-1 of the design matrix, coefficient order [X_0, Re X_1, Im X_1, Re X_2, ...];
        multiply by ``residual_std**2`` for the covariance of one channel (see
        :attr:`covariance`).
    fs : float [Hz]
        Sampling rate of the records.
    samples : (..., n_samples) array [unit of x]
        The records fitted (held, not copied).
    t0 : float [s]
        Absolute time of the first sample.
    """

    f0: float
    phasors: np.ndarray
    residual_std: np.ndarray
    phasor_std: np.ndarray
    unscaled_covariance: np.ndarray
    fs: float
    samples: np.ndarray = field(repr=False, compare=False)
    t0: float = 0.0
    _residuals: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def residuals(self) -> np.ndarray:
        """(..., n_samples) data minus the fitted series [unit of x] (of a long record,
        computed on first use)."""
        if self._residuals is None:
            fitted = grid_series(self.phasors, self.f0, self.fs, self.t0, self.n_samples)
            object.__setattr__(self, "_residuals", np.subtract(self.samples, fitted,
                                                               out=fitted))
        assert self._residuals is not None
        return self._residuals

    @property
    def n_harmonics(self) -> int:
        """Number H of harmonics above DC."""
        return self.phasors.shape[-1] - 1

    @property
    def n_samples(self) -> int:
        """Number of samples per record."""
        return int(self.samples.shape[-1])

    @property
    def dof(self) -> int:
        """Residual degrees of freedom N - (2H+1)."""
        return self.n_samples - (2 * self.n_harmonics + 1)

    @property
    def amplitudes(self) -> np.ndarray:
        """(..., H+1) amplitudes |X_n| [unit of x] (|mean| for n = 0)."""
        return np.abs(self.phasors)

    @property
    def phases(self) -> np.ndarray:
        """(..., H+1) phases arg X_n [rad]."""
        return np.angle(self.phasors)

    @property
    def times(self) -> np.ndarray:
        """(n_samples,) absolute sample times t0 + k / fs [s]."""
        return self.t0 + np.arange(self.n_samples) / self.fs

    @property
    def covariance(self) -> np.ndarray:
        """(..., 2H+1, 2H+1) covariance of [X_0, Re X_1, Im X_1, ...] [unit of x ^2]."""
        s2 = np.asarray(self.residual_std) ** 2
        return s2[..., None, None] * self.unscaled_covariance

    def evaluate(self, t: np.ndarray) -> np.ndarray:
        """Reconstruct the fitted series.

        Parameters
        ----------
        t : (n_t,) array [s]
            Absolute times (evaluated a block at a time: memory bounded).

        Returns
        -------
        (..., n_t) array [unit of x]
        """
        return series_at(self.phasors, self.f0, t)


def fit_harmonics(
    x: np.ndarray, fs: float, f0: float, n_harmonics: int, t0: float = 0.0,
    chunk: int | None = None,
) -> HarmonicFit:
    """Fit the Fourier series of one or several records at a known fundamental.

    Parameters
    ----------
    x : (..., n_samples) array [any unit]
        Records, time on the last axis; every channel shares the time base.
    fs : float
        Sampling rate [Hz].
    f0 : float
        Fundamental frequency [Hz] (refine it first with :func:`refine_fundamental`).
    n_harmonics : int
        Number H of harmonics above DC; H f0 must be below fs / 2.
    t0 : float
        Absolute time of the first sample [s].
    chunk : int, optional
        Samples per chunk of the normal equations
        (:func:`forcecal.signals.fourier_sums.fit_chunked`). Default: one QR factorization of
        the whole design matrix for records up to
        :data:`~forcecal.signals.fundamental.LONG_RECORD` samples, chunks of
        :data:`~forcecal.signals.fourier_sums.CHUNK` beyond. Either way the results agree to
        rounding.

    Returns
    -------
    HarmonicFit
        Phasors X_0 .. X_H of every record, their standard uncertainties and the residuals.

    Raises
    ------
    DataError
        Non-finite samples, too few samples, or harmonics above the Nyquist frequency.
    ConditioningError
        The design matrix is numerically rank deficient.
    """
    x = checked_samples(x, fs, f0, n_harmonics)
    n_cols = 2 * n_harmonics + 1
    n_samples = x.shape[-1]
    lead = x.shape[:-1]
    resid = None
    if chunk is None and n_samples <= LONG_RECORD:
        t = t0 + np.arange(n_samples) / fs
        xt = x.reshape(-1, n_samples).T  # (N, M)
        fit = qr_fit(xt, t, f0, n_harmonics)
        coef, sigma, resid = fit.coef, fit.sigma, fit.residuals.T.reshape(x.shape)
        r_inv = solve_triangular(fit.r, np.eye(n_cols))
        cov = r_inv @ r_inv.T
    else:
        chunked = fit_chunked(x.reshape(-1, n_samples), fs, f0, n_harmonics, t0,
                              CHUNK if chunk is None else chunk)
        coef, cov = chunked.coef.T, chunked.covariance
        sigma = np.sqrt(chunked.rss / (n_samples - n_cols))
    unit_std = _unit_phasor_std(cov, n_harmonics)

    phasors = np.empty((n_harmonics + 1, coef.shape[1]), dtype=complex)
    phasors[0] = coef[0]
    phasors[1:] = coef[1::2] + 1j * coef[2::2]
    respond = _tone_response(t0 + np.arange(n_samples) / fs, f0, n_harmonics, cov) \
        if n_samples <= LONG_RECORD else None
    std = phasor_noise(_residual_segments(x.reshape(-1, n_samples), resid, phasors.T, fs, f0,
                                          t0), n_samples, fs, f0, unit_std, sigma, respond)

    return HarmonicFit(
        f0=float(f0),
        phasors=phasors.T.reshape(*lead, n_harmonics + 1),
        residual_std=sigma.reshape(lead),
        phasor_std=std.reshape(*lead, n_harmonics + 1),
        unscaled_covariance=cov,
        fs=float(fs),
        samples=x,
        t0=float(t0),
        _residuals=resid,
    )


def _tone_response(t: np.ndarray, f0: float, n_harmonics: int, cov: np.ndarray
                   ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """``respond(freqs)``: the phasors X_0 .. X_H (n_freqs, H+1) the fit gives unit cosines and
    unit sines at ``freqs`` sampled at times ``t``: (A^T A)^-1 A^T of them, ``cov`` being
    (A^T A)^-1."""
    def respond(freqs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = design_matrix(t, f0, n_harmonics)
        arg = 2 * np.pi * np.outer(t, freqs)
        tone = cov @ (a.T @ np.hstack([np.cos(arg), np.sin(arg)]))
        z = np.vstack([tone[:1], tone[1::2] + 1j * tone[2::2]]).T    # (2 n_freqs, H+1)
        return z[:len(freqs)], z[len(freqs):]
    return respond


def _residual_segments(records: np.ndarray, resid: np.ndarray | None, phasors: np.ndarray,
                       fs: float, f0: float, t0: float) -> Callable[[int, int], np.ndarray]:
    """``segment(a, b)``: samples a..b-1 of the fit's residual, from the residuals when held,
    else computed from the records and the phasors (n_records, H+1)."""
    if resid is not None:
        flat = resid.reshape(records.shape)
        return lambda a, b: flat[:, a:b]
    def segment(a: int, b: int) -> np.ndarray:
        out = np.array(records[:, a:b], dtype=float)
        step = CHUNK // 4                       # the series a block at a time: memory bounded
        for c in range(a, b, step):
            d = min(c + step, b)
            out[:, c - a:d - a] -= series_at(phasors, f0, t0 + np.arange(c, d) / fs)
        return out
    return segment


def _unit_phasor_std(cov: np.ndarray, n_harmonics: int) -> np.ndarray:
    """(H+1,) standard uncertainty of X_0 and of Re, Im X_n for unit noise [1].

    From the diagonal of the unscaled covariance ``cov`` (2H+1, 2H+1): the mean's own entry,
    then the root mean square of the Re and Im entries of every harmonic.
    """
    diag = np.diag(cov)
    unit_std = np.empty(n_harmonics + 1)
    unit_std[0] = math.sqrt(diag[0])
    unit_std[1:] = np.sqrt(0.5 * (diag[1::2] + diag[2::2]))
    return unit_std


def noise_bound(sigma: float | np.ndarray, n_samples: int) -> float | np.ndarray:
    """Standard uncertainty of Re X_n and Im X_n (n >= 1) for white noise.

    var(Re X_n) = var(Im X_n) = 2 sigma^2 / N for a whole number of periods (METHOD.md
    section 6).

    Parameters
    ----------
    sigma : float or array [unit of x]
        Standard deviation of the white noise on each sample.
    n_samples : int
        Number of samples N in the record.

    Returns
    -------
    float or array [unit of x]
        sqrt(2 sigma^2 / N).

    Raises
    ------
    DataError
        ``n_samples`` not positive.
    """
    if n_samples <= 0:
        raise DataError(f"n_samples must be positive; got {n_samples}")
    return np.sqrt(2.0 / n_samples) * np.asarray(sigma, dtype=float)


def significant_harmonics(fit: HarmonicFit, k: float = 5.0) -> np.ndarray:
    """Which harmonics stand above the noise floor.

    Parameters
    ----------
    fit : HarmonicFit
        The fit whose phasors are tested.
    k : float
        Coverage factor: harmonic n is significant when |X_n| > k * phasor_std[n].

    Returns
    -------
    (..., H+1) bool array
        Index n is harmonic n (index 0 is the mean). Combine channels with ``.any(axis=0)``.
    """
    return np.abs(fit.phasors) > k * fit.phasor_std
