"""Fourier series of steady periodic signals, fitted by linear least squares.

Convention
----------
A steady periodic signal of fundamental frequency f0 = w0 / (2 pi) is written

    x(t) = X_0 + sum_{n=1..H} Re( X_n exp(j n w0 t) ),

with t the *absolute* time stamp of each sample, t = t0 + k / fs (k = 0 .. N-1), so that records
taken at different times keep their relative phase. X_0 is real (the mean) and
X_n = A_n exp(j phi_n) carries the amplitude A_n and the phase phi_n of harmonic n (one-sided
amplitude: a unit cosine has X_1 = 1).

The fit is ordinary least squares on the design matrix of :func:`design_matrix`; it neither
needs nor assumes a whole number of periods in the record, so the phasors of noise-free data are
exact either way. Time is on the last axis: ``x`` is ``(..., n_samples)`` and every channel is
fitted with one shared QR factorization.

For white noise of standard deviation sigma over N samples spanning a whole number of periods,
Re and Im of every harmonic n >= 1 have variance 2 sigma^2 / N and the mean has sigma^2 / N
(METHOD.md section 6, :func:`noise_bound`); for other record lengths the exact diagonal of
(A^T A)^-1 is used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_triangular
from scipy.optimize import minimize_scalar

from .checks import as_records, check_periods
from .errors import ConditioningError, DataError, DimensionError

__all__ = [
    "HarmonicFit",
    "design_matrix",
    "fit_harmonics",
    "fundamental_uncertainty",
    "noise_bound",
    "refine_fundamental",
    "significant_harmonics",
]

#: Largest condition number of the design matrix accepted by :func:`fit_harmonics`.
_MAX_CONDITION = 1e10


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
        sigma * sqrt(diag (A^T A)^-1), which are equal (sqrt(2 / N) sigma) for a whole number
        of periods.
    residuals : (..., n_samples) array [unit of x]
        Data minus the fitted series.
    unscaled_covariance : (2H+1, 2H+1) array [1]
        (A^T A)^-1 of the design matrix, coefficient order [X_0, Re X_1, Im X_1, Re X_2, ...];
        multiply by ``residual_std**2`` for the covariance of one channel (see
        :attr:`covariance`).
    fs : float [Hz]
        Sampling rate of the records.
    t0 : float [s]
        Absolute time of the first sample.
    """

    f0: float
    phasors: np.ndarray
    residual_std: np.ndarray
    phasor_std: np.ndarray
    residuals: np.ndarray
    unscaled_covariance: np.ndarray
    fs: float
    t0: float = 0.0

    @property
    def n_harmonics(self) -> int:
        """Number H of harmonics above DC."""
        return self.phasors.shape[-1] - 1

    @property
    def n_samples(self) -> int:
        """Number of samples per record."""
        return self.residuals.shape[-1]

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
            Absolute times.

        Returns
        -------
        (..., n_t) array [unit of x]
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = np.arange(self.n_harmonics + 1)
        cycles = np.mod(np.multiply.outer(n * self.f0, t), 1.0)  # as in design_matrix
        rotor = np.exp(1j * 2.0 * np.pi * cycles)  # (H+1, n_t)
        return (self.phasors @ rotor).real


