"""The streaming estimator's kernel: recursive least squares of harmonic regressors with
forgetting (METHOD.md section 3, step 7).

Every channel (gauges, probes, coil current) is a Fourier series whose phasors drift slowly,
y_c(t_k) = X_{c,0}(k) + sum_{n=1..H} Re(X_{c,n}(k) exp(j n theta_k)), theta_k the drive's
phase, on the regressor of :func:`forcecal.signals.harmonics.design_matrix`. The phasors of
sample k minimize sum_{i <= k} lambda^(k-i) (y_i - phi_i^T x)^2 + lambda^k r0 |x|^2: RLS with
forgetting factor lambda from the prior P_0 = I / r0 (``PRIOR``). Every channel shares the
regressor, hence one information matrix; the forces follow from the phasors at every sample
as in the batch :func:`forcecal.forces.steady.reconstruct`.

:func:`rls_update` is the textbook information form, the reference (O(p^3) per sample,
p = 2H+1). :func:`harmonic_update` computes the same estimate, exactly, in O(p) per sample and
channel: in the frame that rotates with the drive the information matrix has a closed form
(:func:`harmonic_information`) and the right-hand side is the demodulated, exponentially
averaged signal (derived in their docstrings). A block is processed in pieces that end on
a fixed grid of sample counts (``grid``, one drive period) and the frequency tracker acts only
there, so the result does not depend on how the samples were split into blocks (to rounding).
The per-sample loops run compiled (:mod:`forcecal.realtime.compiled`); ``compiled=False`` runs
them as whole-array NumPy, the reference they are tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import DimensionError
from . import compiled as jit
from .reference import PRIOR, rls_start, rls_update

__all__ = ["harmonic_start", "harmonic_update", "rls_start", "rls_update", "steady_count"]

STEADY_TOL = 1e-16
"""lambda^k below which the information matrix is its stationary value (to rounding)."""
_GROWTH = math.log(4.0)
"""A cumulative sum spans at most ln(4) / (1 - lambda) samples (weights up to 4)."""


# --------------------------------------------------------------------------------------------
# the fast exact form for the harmonic regressor


@dataclass(frozen=True)
class HarmonicState:
    """RLS state of harmonic regressors in demodulated form.

    Attributes
    ----------
    demod : (n_channels, H+1) complex [unit of y] d_n = sum lambda^(k-i) y_i exp(-j n theta_i)
    energy : (n_channels,) [unit of y ^2] sum lambda^(k-i) y_i^2 (for the residual)
    phase : [cycles] theta of the last sample / 2 pi, reduced modulo 1
    step : [cycles per sample] phase advance per sample, f0 / fs
    count : samples seen
    """

    demod: np.ndarray
    energy: np.ndarray
    phase: float
    step: float
    count: int = 0

    @property
    def n_harmonics(self) -> int:
        return self.demod.shape[1] - 1


def harmonic_start(n_channels: int, n_harmonics: int, f0: float, fs: float,
                   t0: float = 0.0) -> HarmonicState:
    """The state before the first sample, taken at absolute time t0 [s].

    With the phase started at f0 * t0 the phasors follow the absolute-time convention of
    :mod:`forcecal.signals.harmonics` for as long as the frequency is not changed.

    Parameters
    ----------
    n_channels : int
        Channels sharing the regressor.
    n_harmonics : int
        H.
    f0 : float
        [Hz] the drive frequency.
    fs : float
        [Hz] the sampling rate.
    t0 : float
        [s] absolute time of the first sample.

    Returns
    -------
    HarmonicState
    """
    step = f0 / fs
    return HarmonicState(demod=np.zeros((n_channels, n_harmonics + 1), dtype=complex),
                         energy=np.zeros(n_channels),
                         phase=float((f0 * t0 - step) % 1.0), step=float(step))


def _window_sums(lam: float, step: float, n_harmonics: int,
                 count: int | np.ndarray | None) -> np.ndarray:
    """g_m = sum_{d < count} lambda^d exp(j 2 pi m step d), m = 0..2H -> (..., 2H+1)."""
    m = np.arange(2 * n_harmonics + 1)
    g = 1.0 / (1.0 - lam * np.exp(2j * np.pi * step * m))
    if count is None:
        return g
    k = np.asarray(count, dtype=float)[..., None]
    power = lam**k * np.exp(2j * np.pi * np.mod(step * m * k, 1.0))   # (lam e^{j m a})^count
    return g * (1.0 - power)


@lru_cache(maxsize=8)
def _assembly(n_harmonics: int) -> np.ndarray:
    """(2 (2H+1), p^2) real map from [Re g, Im g] to the flattened information matrix."""
    h = n_harmonics
    p, ng = 2 * h + 1, 2 * h + 1
    a = np.zeros((2 * ng, p, p))
    re, im = 0, ng

    def put(row, col, part, m, weight):
        a[part + m, row, col] += weight

    put(0, 0, re, 0, 1.0)
    for n in range(1, h + 1):
        for r, c in ((0, 2 * n - 1), (2 * n - 1, 0)):
            put(r, c, re, n, 1.0)
        for r, c in ((0, 2 * n), (2 * n, 0)):
            put(r, c, im, n, 1.0)
        for m in range(1, h + 1):
            d, t = abs(n - m), n + m
            put(2 * n - 1, 2 * m - 1, re, d, 0.5)              # sum cos(n.) cos(m.)
            put(2 * n - 1, 2 * m - 1, re, t, 0.5)
            put(2 * n, 2 * m, re, d, 0.5)                      # sum sin(n.) sin(m.)
            put(2 * n, 2 * m, re, t, -0.5)
            sign = float(np.sign(m - n))                       # sum cos(n.) sin(m.)
            for r, c in ((2 * n - 1, 2 * m), (2 * m, 2 * n - 1)):
                put(r, c, im, t, 0.5)
                put(r, c, im, d, 0.5 * sign)
    flat: np.ndarray = a.reshape(2 * ng, p * p)
    flat.setflags(write=False)
    return flat


@lru_cache(maxsize=8)
def _terms(n_harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """(2, p^2) rows and weights of the (at most two) terms of :func:`_assembly`'s columns."""
    a = _assembly(n_harmonics)
    rows = np.argsort(a == 0, axis=0, kind="stable")[:2]
    return rows, np.take_along_axis(a, rows, axis=0)


