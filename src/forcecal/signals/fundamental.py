"""The fundamental frequency shared by several records: its refinement and its uncertainty.

:func:`refine_fundamental` minimizes the total residual sum of squares of the harmonic fits of
all records (each scaled by its own RMS), then of the same fits weighted by each record's noise.
Records up to :data:`LONG_RECORD` samples are searched on the whole record with QR fits; the
grid that brackets the minimum is localized first on shorter leading segments (its points
near the minimum are the only ones fitted on the whole record), so the work grows like the
record's length. Longer records are refined on their leading :data:`LONG_RECORD` samples, then
checked and finished on the whole record with chunked sums (:mod:`forcecal.signals.fourier_sums`):
memory stays that of a few chunks and the records are never copied.

:func:`fundamental_uncertainty` is the linearized (Cramer-Rao) bound for white noise, from the
same derivative of the fitted series that gives the refinement's steps; for long records its
sums over time come from the chunk-0 design matrix and one rotation per chunk.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from ..errors import DataError
from .checks import as_records, check_periods
from .fourier_sums import (
    GridBasis,
    check_nyquist,
    checked_samples,
    design_matrix,
    fit_chunked,
    normal_fit,
    qr_fit,
)

__all__: list[str] = []

LONG_RECORD = 1 << 16
"""Records longer than this [samples] are refined on a leading subset, then on the whole
record with chunked sums."""
_SEGMENT_PERIODS = 40
"""Periods of the leading segment on which :func:`refine_fundamental` first searches."""
_WHOLE_GRID = 16
"""Largest grid whose every point is fitted on the whole segment; a larger one is localized
first on shorter segments."""
_CHECK_STEPS = 8
"""Grid steps the check on the whole record may move from the subset's fundamental."""
_BLOCK = 1 << 16
"""Samples per block of a pass over a record (bounds the temporaries)."""
_MAX_STEPS = 20
"""Most scoring steps of a refinement (it converges in a few from the grid's best point)."""

Score = Callable[[int, float], float]
"""score(n_seg, f): the objective on the leading n_seg samples at the fundamental f [Hz]."""


class _GridMinimum(NamedTuple):
    """The best point of the last (full-length) grid of a grid search."""

    f: float  # [Hz] the grid point of least residual
    rss: float  # its total residual sum of squares
    lo: float  # [Hz] the neighbouring grid points, bracketing the minimum
    hi: float
    spacing: float  # [Hz] the grid spacing


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
    search brackets the minimum, scoring (Gauss-Newton) steps on the variable-projection
    residual refine it to about 1e-10 relative, and several records are finally weighted by
    their own noise. Records longer than :data:`LONG_RECORD` samples are refined on their
    leading :data:`LONG_RECORD` samples first; the result is then checked on a grid over the
    whole record (searched further, or by doubling segments, when the minimum is not where the
    subset put it) and refined there.

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
    check_nyquist(f_hi, n_harmonics, fs)
    lengths = np.array([rec.size for rec in recs])
    check_periods(lengths, fs, f0_nominal)
    if lengths.max() > LONG_RECORD:
        return _refine_long(recs, fs, f0_nominal, n_harmonics, t0, (f_lo, f_hi),
                            (search, min_explained))
    groups = _group_by_length(_unit_rms(recs))
    total_var = float(lengths.sum())  # each scaled record has unit mean square
    best = _grid_search(groups, fs, f0_nominal, n_harmonics, t0, f_lo, f_hi)
    xatol = 1e-10 * f0_nominal

    def objective(f: float) -> float:
        return _total_rss(groups, fs, f, n_harmonics, t0)

    f_best = _scoring_minimum(_group_terms(groups, fs, n_harmonics, t0), best.f,
                              (best.lo, best.hi), xatol)
    rss_best = objective(f_best)
    if best.rss < rss_best:  # the grid point itself was better than the steps' end
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


def _group_by_length(records: list[np.ndarray]) -> list[np.ndarray]:
    groups: dict[int, list[np.ndarray]] = {}
    for rec in records:
        groups.setdefault(rec.size, []).append(rec)
    return [np.stack(g) for g in groups.values()]


