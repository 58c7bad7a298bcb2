"""Compiled loops of the streaming kernel (:func:`forcecal.realtime.rls.kernel`).

The per-sample work of exact RLS on the harmonic regressor, as :mod:`.rls` derives it, is a
demodulation (every channel times lambda^-i exp(-j n theta_i)), cumulative sums of the
demodulated (and, in the stationary regime, readout-mixed) signals, and the readout. The
products that mix channels are matrix products (BLAS); what is sequential, the cumulative sums
and the readout at every sample, runs here in one pass per pair of harmonics, compiled by Numba
(machine code cached on disk, so that a new process pays no compilation), where NumPy would
build and walk several temporaries as long as the piece.

The per-sample factors are those of :func:`forcecal.realtime.rls.window_tables` split into real
planes, ``planes`` (4, H+1, L) = [Re w, Im w, Re b, Im b] with w = lambda^-i rotor and
b = lambda^i conj(rotor), referred to the phase before the piece's first sample; the rotation
by the piece's start phase is left to the caller (a factor per harmonic on the piece's sums).
The results equal NumPy's to rounding: the sums run in another order, which moves them by a
few units in the last place.
"""

from __future__ import annotations

import numba
import numpy as np

__all__: list[str] = []

_jit = numba.njit(nogil=True, cache=True, error_model="numpy", fastmath={"reassoc", "contract"})
"""Compiled, cached on disk; reassociation and fused multiply-adds allowed (no assumption about
NaN, infinities or signed zeros)."""
TILE = 1024
"""Samples mixed at once: the tile stays in cache, and its matrix products stay below the size
from which BLAS would hand them to a thread pool (which only costs on a shared machine)."""


@_jit
def _scan_readout(mixed, planes, start, state, out):                 # pragma: no cover
    """out[o, i] = Re sum_n (state[o, n] + sum_{i' <= i} mixed[o, n, i'] w_n(start + i'))
    b_n(start + i), the sums carried on in ``state`` (n_out, H+1, 2).

    Two harmonics per pass over the samples, so that two chains of sums are in flight.
    """
    n_out, n_h, _, c = mixed.shape
    for o in range(n_out):
        acc = out[o]
        for i in range(c):
            acc[i] = 0.0
        for n in range(0, n_h, 2):
            k = min(n + 1, n_h - 1)
            f = 1.0 if k > n else 0.0           # a lone last harmonic: its pair is void
            mr0 = mixed[o, n, 0]
            mi0 = mixed[o, n, 1]
            mr1 = mixed[o, k, 0]
            mi1 = mixed[o, k, 1]
            wr0 = planes[0, n, start:]
            wi0 = planes[1, n, start:]
            br0 = planes[2, n, start:]
            bi0 = planes[3, n, start:]
            wr1 = planes[0, k, start:]
            wi1 = planes[1, k, start:]
            br1 = planes[2, k, start:]
            bi1 = planes[3, k, start:]
            pr0 = state[o, n, 0]
            pi0 = state[o, n, 1]
            pr1 = f * state[o, k, 0]
            pi1 = f * state[o, k, 1]
            for i in range(c):
                pr0 += mr0[i] * wr0[i] - mi0[i] * wi0[i]
                pi0 += mr0[i] * wi0[i] + mi0[i] * wr0[i]
                pr1 += f * (mr1[i] * wr1[i] - mi1[i] * wi1[i])
                pi1 += f * (mr1[i] * wi1[i] + mi1[i] * wr1[i])
                acc[i] += (pr0 * br0[i] - pi0 * bi0[i]) + (pr1 * br1[i] - pi1 * bi1[i])
            state[o, n, 0] = pr0
            state[o, n, 1] = pi0
            if k > n:
                state[o, k, 0] = pr1
                state[o, k, 1] = pi1


@_jit
def _prefix(y, planes, cum):                                         # pragma: no cover
    """cum[ch, n, :, i] = [Re, Im] sum_{i' <= i} y[ch, i'] w_n(i')."""
    n_ch, c = y.shape
    for ch in range(n_ch):
        row = y[ch]
        for n in range(planes.shape[1]):
            wr = planes[0, n]
            wi = planes[1, n]
            sr = 0.0
            si = 0.0
            for i in range(c):
                sr += row[i] * wr[i]
                si += row[i] * wi[i]
                cum[ch, n, 0, i] = sr
                cum[ch, n, 1, i] = si


@_jit
def _energy(y, power, esum):                                          # pragma: no cover
    """esum[ch] = sum_i y[ch, i]^2 lambda^(c-1-i)."""
    n_ch, c = y.shape
    for ch in range(n_ch):
        row = y[ch]
        e = 0.0
        for i in range(c):
            e += row[i] * row[i] * power[c - 1 - i]
        esum[ch] = e


@_jit
def _sums(y, planes, dsum):                                           # pragma: no cover
    """dsum[ch, n] = [Re, Im] sum_i y[ch, i] w_n(i)."""
    n_ch, c = y.shape
    for ch in range(n_ch):
        row = y[ch]
        for n in range(planes.shape[1]):
            wr = planes[0, n]
            wi = planes[1, n]
            sr = 0.0
            si = 0.0
            for i in range(c):
                sr += row[i] * wr[i]
                si += row[i] * wi[i]
            dsum[ch, n, 0] = sr
            dsum[ch, n, 1] = si


@_jit
def _tile(y, planes, power, mixed, start, state, out, dsum, esum):  # pragma: no cover
    """One tile's readouts (``mixed`` from ``start``); with ``dsum`` given, the sums too."""
    _scan_readout(mixed, planes, start, state, out)
    if dsum.size:
        _sums(y, planes, dsum)
        _energy(y, power, esum)