def _assemble(g: np.ndarray) -> np.ndarray:
    """Information matrix (..., p, p) from the window sums g (..., 2H+1); the product with
    :func:`_assembly` as its two terms per entry (no BLAS call, so no thread pool)."""
    h = (g.shape[-1] - 1) // 2
    parts = np.concatenate([g.real, g.imag], axis=-1)
    (r0, r1), (w0, w1) = _terms(h)
    flat = parts[..., r0] * w0 + parts[..., r1] * w1
    return flat.reshape(*g.shape[:-1], 2 * h + 1, 2 * h + 1)


def harmonic_information(lam: float, step: float, n_harmonics: int,
                         count: int | np.ndarray | None = None,
                         prior: float = PRIOR) -> np.ndarray:
    """Information matrix M_k of the harmonic regressor in the rotating frame.

    The regressor is a rotating phasor: phi_i = T(theta_i) phi(0), T a block rotation by
    n theta_i. In the frame that rotates with the drive the information matrix

        M_k = T_k^T R_k T_k = lambda^k r0 I + sum_{d=0}^{k-1} lambda^d phi(-d a) phi(-d a)^T

    (a = w0 / fs) depends neither on the data nor on the absolute phase; its entries are the
    geometric sums g_m = sum_d lambda^d exp(j m a d) = (1 - (lambda e^{jma})^k) /
    (1 - lambda e^{jma}), m = 0..2H, in closed form.

    Parameters
    ----------
    lam : forgetting factor
    step : [cycles per sample] f0 / fs
    n_harmonics : H
    count : samples seen, scalar or (n,); None for the stationary value (count -> infinity)
    prior : r0 (``PRIOR``, one sample's worth of information: it keeps the first, poorly
        conditioned samples finite and fades as lambda^k)

    Returns
    -------
    (p, p) or (n, p, p) [1], p = 2H+1, ordered [DC, Re 1, Im 1, Re 2, ...]
    """
    m = _assemble(_window_sums(lam, step, n_harmonics, count))
    if count is not None:
        w = prior * lam ** np.asarray(count, dtype=float)
        m = m + w[..., None, None] * np.eye(m.shape[-1])
    return m


@lru_cache(maxsize=16)
def stationary(lam: float, step: float, n_harmonics: int) -> tuple[np.ndarray, np.ndarray,
                                                                   np.ndarray]:
    """(M, M^-1, M^-1 M(lambda^2) M^-1): stationary information, its inverse, and the
    covariance of the rotated coefficients per unit white-noise variance."""
    m = harmonic_information(lam, step, n_harmonics)
    inv = np.linalg.inv(m)
    noise = inv @ _assemble(_window_sums(lam * lam, step, n_harmonics, None)) @ inv
    for a in (m, inv, noise):
        a.setflags(write=False)
    return m, inv, noise