def _centred(rec: np.ndarray, i: int) -> tuple[float, float]:
    """(mean, sum of squares about it) of record ``i``; DataError when it is constant."""
    mean = float(rec.mean())
    power = 0.0
    for s in range(0, rec.size, _BLOCK):
        part = rec[s:s + _BLOCK] - mean
        power += float(part @ part)
    peak = max(float(rec.max()), -float(rec.min()))
    if power == 0.0 or math.sqrt(power / rec.size) <= 1e-12 * peak:
        raise DataError(f"record {i} is constant; it carries no information on f0")
    return mean, power


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


# ------------------------------------------------------------------ objectives


def _total_rss(groups: list[np.ndarray], fs: float, f0: float, h: int, t0: float) -> float:
    """Total residual sum of squares of least-squares fits of every record of ``groups``."""
    total = 0.0
    for g in groups:
        t = t0 + np.arange(g.shape[1]) / fs
        a = design_matrix(t, f0, h)
        got = normal_fit(a, g.T)
        if got is None:
            q, _ = np.linalg.qr(a)
            resid = g.T - q @ (q.T @ g.T)
        else:
            resid = got[1]
        total += float(np.sum(resid**2))
    return total


def _explained_power(records: Sequence[np.ndarray] | np.ndarray, means: np.ndarray, fs: float,
                     f0: float, h: int, t0: float) -> np.ndarray:
    """(n_records,) power of the fitted series about each record's mean, ||P (y - mean)||^2,
    from chunked sums: the residual sum of squares is the record's power about its mean less
    this. All records have the length of the first. -inf when the design matrix is singular
    (the residual is then +inf: never the minimum)."""
    basis = GridBasis(len(records[0]), fs, t0, f0, h)
    gram = basis.gram()
    scale = np.sqrt(np.diag(gram))
    try:
        factor = cho_factor(gram / np.outer(scale, scale), lower=True)
    except LinAlgError:
        return np.full(len(records), -np.inf)
    b = np.stack([basis.project(y) for y in records], axis=1)        # (p, m)
    b -= np.outer(gram[:, 0], means)                                 # X^T (y - mean)
    b /= scale[:, None]
    z = cho_solve(factor, b)
    return np.sum(b * z, axis=0)


def _fast_score(groups: list[np.ndarray], fs: float, h: int, t0: float) -> Score:
    """The total RSS of unit-RMS ``groups`` on a leading segment, less a constant (the
    segment's power): ranks the points of a grid as :func:`_total_rss` does."""
    def score(n_seg: int, f: float) -> float:
        total = 0.0
        for g in groups:
            part = g[:, :n_seg]
            total -= float(np.sum(_explained_power(part, np.zeros(len(part)), fs, f, h, t0)))
        return total
    return score


class _LongRecords:
    """Records of a long run by length, with the sums the chunked objective needs."""

    def __init__(self, records: list[np.ndarray], fs: float, h: int, t0: float) -> None:
        self.fs, self.h, self.t0 = fs, h, t0
        stats = np.array([_centred(rec, i) for i, rec in enumerate(records)])
        self.records = records
        self.means, self.power = stats[:, 0], stats[:, 1]
        self.lengths = np.array([rec.size for rec in records])
        self.by_length = [np.flatnonzero(self.lengths == n) for n in np.unique(self.lengths)]
        self._segments: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def rss(self, f: float, n_seg: int | None = None) -> np.ndarray:
        """(n_records,) residual sum of squares of every record at ``f`` [Hz], on its leading
        ``n_seg`` samples when given."""
        out = np.empty(len(self.records))
        for idx in self.by_length:
            part = [self.records[i][:n_seg] for i in idx]
            means, power = self._stats(idx, n_seg)
            out[idx] = power - _explained_power(part, means, self.fs, f, self.h, self.t0)
        return out

    def _stats(self, idx: np.ndarray, n_seg: int | None) -> tuple[np.ndarray, np.ndarray]:
        """Means and powers about them of records ``idx`` (of one length), on their leading
        ``n_seg`` samples when given."""
        if n_seg is None or n_seg >= self.lengths[idx[0]]:
            return self.means[idx], self.power[idx]
        key = (n_seg, int(idx[0]))
        if key not in self._segments:
            stats = np.array([_centred(self.records[i][:n_seg], int(i)) for i in idx])
            self._segments[key] = (stats[:, 0], stats[:, 1])
        return self._segments[key]

    def score(self, weights: np.ndarray, n_seg: int | None = None) -> Callable[[float], float]:
        """f -> sum of the records' RSS times ``weights``."""
        return lambda f: float(weights @ self.rss(f, n_seg))

    def terms(self, weights: np.ndarray,
              n_seg: int | None = None) -> Callable[[float], tuple[float, float]]:
        """f -> (sum w r . d, sum w ||P d||^2) of the records (:func:`_fit_terms_long`), on
        their leading ``n_seg`` samples when given."""
        def at(f: float) -> tuple[float, float]:
            rd, energy = 0.0, 0.0
            for idx in self.by_length:
                part = [self.records[i][:n_seg] for i in idx]
                got = _fit_terms_long(part, self.fs, f, self.h, self.t0)
                rd += float(weights[idx] @ got[0])
                energy += float(weights[idx] @ got[1])
            return rd, energy
        return at