def steady_readout(y: np.ndarray, planes: np.ndarray, power: np.ndarray, kap: np.ndarray,
                   offset: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stationary fast path: readouts of every sample and the piece's sums.

    Parameters
    ----------
    y : (n_channels, c) ndarray
        The piece's samples.
    planes : (4, H+1, L) ndarray, L >= c
        [Re w, Im w, Re b, Im b] of :func:`forcecal.realtime.rls.window_tables`.
    power : (L,) ndarray
        lambda^i.
    kap : (n_out, H+1, n_channels) complex ndarray
        The readout folded into the channel mixing (:func:`forcecal.realtime.rls.mixing`).
    offset : (n_out, H+1) complex ndarray
        The mixed state before the piece, lambda sum_c kappa_c d_c, rotated back by the
        start phase.

    Returns
    -------
    out : (n_out, c) ndarray
        Re sum_n (offset_n + sum_{i' <= i} m_n(i') w_n(i')) b_n(i) at every sample i, with
        m_n = sum_c kappa_{n,c} y_c.
    dsum : (n_channels, H+1) complex ndarray
        sum_i y_i w_i, to be rotated by the start phase.
    esum : (n_channels,) ndarray
        sum_i y_i^2 lambda^(c-1-i).
    """
    n_ch, c = y.shape
    n_out, n_h = kap.shape[:2]
    y = np.ascontiguousarray(y)
    planes_of_kap = np.empty((n_out, n_h, 2, n_ch))
    planes_of_kap[:, :, 0], planes_of_kap[:, :, 1] = kap.real, kap.imag
    gains = planes_of_kap.reshape(-1, n_ch)
    state = np.stack([offset.real, offset.imag], axis=-1)
    out = np.empty((n_out, c))
    d = np.empty((n_ch, n_h, 2))
    esum = np.empty(n_ch)
    none = np.empty((0, 0, 0))
    for s in range(0, c, TILE):
        e = min(c, s + TILE)
        part = y[:, s:e] if e - s < c else y
        _tile(y, planes, power, (gains @ part).reshape(n_out, n_h, 2, e - s), s, state,
                out[:, s:e], d if e == c else none, esum)
    return out, d[..., 0] + 1j * d[..., 1], esum


def demodulate(y: np.ndarray, planes: np.ndarray,
               power: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cumulative demodulated sums of every channel (the start-up and phasor paths).

    Parameters
    ----------
    y : (n_channels, c) ndarray
        The piece's samples.
    planes : (4, H+1, L) ndarray, L >= c
        As :func:`steady_readout`.
    power : (L,) ndarray
        lambda^i.

    Returns
    -------
    cum : (n_channels, H+1, c) complex ndarray
        sum_{i' <= i} y_i' w_i', to be rotated by the start phase.
    dsum : (n_channels, H+1) complex ndarray
        The last of them.
    esum : (n_channels,) ndarray
        sum_i y_i^2 lambda^(c-1-i).
    """
    n_ch, c = y.shape
    y = np.ascontiguousarray(y)
    cum = np.empty((n_ch, planes.shape[1], 2, c))
    esum = np.empty(n_ch)
    _prefix(y, planes, cum)
    _energy(y, power, esum)
    z = cum[:, :, 0] + 1j * cum[:, :, 1]
    return z, z[..., -1].copy(), esum


@_jit
def _solve(parts, rows, weights, diag, beta, u):                     # pragma: no cover
    n_ch, p, c = beta.shape
    m = np.empty((p, p))
    z = np.empty(p)
    for j in range(c):
        for i in range(p * p):                   # M_k entry by entry (two terms each)
            m[i // p, i % p] = parts[j, rows[0, i]] * weights[0, i] \
                + parts[j, rows[1, i]] * weights[1, i]
        for a in range(p):
            m[a, a] += diag[j]
        for a in range(p):                       # Cholesky, L in the lower triangle
            s = m[a, a]
            for k in range(a):
                s -= m[a, k] * m[a, k]
            d = np.sqrt(s)
            m[a, a] = d
            for b in range(a + 1, p):
                t = m[b, a]
                for k in range(a):
                    t -= m[b, k] * m[a, k]
                m[b, a] = t / d
        for ch in range(n_ch):
            for a in range(p):                   # L z = beta
                t = beta[ch, a, j]
                for k in range(a):
                    t -= m[a, k] * z[k]
                z[a] = t / m[a, a]
            for a in range(p - 1, -1, -1):       # L^T u = z
                t = z[a]
                for k in range(a + 1, p):
                    t -= m[k, a] * u[ch, k, j]
                u[ch, a, j] = t / m[a, a]


def solve_information(parts: np.ndarray, rows: np.ndarray, weights: np.ndarray,
                      diag: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """u = M_k^-1 beta_k at every sample of the start-up, M_k assembled sample by sample.

    Parameters
    ----------
    parts : (c, 2 (2H+1)) ndarray
        [Re g, Im g], the window sums of every sample (:func:`forcecal.realtime.rls`).
    rows, weights : (2, p^2) ndarray
        The two terms of every entry of M in ``parts`` (the assembly map's nonzeros).
    diag : (c,) ndarray
        The prior's information r0 lambda^k added to the diagonal.
    beta : (n_channels, p, c) ndarray
        The right-hand sides.

    Returns
    -------
    (n_channels, p, c) ndarray
        The rotated coefficients u (M_k is positive definite: Cholesky).
    """
    u = np.empty(beta.shape)
    _solve(np.ascontiguousarray(parts), rows, weights, diag, np.ascontiguousarray(beta), u)
    return u