@dataclass(frozen=True)
class _Tables:
    """Per-sample factors of a piece of up to ``length`` samples at one frequency.

    sample i of a piece (i = 0..length-1), phase theta_i = theta_start + step (i + 1):
    rotor : (H+1, L) exp(-j 2 pi n step (i+1))
    weight : (H+1, L) lambda^-i rotor
    back : (H+1, L) lambda^i conj(rotor)
    power : (L,) lambda^i
    planes : (4, H+1, L) [Re weight, Im weight, Re back, Im back], for the compiled loops
    """

    rotor: np.ndarray
    weight: np.ndarray
    back: np.ndarray
    power: np.ndarray
    planes: np.ndarray


@lru_cache(maxsize=8)
def window_tables(lam: float, step: float, n_harmonics: int, length: int) -> _Tables:
    i = np.arange(length)
    first = np.exp(-2j * np.pi * np.mod(step * (i + 1), 1.0))
    rotor = np.empty((n_harmonics + 1, length), dtype=complex)
    rotor[0] = 1.0
    for n in range(1, n_harmonics + 1):
        np.multiply(rotor[n - 1], first, out=rotor[n])
    power = lam ** i.astype(float)
    weight, back = rotor / power, rotor.conj() * power
    planes = np.empty((4, n_harmonics + 1, length))
    planes[0], planes[1], planes[2], planes[3] = weight.real, weight.imag, back.real, back.imag
    t = _Tables(rotor=rotor, weight=weight, back=back, power=power, planes=planes)
    for a in (t.rotor, t.weight, t.back, t.power, t.planes):
        a.setflags(write=False)
    return t


def steady_count(lam: float) -> int:
    """Samples after which M_k is stationary to rounding (lambda^k < STEADY_TOL).

    Parameters
    ----------
    lam : float
        The forgetting factor.

    Returns
    -------
    int
    """
    return int(math.ceil(math.log(STEADY_TOL) / math.log(lam)))


def chunk_limit(lam: float) -> int:
    """Longest stretch summed at once: lambda^-n stays below 4.

    Parameters
    ----------
    lam : float
        The forgetting factor.

    Returns
    -------
    int
    """
    return max(1, int(_GROWTH / -math.log(lam)))


def to_real(z: np.ndarray) -> np.ndarray:
    """Complex phasors to real coefficients [Re z0, Re z1, Im z1, ...].

    Parameters
    ----------
    z : (..., H+1, n) complex ndarray

    Returns
    -------
    (..., 2H+1, n) ndarray
    """
    h = z.shape[-2] - 1
    out = np.empty((*z.shape[:-2], 2 * h + 1, z.shape[-1]))
    out[..., 0, :] = z[..., 0, :].real
    out[..., 1::2, :] = z[..., 1:, :].real
    out[..., 2::2, :] = z[..., 1:, :].imag
    return out