# ------------------------------------------------------------------ searches


def _descend(evaluate: Callable[[int, np.ndarray], tuple[int, float]], n_start: int,
             n_end: int, fs: float, h: int, bounds: tuple[float, float],
             start: tuple[float, float]) -> _GridMinimum:
    """Bracket the minimum of an objective over ``start`` [Hz], coarse to fine.

    The grid is spaced a quarter of the narrowest valley of the objective, 1 / (2 H T) for a
    segment of duration T. The full grid runs on the leading ``n_start`` samples, then the
    segment is doubled up to ``n_end`` with the bracket narrowed each time (within
    ``bounds``), so the work grows like the record length, not like its square.
    ``evaluate(n_seg, grid)`` returns the index of the grid's least value and that value.
    """
    n_seg = n_start
    lo_f, hi_f = start
    while True:
        spacing = 1.0 / (2.0 * h * n_seg / fs)
        n_grid = max(math.ceil((hi_f - lo_f) / spacing) + 1, 5)
        grid = np.linspace(lo_f, hi_f, n_grid)
        i_best, value = evaluate(n_seg, grid)
        lo = float(grid[max(i_best - 1, 0)])
        hi = float(grid[min(i_best + 1, n_grid - 1)])
        if n_seg >= n_end:
            return _GridMinimum(float(grid[i_best]), value, lo, hi, spacing)
        n_seg = min(2 * n_seg, n_end)
        lo_f, hi_f = max(lo - spacing, bounds[0]), min(hi + spacing, bounds[1])


def _every_point(score: Score) -> Callable[[int, np.ndarray], tuple[int, float]]:
    """Grid evaluation by ``score`` at every point."""
    def evaluate(n_seg: int, grid: np.ndarray) -> tuple[int, float]:
        values = np.array([score(n_seg, f) for f in grid])
        i = int(np.argmin(values))
        return i, float(values[i])
    return evaluate