def design_matrix(t: np.ndarray, f0: float, n_harmonics: int) -> np.ndarray:
    """Least-squares design matrix of a Fourier series.

    Parameters
    ----------
    t : (n_samples,) array [s]
        Absolute sample times.
    f0 : float [Hz]
        Fundamental frequency.
    n_harmonics : int
        Number H of harmonics above DC.

    Returns
    -------
    (n_samples, 2H+1) array [1]
        Columns [1, cos(w0 t), -sin(w0 t), cos(2 w0 t), -sin(2 w0 t), ...], so that the
        least-squares coefficients c give X_0 = c_0 and X_n = c_{2n-1} + j c_{2n}.

    Raises
    ------
    DimensionError
        ``t`` not one-dimensional, or ``n_harmonics`` negative.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DimensionError(f"t must be one-dimensional; got shape {t.shape}")
    if n_harmonics < 0:
        raise DimensionError(f"n_harmonics must be >= 0; got {n_harmonics}")
    n = np.arange(1, n_harmonics + 1)
    # phase in cycles, reduced modulo 1 before scaling by 2 pi
    cycles = np.mod(np.multiply.outer(t, n * f0), 1.0)
    arg = 2.0 * np.pi * cycles
    a = np.empty((t.size, 2 * n_harmonics + 1))
    a[:, 0] = 1.0
    a[:, 1::2] = np.cos(arg)
    a[:, 2::2] = -np.sin(arg)
    return a


def _check_nyquist(f0: float, n_harmonics: int, fs: float) -> None:
    if n_harmonics * f0 >= 0.5 * fs:
        raise DataError(
            f"harmonic {n_harmonics} of {f0:.6g} Hz is at {n_harmonics * f0:.6g} Hz, not below "
            f"the Nyquist frequency {0.5 * fs:.6g} Hz of fs = {fs:.6g} Hz; reduce n_harmonics"
        )


def _qr(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q, r = np.linalg.qr(a)
    d = np.abs(np.diag(r))
    if d.min() <= d.max() / _MAX_CONDITION:
        raise ConditioningError(
            f"the harmonic design matrix ({a.shape[0]} samples, {a.shape[1]} columns) is "
            "numerically rank deficient: the record is too short for the harmonics requested"
        )
    return q, r


def fit_harmonics(
    x: np.ndarray, fs: float, f0: float, n_harmonics: int, t0: float = 0.0
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
    x = _checked_samples(x, fs, f0, n_harmonics)
    n_cols = 2 * n_harmonics + 1
    n_samples = x.shape[-1]
    t = t0 + np.arange(n_samples) / fs
    a = design_matrix(t, f0, n_harmonics)
    q, r = _qr(a)
    lead = x.shape[:-1]
    xt = x.reshape(-1, n_samples).T  # (N, M)
    qtx = q.T @ xt  # (2H+1, M)
    coef = solve_triangular(r, qtx)  # (2H+1, M)
    resid = xt - q @ qtx
    dof = n_samples - n_cols
    sigma = np.sqrt(np.sum(resid**2, axis=0) / dof)

    r_inv = solve_triangular(r, np.eye(n_cols))
    cov = r_inv @ r_inv.T
    unit_std = _unit_phasor_std(cov, n_harmonics)

    phasors = np.empty((n_harmonics + 1, xt.shape[1]), dtype=complex)
    phasors[0] = coef[0]
    phasors[1:] = coef[1::2] + 1j * coef[2::2]

    return HarmonicFit(
        f0=float(f0),
        phasors=phasors.T.reshape(*lead, n_harmonics + 1),
        residual_std=sigma.reshape(lead),
        phasor_std=(sigma[:, None] * unit_std).reshape(*lead, n_harmonics + 1),
        residuals=resid.T.reshape(x.shape),
        unscaled_covariance=cov,
        fs=float(fs),
        t0=float(t0),
    )


def _checked_samples(x: np.ndarray, fs: float, f0: float, n_harmonics: int) -> np.ndarray:
    """``x`` as a float array, once it is known to support a fit of ``n_harmonics``.

    Raises DataError (complex, non-finite or too few samples, non-positive rates, harmonics
    above the Nyquist frequency) or DimensionError (no time axis).
    """
    if np.iscomplexobj(x):
        raise DataError("x must be real-valued samples; got a complex array")
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        raise DimensionError("x must have a time axis; got a scalar")
    if not (fs > 0 and f0 > 0):
        raise DataError(f"fs and f0 must be positive; got fs = {fs} Hz, f0 = {f0} Hz")
    n_cols = 2 * n_harmonics + 1
    n_samples = x.shape[-1]
    if n_samples <= n_cols:
        raise DataError(
            f"a fit of {n_harmonics} harmonics needs more than {n_cols} samples; "
            f"the record has {n_samples}"
        )
    bad = ~np.isfinite(x)
    if bad.any():
        raise DataError(f"x contains {int(bad.sum())} non-finite samples")
    _check_nyquist(f0, n_harmonics, fs)
    return x


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


def _group_by_length(records: list[np.ndarray]) -> list[np.ndarray]:
    groups: dict[int, list[np.ndarray]] = {}
    for rec in records:
        groups.setdefault(rec.size, []).append(rec)
    return [np.stack(g) for g in groups.values()]


def _total_rss(groups: list[np.ndarray], fs: float, f0: float, h: int, t0: float) -> float:
    total = 0.0
    for g in groups:
        t = t0 + np.arange(g.shape[1]) / fs
        q, _ = np.linalg.qr(design_matrix(t, f0, h))
        resid = g.T - q @ (q.T @ g.T)
        total += float(np.sum(resid**2))
    return total


_SEGMENT_PERIODS = 40
"""Periods of the leading segment on which :func:`refine_fundamental` first searches."""


def refine_fundamental(
    records: np.ndarray | Sequence[np.ndarray],
    fs: float,
    f0_nominal: float,
    n_harmonics: int,
    t0: float = 0.0,
    search: float = 0.05,
    min_explained: float = 0.5,
) -> float:
    """Estimate the fundamental frequency shared by several records.

    The fundamental minimizes the total residual sum of squares of the harmonic fits of all
    records, each scaled by its own RMS (about its mean) so that no record dominates: a grid
    search (:func:`_grid_search`) brackets the minimum, a bounded scalar minimization refines
    it to about 1e-10 relative, and several records are finally weighted by their own noise.

    Parameters
    ----------
    records : (n_records, n_samples) array or sequence of 1-D arrays [any unit]
        Records that share one fundamental (all scan reference records, all channels of a
        run); records in a sequence may differ in length.
    fs : float
        Sampling rate [Hz].
    f0_nominal : float
        Nominal drive frequency [Hz].
    n_harmonics : int
        Number H of harmonics in the model (at least 1).
    t0 : float
        Absolute time of the first sample [s]; the residual, hence the result, does not depend
        on it.
    search : float
        Half-width of the search interval relative to ``f0_nominal`` [1].
    min_explained : float
        Smallest acceptable fraction of the (mean-removed) variance explained by the best
        fit [1].

    Returns
    -------
    float
        The refined fundamental [Hz].

    Raises
    ------
    DataError
        A record shorter than 5 periods, a constant record, harmonics above the Nyquist
        frequency, or a best fit that explains less than ``min_explained`` of the variance
        (the data contradict the nominal frequency).
    """
    _check_refine_arguments(fs, f0_nominal, n_harmonics, search)
    recs = as_records(records)
    f_lo = f0_nominal * (1.0 - search)
    f_hi = f0_nominal * (1.0 + search)
    _check_nyquist(f_hi, n_harmonics, fs)
    lengths = np.array([rec.size for rec in recs])
    check_periods(lengths, fs, f0_nominal)
    groups = _group_by_length(_unit_rms(recs))
    total_var = float(lengths.sum())  # each scaled record has unit mean square
    best = _grid_search(groups, fs, f0_nominal, n_harmonics, t0, f_lo, f_hi)
    xatol = 1e-10 * f0_nominal
    f_best, rss_best = _bounded_minimum(groups, fs, n_harmonics, t0, (best.lo, best.hi), xatol)
    if best.rss < rss_best:  # the grid point itself was better than any trial of the search
        f_best, rss_best = best.f, best.rss
    _check_explained(1.0 - rss_best / total_var, f_best, f0_nominal, search, min_explained)
    return _noise_weighted(groups, len(recs), fs, f_best, n_harmonics, t0, best.spacing, xatol)


def _check_refine_arguments(fs: float, f0_nominal: float, n_harmonics: int,
                            search: float) -> None:
    """DataError for arguments :func:`refine_fundamental` cannot work with."""
    if n_harmonics < 1:
        raise DataError(f"refine_fundamental needs n_harmonics >= 1; got {n_harmonics}")
    if not (0.0 < search < 1.0):
        raise DataError(f"search must be in (0, 1); got {search}")
    if not (fs > 0 and f0_nominal > 0):
        raise DataError(f"fs and f0 must be positive; got fs = {fs} Hz, f0 = {f0_nominal} Hz")


def _unit_rms(records: list[np.ndarray]) -> list[np.ndarray]:
    """Every record less its mean, divided by its RMS; DataError for a constant record."""
    scaled = []
    for i, rec in enumerate(records):
        centred = rec - rec.mean()
        rms = math.sqrt(float(np.mean(centred**2)))
        if rms == 0.0 or rms <= 1e-12 * float(np.max(np.abs(rec))):
            raise DataError(f"record {i} is constant; it carries no information on f0")
        scaled.append(centred / rms)
    return scaled


def _check_explained(explained: float, f_best: float, f0_nominal: float, search: float,
                     min_explained: float) -> None:
    """DataError when the best fit explains less than ``min_explained`` of the variance."""
    if explained < min_explained:
        raise DataError(
            f"the data contradict the nominal drive frequency of {f0_nominal:.6g} Hz: best fit "
            f"at {f_best:.6g} Hz within +-{100 * search:.3g} % explains only "
            f"{100 * max(explained, 0.0):.1f} % of the variance of the records "
            f"(at least {100 * min_explained:.0f} % expected)"
        )


class _GridMinimum(NamedTuple):
    """The best point of the last (full-length) grid of :func:`_grid_search`."""

    f: float  # [Hz] the grid point of least residual
    rss: float  # its total residual sum of squares
    lo: float  # [Hz] the neighbouring grid points, bracketing the minimum
    hi: float
    spacing: float  # [Hz] the grid spacing


def _grid_search(groups: list[np.ndarray], fs: float, f0_nominal: float, n_harmonics: int,
                 t0: float, f_lo: float, f_hi: float) -> _GridMinimum:
    """Bracket the minimum of the total RSS over [f_lo, f_hi] [Hz], coarse to fine.

    The grid is spaced a quarter of the narrowest valley of the objective, 1 / (2 H T) for
    records of duration T. The full grid runs on a leading segment of the records, then the
    segment is doubled with the bracket narrowed each time, so the work grows like the record
    length, not like its square (the valley of the objective narrows as 1 / duration).
    """
    n_full = max(g.shape[1] for g in groups)
    n_seg = min(n_full, int(_SEGMENT_PERIODS * fs / f0_nominal))
    lo_f, hi_f = f_lo, f_hi
    while True:
        part = [g[:, :n_seg] for g in groups]
        spacing = 1.0 / (2.0 * n_harmonics * n_seg / fs)
        n_grid = max(math.ceil((hi_f - lo_f) / spacing) + 1, 5)
        grid = np.linspace(lo_f, hi_f, n_grid)
        rss = np.array([_total_rss(part, fs, f, n_harmonics, t0) for f in grid])
        i_best = int(np.argmin(rss))
        lo = float(grid[max(i_best - 1, 0)])
        hi = float(grid[min(i_best + 1, n_grid - 1)])
        if n_seg >= n_full:
            return _GridMinimum(float(grid[i_best]), float(rss[i_best]), lo, hi, spacing)
        n_seg = min(2 * n_seg, n_full)
        lo_f, hi_f = max(lo - spacing, f_lo), min(hi + spacing, f_hi)


def _bounded_minimum(groups: list[np.ndarray], fs: float, n_harmonics: int, t0: float,
                     bounds: tuple[float, float], xatol: float) -> tuple[float, float]:
    """(f [Hz], total RSS) at the minimum of the total RSS of ``groups`` within ``bounds``."""
    res = minimize_scalar(
        lambda f: _total_rss(groups, fs, f, n_harmonics, t0),
        bounds=bounds,
        method="bounded",
        options={"xatol": xatol, "maxiter": 500},
    )
    return float(res.x), float(res.fun)


def _noise_weighted(groups: list[np.ndarray], n_records: int, fs: float, f_best: float,
                    n_harmonics: int, t0: float, spacing: float, xatol: float) -> float:
    """The fundamental [Hz] refined within +-``spacing`` of ``f_best`` with every record
    weighted by its own noise (maximum likelihood for white noise), so that a faint, noisy
    record (a probe near a node) does not pull as hard as a clean one. One record, or
    noise-free records, keep ``f_best``."""
    noise = [fit_harmonics(g, fs, f_best, n_harmonics, t0=t0).residual_std for g in groups]
    floor = 1e-9                    # scaled records have unit RMS: below this, noise-free
    if n_records > 1 and all(np.all(s > floor) for s in noise):
        weighted = [g / s[:, None] for g, s in zip(groups, noise, strict=True)]
        bounds = (f_best - spacing, f_best + spacing)
        f_best = _bounded_minimum(weighted, fs, n_harmonics, t0, bounds, xatol)[0]
    return f_best


def fundamental_uncertainty(
    records: np.ndarray | Sequence[np.ndarray],
    fs: float,
    f0: float,
    n_harmonics: int,
    t0: float = 0.0,
) -> float:
    """Standard uncertainty of a fundamental estimated by :func:`refine_fundamental`.

    Linearized (Cramer-Rao) bound for white noise: every record contributes the Fisher
    information ||P d||^2 / sigma^2 on f0, where d = dx/df0 is the derivative of its fitted
    series, P projects out the span of its own harmonic design matrix (its phasors are nuisance
    parameters) and sigma is its residual standard deviation.

    Parameters
    ----------
    records : (n_records, n_samples) array or sequence of 1-D arrays [any unit]
        The records the fundamental was refined from.
    fs : float [Hz]
        Sampling rate.
    f0 : float [Hz]
        The refined fundamental.
    n_harmonics : int
        Number H of harmonics in the model.
    t0 : float [s]
        Absolute time of the first sample.

    Returns
    -------
    float [Hz]
        The standard uncertainty; inf when the records carry no information (noise-free
        records give 0).

    Raises
    ------
    DataError
        Complex, non-finite or empty records (see :func:`forcecal.checks.as_records`).
    """
    recs = as_records(records)
    info = 0.0
    for rec in recs:
        fit = fit_harmonics(rec, fs, f0, n_harmonics, t0)
        t = fit.times
        n = np.arange(n_harmonics + 1)
        rotor = np.exp(1j * 2.0 * np.pi * f0 * np.multiply.outer(n, t))
        d = ((1j * 2.0 * np.pi * n * t[:, None]) * rotor.T) @ fit.phasors
        d = d.real
        q, _ = np.linalg.qr(design_matrix(t, f0, n_harmonics))
        d_perp = d - q @ (q.T @ d)
        sigma2 = float(fit.residual_std) ** 2
        energy = float(d_perp @ d_perp)
        if sigma2 == 0.0:
            if energy > 0.0:
                return 0.0
            continue
        info += energy / sigma2
    return math.inf if info == 0.0 else 1.0 / math.sqrt(info)
