"""Least-squares sums of a Fourier series over a uniform time grid, chunk by chunk.

The design matrix of :func:`design_matrix` over samples t_k = t0 + k / fs is never built whole.
The grid is cut into chunks of ``chunk`` samples; chunk i starts at T_i = t0 + i chunk / fs,
and its rows are those of the first chunk rotated: harmonic n of chunk i is harmonic n of
chunk 0 turned by the phase 2 pi n f0 T_i. So X^T y (:meth:`GridBasis.project`) and the
fitted series (:meth:`GridBasis.evaluate`) need the chunk-0 design matrix (``chunk`` x (2H+1))
and one phase per chunk and harmonic; the records themselves are read as (n_chunks, chunk)
views, one matrix product per record, with no copy. X^T X and its time moments
(:meth:`GridBasis.moment_grams`) follow from the sums of exp(j k w0 t), k = 0 .. 2H, over the
grid, themselves sums over chunk 0 turned chunk by chunk. Memory stays that of a few chunks
whatever the length of the record, and the time is one pass over the data.

:func:`fit_chunked` solves the normal equations (scaled Cholesky), then makes a second pass
over the data for the residuals: their sum of squares (no cancellation between y^T y and
b^T x) and one step of iterative refinement of the coefficients, so that the phasors agree
with a QR factorization of the whole design matrix to rounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve, solve_triangular

from ..errors import ConditioningError, DataError, DimensionError

__all__ = ["grid_series", "series_at"]

CHUNK = 4096
"""Samples per chunk of the sums [samples]."""
_BLOCK = 64
"""Chunks per block of the residual pass and of the evaluation (bounds the temporaries)."""
_TIMES = 1 << 16
"""Time stamps per block of :func:`series_at`."""
MAX_CONDITION = 1e10
"""Largest condition number of the design matrix accepted by a fit."""


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
    # the fundamental's phase in cycles, reduced modulo 1 before scaling by 2 pi; the
    # harmonics as its powers, at a fifth of the time of their own cosines and sines and no
    # less accurate (their phases n f0 t round as the powers' products do)
    z = np.exp(2j * np.pi * np.mod(t * f0, 1.0))
    powers = np.empty((t.size, n_harmonics), dtype=complex)
    if n_harmonics:
        powers[:, 0] = z
        for k in range(1, n_harmonics):
            np.multiply(powers[:, k - 1], z, out=powers[:, k])
    a = np.empty((t.size, 2 * n_harmonics + 1))
    a[:, 0] = 1.0
    a[:, 1::2] = powers.real
    a[:, 2::2] = -powers.imag
    return a


def check_nyquist(f0: float, n_harmonics: int, fs: float) -> None:
    """DataError when harmonic ``n_harmonics`` of ``f0`` [Hz] is not below fs / 2."""
    if n_harmonics * f0 >= 0.5 * fs:
        raise DataError(
            f"harmonic {n_harmonics} of {f0:.6g} Hz is at {n_harmonics * f0:.6g} Hz, not below "
            f"the Nyquist frequency {0.5 * fs:.6g} Hz of fs = {fs:.6g} Hz; reduce n_harmonics"
        )


def checked_samples(x: np.ndarray, fs: float, f0: float, n_harmonics: int) -> np.ndarray:
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
    bad = 0
    for s in range(0, n_samples, _TIMES):                  # a bounded temporary
        bad += int(np.count_nonzero(~np.isfinite(x[..., s:s + _TIMES])))
    if bad:
        raise DataError(f"x contains {bad} non-finite samples")
    check_nyquist(f0, n_harmonics, fs)
    return x


class QRFit(NamedTuple):
    """Least-squares fit of records (columns) by one QR factorization of the design matrix."""

    coef: np.ndarray        # (2H+1, m) [c_0, Re X_1, Im X_1, ...] of every record
    residuals: np.ndarray   # (n, m)
    sigma: np.ndarray       # (m,) unbiased residual standard deviation
    r: np.ndarray           # (2H+1, 2H+1) the triangular factor

    @property
    def phasors(self) -> np.ndarray:
        """(H+1, m) complex X_0 .. X_H of every record."""
        out = np.empty(((self.coef.shape[0] + 1) // 2, self.coef.shape[1]), dtype=complex)
        out[0] = self.coef[0]
        out[1:] = self.coef[1::2] + 1j * self.coef[2::2]
        return out


WELL_CONDITIONED = 1e6
"""Largest condition number of a design matrix's column-scaled Gram matrix solved by its
normal equations (:func:`normal_fit`); a worse one is fitted by QR."""


def normal_fit(a: np.ndarray, y: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Least-squares fit of the columns of ``y`` (n, m) on those of ``a`` (n, p) by the
    normal equations (the column-scaled Gram matrix's Cholesky factor) and one step of
    iterative refinement, as :func:`fit_chunked` does: the coefficients agree with QR's to
    rounding at a quarter of its time, and the residual is formed explicitly.

    Returns
    -------
    (coef (p, m), residuals (n, m), r (p, p) upper triangular with r^T r = a^T a), or None
    where the scaled Gram matrix is not positive definite or its condition number exceeds
    :data:`WELL_CONDITIONED` (a record of few periods: fit it by QR).
    """
    gram = a.T @ a
    scale = np.sqrt(np.diag(gram))
    if not np.all(scale > 0):
        return None
    unit = gram / np.outer(scale, scale)
    try:
        lower = np.linalg.cholesky(unit)
    except np.linalg.LinAlgError:
        return None
    if np.linalg.cond(unit) > WELL_CONDITIONED:
        return None

    def solve(b: np.ndarray) -> np.ndarray:
        return cho_solve((lower, True), b / scale[:, None]) / scale[:, None]

    coef = solve(a.T @ y)
    resid = y - a @ coef
    coef += solve(a.T @ resid)
    return coef, y - a @ coef, lower.T * scale[None, :]