def _grid_search(groups: list[np.ndarray], fs: float, f0_nominal: float, h: int,
                 t0: float, f_lo: float, f_hi: float) -> _GridMinimum:
    """Bracket the minimum of the total RSS (QR fits) over [f_lo, f_hi] [Hz], coarse to fine
    (:func:`_descend` from a leading segment of :data:`_SEGMENT_PERIODS` periods).

    A grid of more than :data:`_WHOLE_GRID` points is localized first with chunked sums on
    shorter segments; only its points near the minimum are fitted on the whole segment,
    and more of them while the least lies at the edge of those fitted.
    """
    n_full = max(g.shape[1] for g in groups)
    n_seg = min(n_full, int(_SEGMENT_PERIODS * fs / f0_nominal))
    fast = _fast_score(groups, fs, h, t0)

    def evaluate(n_seg: int, grid: np.ndarray) -> tuple[int, float]:
        part = [g[:, :n_seg] for g in groups]
        values = {}

        def value(i: int) -> float:
            if i not in values:
                values[i] = _total_rss(part, fs, float(grid[i]), h, t0)
            return values[i]

        if grid.size <= _WHOLE_GRID:
            first, last = 0, grid.size - 1
        else:
            n_coarse = _coarse_start(n_seg, grid[-1] - grid[0], fs, h, 8 * fs / f_lo)
            near = _descend(_every_point(fast), n_coarse, n_seg // 2, fs, h,
                            (grid[0], grid[-1]), (grid[0], grid[-1]))
            margin = 1.0 / (2.0 * h * (n_seg // 2) / fs)      # as between two levels
            first = max(int(np.searchsorted(grid, near.lo - margin)) - 1, 0)
            last = min(int(np.searchsorted(grid, near.hi + margin)), grid.size - 1)
        for i in range(first, last + 1):
            value(i)
        while True:
            i_best = min(values, key=values.__getitem__)
            if i_best == first and first > 0:
                first -= 1
                value(first)
            elif i_best == last and last < grid.size - 1:
                last += 1
                value(last)
            else:
                return i_best, values[i_best]

    return _descend(evaluate, n_seg, n_full, fs, h, (f_lo, f_hi), (f_lo, f_hi))


def _coarse_start(n_seg: int, width: float, fs: float, h: int, shortest: float) -> int:
    """The leading segment [samples] whose grid over ``width`` [Hz] has at most
    :data:`_WHOLE_GRID` points, halving ``n_seg`` (to no fewer than ``shortest`` samples,
    nor 4 (2H+1))."""
    n = n_seg // 2
    while n // 2 >= max(shortest, 4 * (2 * h + 1)) and width * 2.0 * h * n / fs + 1 > _WHOLE_GRID:
        n //= 2
    return max(n, 1)


def _scoring_minimum(terms: Callable[[float], tuple[float, float]], start: float,
                     bounds: tuple[float, float], xatol: float) -> float:
    """The fundamental [Hz] at the least residual sum of squares within ``bounds``, by scoring
    steps from ``start``: f += (r . d) / ||P d||^2 (Gauss-Newton on the variable-projection
    residual; ``terms(f)`` gives both sums, :func:`_fit_terms`) until a step is below ``xatol``
    [Hz]."""
    f = start
    for _ in range(_MAX_STEPS):
        rd, energy = terms(f)
        step = rd / energy if energy > 0.0 else math.nan
        if not math.isfinite(step):     # flat (or not a number): nothing to step on
            break
        f_next = min(max(f + step, bounds[0]), bounds[1])
        done = abs(f_next - f) <= xatol
        f = f_next
        if done:
            break
    return f


def _group_terms(groups: list[np.ndarray], fs: float, h: int,
                 t0: float) -> Callable[[float], tuple[float, float]]:
    """f -> (sum r . d, sum ||P d||^2) over every record of ``groups`` (QR fits)."""
    def terms(f: float) -> tuple[float, float]:
        parts = [_fit_terms(g, fs, f, h, t0)[:2] for g in groups]
        return (float(sum(rd.sum() for rd, _ in parts)),
                float(sum(energy.sum() for _, energy in parts)))
    return terms


def _rates(coef: np.ndarray) -> np.ndarray:
    """(..., 2H+1) the coefficients gamma of the series g = (dx/dt) / f0, harmonic n's phasor
    X_n times j 2 pi n: d = dx/df0 = t g, g = X gamma."""
    h = (coef.shape[-1] - 1) // 2
    z = (coef[..., 1::2] + 1j * coef[..., 2::2]) * (1j * 2.0 * np.pi * np.arange(1, h + 1))
    gamma = np.zeros_like(coef)
    gamma[..., 1::2], gamma[..., 2::2] = z.real, z.imag
    return gamma


def _fit_terms(g: np.ndarray, fs: float, f0: float, h: int,
               t0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(r . d, ||P d||^2, r . r), each (m,), of records ``g`` (m, n) fitted at ``f0`` by QR:
    r the residual, d = dx/df0 the fitted series' derivative, P the projection off the design
    matrix's span (the phasors are nuisance parameters). With t' = t - t_mid, P d = P (t' g)
    and r . d = r . (t' g), g being in the span."""
    t = t0 + np.arange(g.shape[1]) / fs
    fit = qr_fit(g.T, t, f0, h)
    a = design_matrix(t, f0, h)
    d = (t - t[t.size // 2])[:, None] * (a @ _rates(fit.coef.T).T)      # (n, m)
    q, _ = np.linalg.qr(a)
    d_perp = d - q @ (q.T @ d)
    return (np.einsum("nm,nm->m", fit.residuals, d), np.einsum("nm,nm->m", d_perp, d_perp),
            np.einsum("nm,nm->m", fit.residuals, fit.residuals))


def _fit_terms_long(recs: list[np.ndarray], fs: float, f0: float, h: int,
                    t0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fit_terms` of long records of one length from chunked sums.

    With g = X gamma, ||P d||^2 = gamma^T M2 gamma - (M1 gamma)^T (X^T X)^-1 (M1 gamma) and
    r . d = gamma^T (sum_k t'_k x_k y_k) - gamma^T M1 c, with M_q = sum_k t'_k^q x_k x_k^T:
    small matrices and one pass over the samples beside the fit's.
    """
    n = len(recs[0])
    fit = fit_chunked(recs, fs, f0, h, t0)
    gamma = _rates(fit.coef)                                          # (m, p)
    basis = GridBasis(n, fs, t0, f0, h)
    t_ref = t0 + 0.5 * (n - 1) / fs
    _, m1, m2 = basis.moment_grams(t_ref, 2)
    moments = np.stack([basis.project(y, t_ref) for y in recs])       # sum t' x y
    xtd = gamma @ m1                                                  # M1 symmetric
    rd = np.einsum("mp,mp->m", gamma, moments) - np.einsum("mp,mp->m", xtd, fit.coef)
    energy = (np.einsum("mp,pq,mq->m", gamma, m2, gamma)
              - np.einsum("mp,pq,mq->m", xtd, fit.covariance, xtd))
    return rd, np.maximum(energy, 0.0), fit.rss


def _noise_weighted(groups: list[np.ndarray], n_records: int, fs: float, f_best: float,
                    n_harmonics: int, t0: float, spacing: float, xatol: float) -> float:
    """The fundamental [Hz] refined within +-``spacing`` of ``f_best`` with every record
    weighted by its own noise (maximum likelihood for white noise), so that a faint, noisy
    record (a probe near a node) does not pull as hard as a clean one. One record, or
    noise-free records, keep ``f_best``."""
    noise = []
    for g in groups:
        t = t0 + np.arange(g.shape[-1]) / fs
        noise.append(qr_fit(g.reshape(-1, g.shape[-1]).T, t, f_best, n_harmonics).sigma)
    floor = 1e-9                    # scaled records have unit RMS: below this, noise-free
    if n_records > 1 and all(np.all(s > floor) for s in noise):
        weighted = [g / s[:, None] for g, s in zip(groups, noise, strict=True)]
        f_best = _scoring_minimum(_group_terms(weighted, fs, n_harmonics, t0), f_best,
                                  (f_best - spacing, f_best + spacing), xatol)
    return f_best


def _refine_long(recs: list[np.ndarray], fs: float, f0_nominal: float, h: int, t0: float,
                 bounds: tuple[float, float], limits: tuple[float, float]) -> float:
    """:func:`refine_fundamental` of records longer than :data:`LONG_RECORD`: refined on the
    leading :data:`LONG_RECORD` samples, checked on a grid over the whole record (searched
    further, then by doubling segments, when the minimum is elsewhere), refined there, then
    weighted by each record's noise; chunked sums throughout, the records never copied."""
    search, min_explained = limits
    long = _LongRecords(recs, fs, h, t0)
    unit = long.lengths / long.power                    # 1 / mean square of every record
    xatol = 1e-10 * f0_nominal
    n_full, n_sub = int(long.lengths.max()), LONG_RECORD

    def score(n_seg: int, f: float) -> float:
        return long.score(unit, n_seg)(f)

    n_start = min(n_sub, int(_SEGMENT_PERIODS * fs / f0_nominal))
    sub = _descend(_every_point(score), n_start, n_sub, fs, h, bounds, bounds)
    f_sub = _scoring_minimum(long.terms(unit, n_sub), sub.f, (sub.lo, sub.hi), xatol)
    whole = long.score(unit)
    best = _check_whole(whole, f_sub, 1.0 / (2.0 * h * n_full / fs), bounds)
    if best is None:                # not where the subset said: search by doubling segments
        best = _descend(_every_point(score), n_sub, n_full, fs, h, bounds,
                        (max(sub.lo - sub.spacing, bounds[0]),
                         min(sub.hi + sub.spacing, bounds[1])))
    f_best = _scoring_minimum(long.terms(unit), best.f, (best.lo, best.hi), xatol)
    rss_best = whole(f_best)
    if best.rss < rss_best:
        f_best, rss_best = best.f, best.rss
    _check_explained(1.0 - rss_best / float(long.lengths.sum()), f_best, f0_nominal, search,
                     min_explained)
    if len(recs) == 1:
        return f_best
    sigma2 = np.empty(len(recs))
    for idx in long.by_length:
        fit = fit_chunked([recs[i] for i in idx], fs, f_best, h, t0)
        sigma2[idx] = fit.rss / (long.lengths[idx] - (2 * h + 1))
    if np.all(sigma2 * unit > 1e-18):               # noise-free below 1e-9 of the RMS
        f_best = _scoring_minimum(long.terms(1.0 / sigma2), f_best,
                                  (f_best - best.spacing, f_best + best.spacing), xatol)
    return f_best


def _check_whole(objective: Callable[[float], float], f_sub: float, spacing: float,
                 bounds: tuple[float, float]) -> _GridMinimum | None:
    """The least of a grid of step ``spacing`` [Hz] about ``f_sub`` on the whole record,
    extended while the least lies at its edge (at most :data:`_CHECK_STEPS` steps); None when
    the minimum is not within reach."""
    values = {}

    def at(k: int) -> float:
        return min(max(f_sub + k * spacing, bounds[0]), bounds[1])

    def value(k: int) -> float:
        if k not in values:
            values[k] = objective(at(k))
        return values[k]

    for k in (-1, 0, 1):
        value(k)
    while True:
        k = min(values, key=values.__getitem__)
        edge = min(values) if k == min(values) else max(values) if k == max(values) else None
        if edge is None:
            return _GridMinimum(at(k), values[k], at(k - 1), at(k + 1), spacing)
        if abs(edge) >= _CHECK_STEPS:
            return None
        value(edge - 1 if edge < 0 else edge + 1)


# ------------------------------------------------------------------ uncertainty


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
        Complex, non-finite or empty records (see :func:`forcecal.signals.checks.as_records`).
    """
    recs = as_records(records)
    info = 0.0
    for rec in recs:
        checked_samples(rec, fs, f0, n_harmonics)
        energy, sigma2 = (_information_long if rec.size > LONG_RECORD else _information)(
            rec, fs, f0, n_harmonics, t0)
        if sigma2 == 0.0:
            if energy > 0.0:
                return 0.0
            continue
        info += energy / sigma2
    return math.inf if info == 0.0 else 1.0 / math.sqrt(info)


def _information(rec: np.ndarray, fs: float, f0: float, h: int,
                 t0: float) -> tuple[float, float]:
    """(||P d||^2, sigma^2) of one record, from QR fits of the whole record."""
    _, energy, rss = _fit_terms(rec.reshape(1, -1), fs, f0, h, t0)
    return float(energy[0]), float(rss[0]) / (rec.size - (2 * h + 1))


def _information_long(rec: np.ndarray, fs: float, f0: float, h: int,
                      t0: float) -> tuple[float, float]:
    """(||P d||^2, sigma^2) of one long record from chunked sums."""
    _, energy, rss = _fit_terms_long([rec], fs, f0, h, t0)
    return float(energy[0]), float(rss[0]) / (rec.size - (2 * h + 1))