def to_complex(u: np.ndarray) -> np.ndarray:
    """Real coefficients to complex phasors; the inverse of :func:`to_real`.

    Parameters
    ----------
    u : (..., 2H+1, n) ndarray

    Returns
    -------
    (..., H+1, n) complex ndarray
    """
    z = np.empty((*u.shape[:-2], (u.shape[-2] + 1) // 2, u.shape[-1]), dtype=complex)
    z[..., 0, :] = u[..., 0, :]
    z[..., 1:, :] = u[..., 1::2, :] + 1j * u[..., 2::2, :]
    return z


def mixing(readout: np.ndarray, lam: float, step: float, n_harmonics: int) -> np.ndarray:
    """The readout folded into the channel mixing of the stationary window:
    readout . u = Re(sum kappa . beta_complex) with u = M^-1 beta.

    Parameters
    ----------
    readout : (n_out, n_channels, 2H+1) ndarray
        A linear functional of the rotated coefficients u.
    lam : float
        The forgetting factor.
    step : float
        [cycles per sample] f0 / fs.
    n_harmonics : int
        H.

    Returns
    -------
    (n_out, H+1, n_channels) complex ndarray
        kappa, acting on the demodulated right-hand side.
    """
    k = readout @ stationary(lam, step, n_harmonics)[1]
    kap = np.empty((k.shape[0], n_harmonics + 1, k.shape[1]), dtype=complex)
    kap[:, 0] = k[..., 0]
    kap[:, 1:] = (k[..., 1::2] - 1j * k[..., 2::2]).transpose(0, 2, 1)
    return kap


def harmonic_update(state: HarmonicState, y: np.ndarray, lam: float,
                    readout: np.ndarray | None = None, prior: float = PRIOR, *,
                    compiled: bool = True) -> tuple[HarmonicState, np.ndarray]:
    """Exact RLS of harmonic regressors over a block, at the state's constant frequency.

    The same x_k as :func:`rls_update` (the information form R_k = lambda R_{k-1} +
    phi_k phi_k^T, b_k = lambda b_{k-1} + phi_k y_k, x_k = R_k^{-1} b_k), in O(p) per sample
    and channel. In the frame that rotates with the drive, M_k is
    :func:`harmonic_information`'s and the right-hand side is the demodulated, exponentially
    averaged signal, T_k^T b_k <-> exp(j n theta_k) d_n(k) with d_n(k) = lambda d_n(k-1) +
    y_k exp(-j n theta_k): a first-order IIR per harmonic (a complex resonator), which a block
    evaluates at once as a scaled cumulative sum. Hence, with no approximation,

        x_k = T_k M_k^{-1} [exp(j n theta_k) d_n(k)].

    Once lambda^k < ``STEADY_TOL`` M_k equals its stationary value to rounding and one inverse
    serves every sample; the linear readout is then folded into the channel mixing
    (:func:`mixing`), so that a sample costs O(p n_channels) for the demodulation and
    O(p n_out) for the cumulative sums. Before that, each sample gets its own solve of M_k
    (start-up only). This is the "demodulate and low-pass" view of RLS; the exact M_k is what
    removes the ripple at 2 n w0, about (1 - lambda) / (2 n a) of each phasor, that a plain
    first-order low-pass of the demodulated signal leaves.

    Parameters
    ----------
    state : after the previous sample (:func:`harmonic_start` at first)
    y : (n_channels, n) [unit of each channel]
    lam : forgetting factor, 0 < lambda < 1
    readout : optional (n_out, n_channels, 2H+1) [1/unit]: a linear functional of the
        instantaneous harmonic components u_{c,k} = T_k^T x_{c,k} ([U_0, Re U_1, Im U_1, ...]
        with U_n = X_n exp(j n theta_k), so that Re U_n is harmonic n's value at sample k)
    prior : r0 of :func:`rls_start`
    compiled : the compiled loops (default) or the NumPy reference (:func:`kernel`)

    Returns
    -------
    state : after the last sample
    out : without ``readout``, (n_channels, H+1, n) complex phasors X_n(k), referred to the
        phase theta_k (the RLS estimate x_k, as :func:`rls_update` with the regressor of
        :func:`forcecal.signals.harmonics.design_matrix`); with it, (n_out, n) sum_c readout_c . u_c
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    if y.shape[0] != state.demod.shape[0]:
        raise DimensionError(f"harmonic_update: {y.shape[0]} channels given, the state holds "
                             f"{state.demod.shape[0]}")
    h = state.n_harmonics
    limit = chunk_limit(lam)
    n = y.shape[-1]
    tabs = window_tables(lam, state.step, h, max(1, min(limit, n)))
    kap = None if readout is None else mixing(readout, lam, state.step, h)
    pieces = []
    for start in range(0, max(n, 1), limit):
        state, out = kernel(state, y[:, start:start + limit], lam, tabs, readout, kap, prior,
                            compiled=compiled)
        pieces.append(out)
    return state, pieces[0] if len(pieces) == 1 else np.concatenate(pieces, axis=-1)


def kernel(state: HarmonicState, y: np.ndarray, lam: float, tables: _Tables,
           readout: np.ndarray | None, kap: np.ndarray | None, prior: float,
           compiled: bool = True) -> tuple[HarmonicState, np.ndarray]:
    """Exact RLS over one piece of at most ``chunk_limit(lam)`` samples.

    Parameters
    ----------
    state : HarmonicState
        After the previous sample.
    y : (n_channels, c) ndarray
        The piece's samples, c no longer than the tables.
    lam : float
        The forgetting factor.
    tables : _Tables
        Per-sample factors at the state's frequency (:func:`window_tables`).
    readout : (n_out, n_channels, 2H+1) ndarray or None
        A linear functional of the rotated coefficients (None: return the phasors).
    kap : ndarray or None
        ``mixing(readout, ...)``, the readout folded for the stationary window.
    prior : float
        r0.
    compiled : bool
        Demodulation, cumulative sums and (stationary) readout by the compiled loops of
        :mod:`forcecal.realtime.compiled`; False: by whole-array NumPy, the reference.

    Returns
    -------
    state : HarmonicState
        After the piece's last sample.
    out : ndarray
        (n_out, c) readouts, or (n_channels, H+1, c) complex phasors without ``readout``.
    """
    n_ch, c = y.shape
    h = state.n_harmonics
    if c == 0:
        if readout is None:
            return state, np.zeros((n_ch, h + 1, 0), dtype=complex)
        return state, np.zeros((readout.shape[0], 0))
    start = np.exp(-2j * np.pi * state.phase * np.arange(h + 1))
    last = tables.power[c - 1]
    steady = state.count >= steady_count(lam)
    if compiled:
        if kap is not None and steady:
            offset = lam * np.sum(kap * state.demod.T, axis=-1) * start.conj()
            out, dsum, esum = jit.steady_readout(y, tables.planes, tables.power, kap, offset)
            return _advance(state, lam, last, dsum * start, esum, c), out
        cum, dsum, esum = jit.demodulate(y, tables.planes, tables.power)
        new = _advance(state, lam, last, dsum * start, esum, c)
        acc = cum * start[:, None] + lam * state.demod[..., None]    # (n_ch, H+1, c)
    else:
        weight = tables.weight[:, :c] * start[:, None]             # lambda^-i exp(-j n theta_i)
        new = _advance(state, lam, last, y @ weight.T, (y * y) @ tables.power[c - 1::-1], c)
        if kap is not None and steady:
            # forces straight from the mixed, demodulated channels: Re sum_n kappa . beta_n
            mixed = np.cumsum((kap @ y) * weight, axis=-1)          # (n_out, H+1, c)
            mixed += lam * np.sum(kap * state.demod.T, axis=-1)[..., None]
            return new, np.einsum("onj,nj->oj", mixed,
                                  tables.back[:, :c] * start.conj()[:, None]).real
        acc = np.cumsum(y[:, None, :] * weight, axis=-1)            # (n_ch, H+1, c)
        acc += lam * state.demod[..., None]
    beta = to_real(acc * (tables.back[:, :c] * start.conj()[:, None]))     # (n_ch, p, c)
    counts = state.count + np.arange(1, c + 1)
    if steady:
        u = np.einsum("pq,cqj->cpj", stationary(lam, state.step, h)[1], beta)
    elif compiled:                                     # M_k of every sample, by Cholesky
        g = _window_sums(lam, state.step, h, counts)
        u = jit.solve_information(np.concatenate([g.real, g.imag], axis=-1), *_terms(h),
                                  prior * lam ** counts.astype(float), beta)
    else:
        info = harmonic_information(lam, state.step, h, counts, prior)
        u = np.linalg.solve(info, beta.transpose(2, 1, 0)).transpose(2, 1, 0)
    if readout is None:
        return new, to_complex(u) * (tables.rotor[:, :c] * start[:, None])
    return new, np.einsum("ocp,cpj->oj", readout, u)


def _advance(state: HarmonicState, lam: float, last: float, dsum: np.ndarray,
             esum: np.ndarray, c: int) -> HarmonicState:
    """The state after a piece of c samples whose weighted sums are dsum and esum."""
    return HarmonicState(demod=lam * last * state.demod + last * dsum,
                         energy=lam * last * state.energy + esum,
                         phase=float((state.phase + state.step * c) % 1.0),
                         step=state.step, count=state.count + c)


def last_coefficients(state: HarmonicState, lam: float, prior: float) -> np.ndarray:
    """The rotated coefficients u of the last sample.

    Parameters
    ----------
    state : HarmonicState
    lam : float
        The forgetting factor.
    prior : float
        r0.

    Returns
    -------
    (n_channels, 2H+1) ndarray
    """
    h = state.n_harmonics
    rot = np.exp(-2j * np.pi * state.phase * np.arange(h + 1))
    beta = to_real((state.demod * rot.conj())[..., None])[..., 0]     # (n_ch, p)
    if state.count >= steady_count(lam):
        info = stationary(lam, state.step, h)[0]
    else:
        info = harmonic_information(lam, state.step, h, max(state.count, 1), prior)
    return np.linalg.solve(info, beta.T).T