def _qr(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q, r = np.linalg.qr(a)
    d = np.abs(np.diag(r))
    if d.min() <= d.max() / MAX_CONDITION:
        raise ConditioningError(
            f"the harmonic design matrix ({a.shape[0]} samples, {a.shape[1]} columns) is "
            "numerically rank deficient: the record is too short for the harmonics requested"
        )
    return q, r


def qr_fit(xt: np.ndarray, t: np.ndarray, f0: float, n_harmonics: int) -> QRFit:
    """Fit records by one QR factorization of their whole design matrix.

    Parameters
    ----------
    xt : (n, m) array [any unit]
        Records as columns.
    t : (n,) array [s]
        Their sample times.
    f0 : float [Hz]
        Fundamental.
    n_harmonics : int
        H.

    Returns
    -------
    QRFit

    Raises
    ------
    ConditioningError
        The design matrix is numerically rank deficient.
    """
    a = design_matrix(t, f0, n_harmonics)
    got = normal_fit(a, xt)
    if got is None:
        q, r = _qr(a)
        qtx = q.T @ xt  # (2H+1, M)
        coef = solve_triangular(r, qtx)  # (2H+1, M)
        resid = xt - q @ qtx
    else:
        coef, resid, r = got
    dof = xt.shape[0] - (2 * n_harmonics + 1)
    sigma = np.sqrt(np.sum(resid**2, axis=0) / dof)
    return QRFit(coef, resid, sigma, r)


def _pairs(v: np.ndarray) -> np.ndarray:
    """(..., 2H+1) coefficients [c_0, Re X_1, Im X_1, ...] -> (..., H) complex X_1 .. X_H."""
    return v[..., 1::2] + 1j * v[..., 2::2]


def _unpair(dc: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The inverse of :func:`_pairs`: (...,) and (..., H) complex -> (..., 2H+1) real."""
    out = np.empty((*z.shape[:-1], 2 * z.shape[-1] + 1))
    out[..., 0] = dc
    out[..., 1::2] = z.real
    out[..., 2::2] = z.imag
    return out


class GridBasis:
    """The design matrix of ``n`` samples t0 + k / fs at one fundamental, by chunks.

    Chunk i (the last one possibly partial) starts at T_i = t0 + i c / fs; its rows are the
    first rows of chunk 0 with harmonic n turned by exp(j n 2 pi f0 T_i). Sums of the design
    matrix's products (X^T X and its time moments) follow from the sums
    S_q(k) = sum_t (t - t_ref)^q exp(j k w0 t), k = 0 .. 2H.

    Parameters
    ----------
    n : int
        Samples in the record.
    fs : float [Hz]
        Sampling rate.
    t0 : float [s]
        Time of the first sample.
    f0 : float [Hz]
        Fundamental frequency.
    n_harmonics : int
        H.
    chunk : int
        Samples per chunk.
    """

    def __init__(self, n: int, fs: float, t0: float, f0: float, n_harmonics: int,
                 chunk: int = CHUNK) -> None:
        if chunk < 1 or n < 1:
            raise DimensionError(f"chunk ({chunk}) and n ({n}) must be positive sample counts")
        self.n, self.fs, self.t0, self.f0, self.h = n, fs, t0, f0, n_harmonics
        self.chunk = c = min(chunk, n)
        self.n_chunks, self.tail = divmod(n, c)
        self.tail_start = self.n_chunks * c
        # exp(j k w0 tau) for tau = 0 .. c-1 samples, k = 0 .. 2H (powers of k = 1)
        self.local = _powers(np.exp(2j * np.pi * np.mod(np.arange(c) * (f0 / fs), 1.0)),
                             2 * n_harmonics)
        self.x0 = _unpair(np.ones(c), self.local[:, 1:n_harmonics + 1].conj()).real
        # ... and exp(j k w0 T_i) for every chunk start, the partial last chunk included
        starts = t0 + np.arange(self.n_chunks + (self.tail > 0)) * (c / fs)
        self.starts = starts
        self.turns = _powers(np.exp(2j * np.pi * np.mod(starts * f0, 1.0)), 2 * n_harmonics)

    @property
    def n_columns(self) -> int:
        """2H + 1."""
        return 2 * self.h + 1

    def _unturn(self, part: np.ndarray, k: int | slice) -> np.ndarray:
        """sum_i R_i^T part_i: projections on chunk 0's rows (..., p) of chunks ``k`` back
        to the whole record's design matrix (summed over those chunks)."""
        turns = self.turns[k, 1:self.h + 1].conj()
        if part.ndim == 1:
            return _unpair(part[0], _pairs(part) * turns)
        return _unpair(part[..., 0].sum(axis=-1), np.sum(_pairs(part) * turns, axis=-2))

    def _turned(self, coef: np.ndarray) -> np.ndarray:
        """(n_starts, 2H+1) the coefficients ``coef`` (2H+1,) as chunk 0 sees chunk i."""
        z = _pairs(coef) * self.turns[:, 1:self.h + 1]
        return _unpair(np.full(len(self.turns), coef[0]), z)

    def moment_grams(self, t_ref: float, order: int = 0) -> list[np.ndarray]:
        """sum_k (t_k - t_ref)^q x_k x_k^T for q = 0 .. ``order`` (at most 2) [s^q].

        x_k is row k of the design matrix; q = 0 is X^T X.
        """
        tau = np.arange(self.chunk) / self.fs
        shift = self.starts - t_ref
        weights = [np.ones_like(tau), tau, tau**2][:order + 1]
        full = [w @ self.local for w in weights]                    # (2H+1,) over a chunk
        part = [w[:self.tail] @ self.local[:self.tail] for w in weights]
        binom = ((1.0,), (1.0, 1.0), (1.0, 2.0, 1.0))
        out = []
        for q in range(order + 1):
            # (shift + tau)^q = sum_r binom(q, r) shift^(q-r) tau^r
            sums = np.zeros(2 * self.h + 1, dtype=complex)
            for r in range(q + 1):
                w = binom[q][r] * shift ** (q - r)
                if self.n_chunks:
                    sums += (w[:self.n_chunks] @ self.turns[:self.n_chunks]) * full[r]
                if self.tail:
                    sums += w[-1] * self.turns[-1] * part[r]
            out.append(_gram_from_sums(sums, self.h))
        return out

    def gram(self) -> np.ndarray:
        """(2H+1, 2H+1) X^T X [1]."""
        return self.moment_grams(0.0, 0)[0]

    def project(self, y: np.ndarray, t_ref: float | None = None) -> np.ndarray:
        """(..., 2H+1) X^T y of records ``y`` (..., n) [unit of y]; with ``t_ref`` [s], the
        first moment sum_k (t_k - t_ref) x_k y_k [s unit of y]."""
        b = np.zeros((*y.shape[:-1], self.n_columns))
        x0 = self.x0
        if t_ref is not None:               # chunk i: t - t_ref = (T_i - t_ref) + tau
            shift = self.starts - t_ref
            x1 = (np.arange(self.chunk) / self.fs)[:, None] * x0
        if self.n_chunks:
            full = y[..., :self.tail_start].reshape(*y.shape[:-1], self.n_chunks, self.chunk)
            part = full @ x0
            if t_ref is not None:
                part = part * shift[:self.n_chunks, None] + full @ x1
            b += self._unturn(part, slice(0, self.n_chunks))
        if self.tail:
            tail = y[..., self.tail_start:]
            part = tail @ x0[:self.tail]
            if t_ref is not None:
                part = part * shift[-1] + tail @ x1[:self.tail]
            b += self._unturn(part, -1)
        return b

    def residual_sums(self, y: np.ndarray, coef: np.ndarray) -> tuple[float, np.ndarray]:
        """(sum r^2, X^T r) of the residual r = y - X coef of one record [unit of y ^2, y]."""
        turned = self._turned(coef)
        rss, xtr = 0.0, np.zeros(self.n_columns)
        if self.tail:
            r_tail = y[self.tail_start:] - self.x0[:self.tail] @ turned[-1]
            rss += float(r_tail @ r_tail)
            xtr += self._unturn(r_tail @ self.x0[:self.tail], -1)
        if self.n_chunks:
            chunks = y[:self.tail_start].reshape(self.n_chunks, self.chunk)
            part = np.empty((self.n_chunks, self.n_columns))
            buf = np.empty((min(_BLOCK, self.n_chunks), self.chunk))
            for s in range(0, self.n_chunks, _BLOCK):
                blk = slice(s, min(s + _BLOCK, self.n_chunks))
                r = buf[:blk.stop - s]
                np.matmul(turned[blk], self.x0.T, out=r)
                np.subtract(chunks[blk], r, out=r)
                rss += float(np.einsum("ij,ij->", r, r))
                part[blk] = r @ self.x0
            xtr += self._unturn(part, slice(0, self.n_chunks))
        return rss, xtr

    def evaluate(self, coef: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Write X coef, coefficients ``coef`` (2H+1,), into ``out`` (n,) and return it."""
        turned = self._turned(coef)
        if self.tail:
            out[self.tail_start:] = self.x0[:self.tail] @ turned[-1]
        if self.n_chunks:
            chunks = out[:self.tail_start].reshape(self.n_chunks, self.chunk)
            for s in range(0, self.n_chunks, _BLOCK):
                blk = slice(s, min(s + _BLOCK, self.n_chunks))
                np.matmul(turned[blk], self.x0.T, out=chunks[blk])
        return out


def _powers(z: np.ndarray, k_max: int) -> np.ndarray:
    """(len(z), k_max + 1) z^0 .. z^k_max by repeated products."""
    out = np.empty((z.size, k_max + 1), dtype=complex)
    out[:, 0] = 1.0
    for k in range(1, k_max + 1):
        out[:, k] = out[:, k - 1] * z if k > 1 else z
    return out


def _gram_from_sums(sums: np.ndarray, h: int) -> np.ndarray:
    """(2H+1, 2H+1) sum_t w_t x_t x_t^T from S(k) = sum_t w_t exp(j k w0 t), k = 0 .. 2H.

    cos a cos b = (cos(a-b) + cos(a+b)) / 2, sin a sin b = (cos(a-b) - cos(a+b)) / 2 and
    cos a (-sin b) = -(sin(b+a) + sin(b-a)) / 2, with the design matrix's columns
    [1, cos w0 t, -sin w0 t, cos 2 w0 t, ...].
    """
    n = np.arange(1, h + 1)
    full = np.concatenate([sums[:0:-1].conj(), sums])        # S(k) for k = -2H .. 2H
    at = lambda k: full[k + 2 * h]                           # noqa: E731
    g = np.empty((2 * h + 1, 2 * h + 1))
    g[0, 0] = sums[0].real
    g[0, 1::2] = g[1::2, 0] = sums[n].real
    g[0, 2::2] = g[2::2, 0] = -sums[n].imag
    dif, tot = at(np.subtract.outer(n, n)), at(np.add.outer(n, n))
    g[1::2, 1::2] = 0.5 * (dif.real + tot.real)
    g[2::2, 2::2] = 0.5 * (dif.real - tot.real)
    cross = -0.5 * (tot.imag - dif.imag)          # [n, m]: cos(n w0 t) (-sin(m w0 t))
    g[1::2, 2::2] = cross
    g[2::2, 1::2] = cross.T
    return g


class ChunkedFit(NamedTuple):
    """Least-squares coefficients of several records at one fundamental."""

    coef: np.ndarray        # (m, 2H+1) [c_0, Re X_1, Im X_1, ...] of every record
    rss: np.ndarray         # (m,) residual sum of squares of every record
    covariance: np.ndarray  # (2H+1, 2H+1) (X^T X)^-1


def _factor(gram: np.ndarray, n: int) -> tuple[tuple[np.ndarray, bool], np.ndarray]:
    """Cholesky factor of the column-scaled Gram matrix, and the column scales.

    ConditioningError when the design matrix (``n`` samples) is numerically rank deficient:
    the diagonal of its triangular factor spans more than ``MAX_CONDITION``, as for a QR
    factorization of the whole matrix.
    """
    p = gram.shape[0]
    scale = np.sqrt(np.diag(gram))
    message = (f"the harmonic design matrix ({n} samples, {p} columns) is numerically rank "
               "deficient: the record is too short for the harmonics requested")
    if not np.all(scale > 0):
        raise ConditioningError(message)
    try:
        factor = cho_factor(gram / np.outer(scale, scale), lower=True)
    except LinAlgError:
        raise ConditioningError(message) from None
    d = np.abs(np.diag(factor[0])) * scale
    if d.min() <= d.max() / MAX_CONDITION:
        raise ConditioningError(message)
    return factor, scale


def _solve(factor: tuple[np.ndarray, bool], scale: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(X^T X)^-1 b for b (2H+1, ...) from the scaled factor."""
    s = scale.reshape(-1, *([1] * (b.ndim - 1)))
    out: np.ndarray = cho_solve(factor, b / s) / s
    return out


def fit_chunked(records: Sequence[np.ndarray] | np.ndarray, fs: float, f0: float,
                n_harmonics: int, t0: float = 0.0, chunk: int = CHUNK) -> ChunkedFit:
    """Least-squares Fourier coefficients of records sharing one uniform time grid.

    Parameters
    ----------
    records : (m, n) array or sequence of m (n,) arrays [any unit]
        Finite records, all of n samples at t0 + k / fs.
    fs : float [Hz]
        Sampling rate.
    f0 : float [Hz]
        Fundamental frequency.
    n_harmonics : int
        H.
    t0 : float [s]
        Time of the first sample.
    chunk : int
        Samples per chunk.

    Returns
    -------
    ChunkedFit

    Raises
    ------
    ConditioningError
        The design matrix is numerically rank deficient.
    """
    n = len(records[0])
    basis = GridBasis(n, fs, t0, f0, n_harmonics, chunk)
    factor, scale = _factor(basis.gram(), n)
    coef = _solve(factor, scale, np.stack([basis.project(y) for y in records], axis=1)).T
    rss = np.empty(len(records))
    for j, y in enumerate(records):
        rss[j], xtr = basis.residual_sums(y, coef[j])
        step = _solve(factor, scale, xtr)            # one step of iterative refinement
        coef[j] += step
        rss[j] = max(rss[j] - float(step @ xtr), 0.0)
    cov = _solve(factor, scale, np.eye(basis.n_columns))
    return ChunkedFit(coef, rss, 0.5 * (cov + cov.T))


def grid_series(phasors: np.ndarray, f0: float, fs: float, t0: float, n: int,
                chunk: int = CHUNK) -> np.ndarray:
    """Fourier series of phasors on the grid t0 + k / fs, k = 0 .. n-1.

    Parameters
    ----------
    phasors : (..., H+1) complex array
        X_0 .. X_H (X_0 real; its imaginary part is ignored).
    f0, fs : float [Hz]
        Fundamental and sampling rate.
    t0 : float [s]
        Time of the first sample.
    n : int
        Samples.
    chunk : int
        Samples per chunk.

    Returns
    -------
    (..., n) array
        X_0 + sum_n Re(X_n exp(j n w0 t)).
    """
    phasors = np.asarray(phasors)
    lead = phasors.shape[:-1]
    rows = phasors.reshape(-1, phasors.shape[-1])
    basis = GridBasis(n, fs, t0, f0, rows.shape[1] - 1, chunk)
    out = np.empty((rows.shape[0], n))
    for j, x in enumerate(rows):
        basis.evaluate(_unpair(np.real(x[0]), x[1:]), out[j])
    return out.reshape(*lead, n)


def square_phasors(phasors: np.ndarray) -> np.ndarray:
    """The harmonics 0..H of x(t)^2 from those of x(t) (:func:`grid_series`'s convention), the
    products above H left out: exact, from the square on a grid of 4 (H+1) points a period.

    Parameters
    ----------
    phasors : (H+1,) complex array

    Returns
    -------
    (H+1,) complex array
    """
    h = len(phasors) - 1
    n_t = 4 * (h + 1)
    series = grid_series(np.asarray(phasors), 1.0, float(n_t), 0.0, n_t)
    spectrum = np.fft.fft(series**2) / n_t
    return np.concatenate([[spectrum[0].real], 2 * spectrum[1:h + 1]])


def series_at(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """Fourier series of phasors at any times, a block of times at a time.

    A block of uniformly spaced times (to rounding) is evaluated as a grid
    (:class:`GridBasis`), any other block from the exponentials of its phases.

    Parameters
    ----------
    phasors : (..., H+1) complex array
        X_0 .. X_H.
    f0 : float [Hz]
        Fundamental.
    t : (n_t,) array [s]
        Absolute times.

    Returns
    -------
    (..., n_t) array
        X_0 + sum_n Re(X_n exp(j n w0 t)), the phase reduced modulo one cycle as in
        :func:`design_matrix`.
    """
    phasors = np.asarray(phasors)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    n = np.arange(phasors.shape[-1])
    rows = phasors.reshape(-1, n.size)
    coef = _unpair(np.real(rows[:, 0]), rows[:, 1:])
    out = np.empty((rows.shape[0], t.size))
    for s in range(0, t.size, _TIMES):
        part = t[s:s + _TIMES]
        step = _uniform_step(part)
        if step:
            basis = GridBasis(part.size, 1.0 / step, float(part[0]), f0, n.size - 1)
            for j, c in enumerate(coef):
                basis.evaluate(c, out[j, s:s + part.size])
        else:
            cycles = np.mod(np.multiply.outer(n * f0, part), 1.0)
            out[:, s:s + part.size] = (rows @ np.exp(1j * 2.0 * np.pi * cycles)).real
    return out.reshape(*phasors.shape[:-1], t.size)


def _uniform_step(t: np.ndarray) -> float:
    """The step [s] of increasing times ``t`` spaced uniformly to rounding, else 0."""
    if t.size < 64:
        return 0.0
    step = float(t[-1] - t[0]) / (t.size - 1)
    if not step > 0.0:
        return 0.0
    tol = 64.0 * np.finfo(float).eps * max(abs(float(t[0])), abs(float(t[-1])))
    off = np.abs(t - (t[0] + np.arange(t.size) * step)).max()
    return step if off <= tol else 0.0
