"""Forces in real time: recursive least squares with forgetting (METHOD.md section 3, step 7).

What is estimated
-----------------
Every channel (gauges, probes, coil current) is written as a Fourier series whose phasors
drift slowly,

    y_c(t_k) = X_{c,0}(k) + sum_{n=1..H} Re( X_{c,n}(k) exp(j n theta_k) ),

with the regressor [1, cos(theta_k), -sin(theta_k), cos(2 theta_k), ...] of
:func:`forcecal.harmonics.design_matrix` and theta_k the phase of the drive. The phasors of
sample k minimize the exponentially weighted squared error

    sum_{i <= k} lambda^(k-i) (y_i - phi_i^T x)^2  +  lambda^k r0 |x|^2,

which is recursive least squares (RLS) with forgetting factor lambda started from the prior
P_0 = I / r0 (``PRIOR``: one sample's worth of information, which keeps the first, poorly
conditioned samples finite and fades as lambda^k). Every channel shares the regressor, hence
one information matrix. The forces at sample k follow from the phasors exactly as in the batch
:func:`forcecal.forces.reconstruct` (Q_n from the probes, J_n = m_n (-(n w0)^2) Q_n,
F_n = Psi^+ (J_n - R_n)), evaluated at that sample: F(t_k) = sum_n Re(F_n(k) exp(j n theta_k)).

The exact block form chosen
---------------------------
:func:`rls_update` is the textbook information form (R_k = lambda R_{k-1} + phi_k phi_k^T,
b_k = lambda b_{k-1} + phi_k y_k, x_k = R_k^{-1} b_k) vectorized over a block: the reference
implementation, O(p^3) per sample with p = 2H+1.

:func:`harmonic_update` computes the same x_k for the harmonic regressor in O(p) per sample
and channel. The regressor is a rotating phasor: phi_i = T(theta_i) phi(0), T a block rotation
by n theta_i. In the frame that rotates with the drive, the information matrix

    M_k = T_k^T R_k T_k = lambda^k r0 I + sum_{d=0}^{k-1} lambda^d phi(-d a) phi(-d a)^T,

(a = w0 / fs) no longer depends on the data nor on the absolute phase; its entries are the
geometric sums g_m = sum_d lambda^d exp(j m a d) = (1 - (lambda e^{jma})^k) / (1 - lambda e^{jma}),
m = 0..2H, in closed form (:func:`harmonic_information`). The right-hand side in that frame is
the demodulated and exponentially averaged signal, T_k^T b_k <-> exp(j n theta_k) d_n(k) with
d_n(k) = lambda d_n(k-1) + y_k exp(-j n theta_k): a first-order IIR per harmonic (a complex
resonator), which a block evaluates at once as a scaled cumulative sum. Hence

    x_k = T_k M_k^{-1} [exp(j n theta_k) d_n(k)]          (exact RLS, no approximation).

After lambda^k < ``STEADY_TOL`` (about 37 / (1 - lambda) samples) M_k equals its stationary
value to rounding and one inverse serves every sample; the linear readout to the forces is then
folded into the channel mixing, so that a sample costs O(p n_channels) for the demodulation and
O(p n_forces) for the cumulative sums. Before that, each sample gets its own solve of M_k
(start-up only). The demodulation is the "demodulate and low-pass" view of RLS; the exact M_k
is what removes the ripple at 2 n w0 that a plain first-order low-pass of the demodulated
signal leaves (about (1 - lambda) / (2 n a) of each phasor, 4 % for a memory of two periods).

A block is processed in pieces that end on a fixed grid of sample counts (``grid``, one drive
period); the frequency tracker acts only on that grid, so the result does not depend on how the
samples were split into blocks (to rounding: 1e-15 relative once the window spans a period,
1e-12 during the first period, where the conditioning of M_k amplifies rounding).

Latency and noise
-----------------
The exponential window has memory 1 / (1 - lambda) samples and mean age (group delay)
lambda / (1 - lambda) samples: :attr:`StreamEstimator.latency_periods` in drive periods. The
default is a memory of ``DEFAULT_MEMORY_PERIODS`` = 2 periods, so a latency of 2 periods (100 ms
at 20 Hz). A step settles to a fraction eps of its size within ln(eps) / ln(lambda) samples
(:meth:`StreamEstimator.settling_periods`): 13.8 periods to 1e-3 by default. For
white noise of std sigma each phasor has var(Re) = var(Im) ~ (1 - lambda) / (1 + lambda)
2 sigma^2, the batch fit's 2 sigma^2 / N with N -> (1 + lambda) / (1 - lambda); the exact
value for the forces is :meth:`StreamEstimator.noise_std`.

Frequency tracking
------------------
The regressor's phase advances by w / fs per sample. Once per grid step (one period) the phase
of the current's fundamental phasor X_1 (referred to theta) is read; a drive faster than w makes
it rotate at (w_true - w). Since the window's phase lags by its mean age, the loop adds that lead
(the last advance times lambda / (1 - lambda) / grid) and feeds a proportional-integral
correction of w (a type-2 phase-locked loop: no steady frequency error even along a linear
drift) of bandwidth min(1 / (``LOOP_MEMORIES`` memory), ``LOOP_MAX_STEP`` / period) and damping
``LOOP_DAMPING``; by default about 5 periods. The loop starts after one memory and two periods,
stays within ``FREQUENCY_RANGE`` of the guess, and holds while |X_1| is below ``LOCK_SNR``
times its noise (no drive, a tare record). Changing w changes M_k and the readout with it: the
estimate is then the RLS estimate with the window's regressors taken at the current frequency.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from .coordinates import MIN_SENSOR_GAIN, sensor_gain, sensor_rows
from .errors import ConditioningError, DataError, DimensionError, InputError
from .forces import FREQUENCY_MISMATCH
from .io.run_files import write_table_csv, write_table_hdf5
from .records import Run
from .relaxation import force_matrix
from .rig import Rig
from .spatial import SpatialModel

__all__ = [
    "DEFAULT_MEMORY_PERIODS",
    "PRIOR",
    "HarmonicState",
    "RlsState",
    "StreamEstimator",
    "chunk_limit",
    "harmonic_information",
    "harmonic_start",
    "harmonic_update",
    "replay",
    "rls_start",
    "rls_update",
    "steady_count",
    "write_stream_csv",
]

DEFAULT_MEMORY_PERIODS = 2.0
"""Default memory 1 / (1 - lambda) of the forgetting, in drive periods."""
PRIOR = 1.0
"""r0: information of the prior at the start (P_0 = I / r0), in samples' worth of regressor."""
STEADY_TOL = 1e-16
"""lambda^k below which the information matrix is its stationary value (to rounding)."""
LOOP_MEMORIES = 1.5
"""The frequency loop's time constant, in memories 1 / ((1 - lambda) fs) of the forgetting."""
LOOP_DAMPING = 0.7
"""Damping ratio of the frequency loop."""
LOOP_MAX_STEP = 1.0 / 3.0
"""Largest loop bandwidth [rad/s] times the loop's update interval (stability of the
discrete loop when the memory is short)."""
ENGAGE_MEMORIES = 1.0
ENGAGE_PERIODS = 2.0
"""The frequency loop starts after this many memories and drive periods, whichever is later."""
LOCK_SNR = 5.0
"""The frequency loop acts only while |X_1| of the current exceeds this many noise stds."""
FREQUENCY_RANGE = 0.05
"""The tracked frequency stays within this relative distance of the initial guess."""
_GROWTH = math.log(4.0)
"""A cumulative sum spans at most ln(4) / (1 - lambda) samples (weights up to 4)."""


# --------------------------------------------------------------------------------------------
# the reference: information-form RLS for any regressor


@dataclass(frozen=True)
class RlsState:
    """Recursive least squares in information form.

    Attributes
    ----------
    information : (p, p) [1] R_k = sum lambda^(k-i) phi_i phi_i^T + lambda^k r0 I
    moment : (p, n_outputs) [unit of y] b_k = sum lambda^(k-i) phi_i y_i^T
    count : samples seen
    """

    information: np.ndarray
    moment: np.ndarray
    count: int = 0


def rls_start(n_regressors: int, n_outputs: int, prior: float = PRIOR) -> RlsState:
    """The state before any sample: prior information ``prior * I``, no data."""
    return RlsState(information=prior * np.eye(n_regressors),
                    moment=np.zeros((n_regressors, n_outputs)))


def rls_update(state: RlsState, y: np.ndarray, regressors: np.ndarray,
               lam: float) -> tuple[RlsState, np.ndarray]:
    """Exact RLS with forgetting over a block of samples (the reference form).

    Parameters
    ----------
    state : the state after the previous sample
    y : (n_outputs, n) [any unit] samples of every output, sharing the regressor
    regressors : (p, n) [1] phi_k of every sample
    lam : forgetting factor lambda, 0 < lambda <= 1

    Returns
    -------
    state : after the last sample
    estimates : (n_outputs, p, n) x_k = R_k^{-1} b_k of every sample
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    phi = np.atleast_2d(np.asarray(regressors, dtype=float))
    p, n = phi.shape
    if y.shape[-1] != n or state.information.shape != (p, p) or y.shape[0] != \
            state.moment.shape[1]:
        raise DimensionError(f"rls_update: y {y.shape}, regressors {phi.shape}, state for "
                             f"{state.information.shape[0]} regressors and "
                             f"{state.moment.shape[1]} outputs")
    if n == 0:
        return state, np.zeros((y.shape[0], p, 0))
    a = [1.0, -lam]
    outer = (phi[:, None, :] * phi[None, :, :]).reshape(p * p, n)
    from scipy.signal import lfilter  # the reference form only; keeps start-up light

    info = lfilter([1.0], a, outer, axis=-1, zi=lam * state.information.reshape(-1, 1))[0]
    cross = (phi[:, None, :] * y[None, :, :]).reshape(p * y.shape[0], n)
    mom = lfilter([1.0], a, cross, axis=-1, zi=lam * state.moment.reshape(-1, 1))[0]
    info = info.reshape(p, p, n)
    mom = mom.reshape(p, y.shape[0], n)
    x = np.linalg.solve(info.transpose(2, 0, 1), mom.transpose(2, 0, 1))     # (n, p, n_out)
    new = RlsState(information=info[:, :, -1].copy(), moment=mom[:, :, -1].copy(),
                   count=state.count + n)
    return new, x.transpose(2, 1, 0)


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
    :mod:`forcecal.harmonics` for as long as the frequency is not changed.
    """
    step = f0 / fs
    return HarmonicState(demod=np.zeros((n_channels, n_harmonics + 1), dtype=complex),
                         energy=np.zeros(n_channels),
                         phase=float((f0 * t0 - step) % 1.0), step=float(step))


def _window_sums(lam: float, step: float, n_harmonics: int,
                 count: np.ndarray | None) -> np.ndarray:
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
    a = a.reshape(2 * ng, p * p)
    a.setflags(write=False)
    return a


def _assemble(g: np.ndarray) -> np.ndarray:
    """Information matrix (..., p, p) from the window sums g (..., 2H+1)."""
    h = (g.shape[-1] - 1) // 2
    flat = np.concatenate([g.real, g.imag], axis=-1) @ _assembly(h)
    return flat.reshape(*g.shape[:-1], 2 * h + 1, 2 * h + 1)


def harmonic_information(lam: float, step: float, n_harmonics: int,
                         count: int | np.ndarray | None = None,
                         prior: float = PRIOR) -> np.ndarray:
    """Information matrix M_k of the harmonic regressor in the rotating frame.

    Parameters
    ----------
    lam : forgetting factor
    step : [cycles per sample] f0 / fs
    n_harmonics : H
    count : samples seen, scalar or (n,); None for the stationary value (count -> infinity)
    prior : r0

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
def _stationary(lam: float, step: float, n_harmonics: int) -> tuple[np.ndarray, np.ndarray,
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
    """

    rotor: np.ndarray
    weight: np.ndarray
    back: np.ndarray
    power: np.ndarray


@lru_cache(maxsize=8)
def _tables(lam: float, step: float, n_harmonics: int, length: int) -> _Tables:
    i = np.arange(length)
    first = np.exp(-2j * np.pi * np.mod(step * (i + 1), 1.0))
    rotor = np.empty((n_harmonics + 1, length), dtype=complex)
    rotor[0] = 1.0
    for n in range(1, n_harmonics + 1):
        np.multiply(rotor[n - 1], first, out=rotor[n])
    power = lam ** i.astype(float)
    t = _Tables(rotor=rotor, weight=rotor / power, back=rotor.conj() * power, power=power)
    for a in (t.rotor, t.weight, t.back, t.power):
        a.setflags(write=False)
    return t


def steady_count(lam: float) -> int:
    """Samples after which M_k is stationary to rounding (lambda^k < STEADY_TOL)."""
    return int(math.ceil(math.log(STEADY_TOL) / math.log(lam)))


def chunk_limit(lam: float) -> int:
    """Longest stretch summed at once: lambda^-n stays below 4."""
    return max(1, int(_GROWTH / -math.log(lam)))


def _to_real(z: np.ndarray) -> np.ndarray:
    """Complex (..., H+1, n) -> real (..., 2H+1, n): [Re z0, Re z1, Im z1, ...]."""
    h = z.shape[-2] - 1
    out = np.empty((*z.shape[:-2], 2 * h + 1, z.shape[-1]))
    out[..., 0, :] = z[..., 0, :].real
    out[..., 1::2, :] = z[..., 1:, :].real
    out[..., 2::2, :] = z[..., 1:, :].imag
    return out


def _to_complex(u: np.ndarray) -> np.ndarray:
    """Real (..., 2H+1, n) -> complex (..., H+1, n); inverse of :func:`_to_real`."""
    z = np.empty((*u.shape[:-2], (u.shape[-2] + 1) // 2, u.shape[-1]), dtype=complex)
    z[..., 0, :] = u[..., 0, :]
    z[..., 1:, :] = u[..., 1::2, :] + 1j * u[..., 2::2, :]
    return z


def _mixing(readout: np.ndarray, lam: float, step: float, n_harmonics: int) -> np.ndarray:
    """Readout (n_out, n_ch, p) of u -> complex kappa (n_out, H+1, n_ch) acting on the rotated
    right-hand side: readout . u = Re(sum kappa . beta_complex) with u = M^-1 beta."""
    k = readout @ _stationary(lam, step, n_harmonics)[1]
    kap = np.empty((k.shape[0], n_harmonics + 1, k.shape[1]), dtype=complex)
    kap[:, 0] = k[..., 0]
    kap[:, 1:] = (k[..., 1::2] - 1j * k[..., 2::2]).transpose(0, 2, 1)
    return kap


def harmonic_update(state: HarmonicState, y: np.ndarray, lam: float,
                    readout: np.ndarray | None = None,
                    prior: float = PRIOR) -> tuple[HarmonicState, np.ndarray]:
    """Exact RLS of harmonic regressors over a block, at the state's constant frequency.

    Parameters
    ----------
    state : after the previous sample (:func:`harmonic_start` at first)
    y : (n_channels, n) [unit of each channel]
    lam : forgetting factor, 0 < lambda < 1
    readout : optional (n_out, n_channels, 2H+1) [1/unit]: a linear functional of the
        instantaneous harmonic components u_{c,k} = T_k^T x_{c,k} ([U_0, Re U_1, Im U_1, ...]
        with U_n = X_n exp(j n theta_k), so that Re U_n is harmonic n's value at sample k)
    prior : r0 of :func:`rls_start`

    Returns
    -------
    state : after the last sample
    out : without ``readout``, (n_channels, H+1, n) complex phasors X_n(k), referred to the
        phase theta_k (the RLS estimate x_k, as :func:`rls_update` with the regressor of
        :func:`forcecal.harmonics.design_matrix`); with it, (n_out, n) sum_c readout_c . u_c
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    if y.shape[0] != state.demod.shape[0]:
        raise DimensionError(f"harmonic_update: {y.shape[0]} channels given, the state holds "
                             f"{state.demod.shape[0]}")
    h = state.n_harmonics
    limit = chunk_limit(lam)
    n = y.shape[-1]
    tables = _tables(lam, state.step, h, max(1, min(limit, n)))
    kap = None if readout is None else _mixing(readout, lam, state.step, h)
    pieces = []
    for start in range(0, max(n, 1), limit):
        state, out = _kernel(state, y[:, start:start + limit], lam, tables, readout, kap, prior)
        pieces.append(out)
    return state, pieces[0] if len(pieces) == 1 else np.concatenate(pieces, axis=-1)


def _kernel(state: HarmonicState, y: np.ndarray, lam: float, tables: _Tables,
            readout: np.ndarray | None, kap: np.ndarray | None,
            prior: float) -> tuple[HarmonicState, np.ndarray]:
    """One piece of at most ``chunk_limit(lam)`` samples (the tables' length or less)."""
    n_ch, c = y.shape
    h = state.n_harmonics
    if c == 0:
        if readout is None:
            return state, np.zeros((n_ch, h + 1, 0), dtype=complex)
        return state, np.zeros((readout.shape[0], 0))
    start = np.exp(-2j * np.pi * state.phase * np.arange(h + 1))[:, None]
    weight = tables.weight[:, :c] * start                         # lambda^-i exp(-j n theta_i)
    power = tables.power[:c]
    last = power[c - 1]
    new = HarmonicState(demod=lam * last * state.demod + last * (y @ weight.T),
                        energy=lam * last * state.energy + (y * y) @ power[::-1],
                        phase=float((state.phase + state.step * c) % 1.0),
                        step=state.step, count=state.count + c)
    steady = state.count >= steady_count(lam)
    if kap is not None and steady:
        # forces straight from the mixed, demodulated channels: Re sum_n kappa . beta_n
        acc = np.cumsum((kap @ y) * weight, axis=-1)                # (n_out, H+1, c)
        acc += lam * np.sum(kap * state.demod.T, axis=-1)[..., None]
        return new, np.einsum("onj,nj->oj", acc, tables.back[:, :c] * start.conj()).real
    acc = np.cumsum(y[:, None, :] * weight, axis=-1)                # (n_ch, H+1, c)
    acc += lam * state.demod[..., None]
    beta = _to_real(acc * (tables.back[:, :c] * start.conj()))     # (n_ch, p, c)
    if steady:
        u = np.einsum("pq,cqj->cpj", _stationary(lam, state.step, h)[1], beta)
    else:
        info = harmonic_information(lam, state.step, h, state.count + np.arange(1, c + 1),
                                    prior)
        u = np.linalg.solve(info, beta.transpose(2, 1, 0)).transpose(2, 1, 0)
    if readout is None:
        return new, _to_complex(u) * (tables.rotor[:, :c] * start)
    return new, np.einsum("ocp,cpj->oj", readout, u)


def _last_coefficients(state: HarmonicState, lam: float, prior: float) -> np.ndarray:
    """(n_channels, p) rotated coefficients u of the last sample."""
    h = state.n_harmonics
    rot = np.exp(-2j * np.pi * state.phase * np.arange(h + 1))
    beta = _to_real((state.demod * rot.conj())[..., None])[..., 0]     # (n_ch, p)
    if state.count >= steady_count(lam):
        info = _stationary(lam, state.step, h)[0]
    else:
        info = harmonic_information(lam, state.step, h, max(state.count, 1), prior)
    return np.linalg.solve(info, beta.T).T


# --------------------------------------------------------------------------------------------
# the stateful estimator


class StreamEstimator:
    """Forces of a live acquisition, one block of samples after another.

    Parameters
    ----------
    rig : the rig (channel names and scales, gauges, force points, probes)
    model : the spatial model from the scan (shapes and mass couplings)
    f0_guess : [Hz] the drive frequency to start from (tracked from then on)
    fs : [Hz] sampling rate of the acquisition
    n_harmonics : H, harmonics 0..H are tracked (default: as many as the scan was fitted with)
    forgetting : lambda (default: a memory of ``DEFAULT_MEMORY_PERIODS`` periods,
        lambda = 1 - f0 / (2 fs))
    t0 : [s] absolute time of the first sample (phasors then follow the batch convention)
    track_frequency : follow a drift of the drive frequency (phase-locked to the current)
    sensor_std : (n_sensors,) [m] noise of each probe, weights of the Q_n fit (default: equal)
    tare_dc : (n_gauges,) [N] gauge DC of a zero-current record, subtracted
    ac_coupled : the gauges do not measure DC: no DC force; the static estimate is AC only
    extra_harmonics : harmonics without a shape in the model that enter the force anyway
        (reactions only, their inertia uncompensated); by default the force holds the DC and
        the model's harmonics, as the batch estimate does when the others are not significant

    Channel order of an array block: :attr:`channel_names` (gauges, probes, current), raw
    values as recorded (the rig's scales are applied here).

    The state is of fixed size (:class:`HarmonicState` plus the frequency loop's scalars), so
    memory does not grow with the number of blocks; per-frequency tables and inverses are
    kept in small bounded caches. The probes' weights are fixed (``sensor_std``), where the
    batch estimate takes them from each probe's fit residual; with probes of equal noise the
    two agree.
    """

    def __init__(self, rig: Rig, model: SpatialModel, f0_guess: float, fs: float, *,
                 n_harmonics: int | None = None, forgetting: float | None = None,
                 t0: float = 0.0, track_frequency: bool = True,
                 sensor_std: Sequence[float] | np.ndarray | None = None,
                 tare_dc: Sequence[float] | np.ndarray | None = None, ac_coupled: bool = False,
                 extra_harmonics: Sequence[int] = ()) -> None:
        if not (fs > 0 and f0_guess > 0):
            raise InputError(f"stream: fs and f0_guess must be positive; got fs = {fs} Hz, "
                             f"f0_guess = {f0_guess} Hz")
        h = int(n_harmonics or len(model.snr))
        if h < 1:
            raise InputError(f"stream: n_harmonics must be >= 1; got {h}")
        if h * f0_guess * (1 + FREQUENCY_RANGE) >= 0.5 * fs:
            raise DataError(f"stream: harmonic {h} of {f0_guess:.6g} Hz is not below the "
                            f"Nyquist frequency {0.5 * fs:.6g} Hz of fs = {fs:.6g} Hz; "
                            "reduce n_harmonics")
        lam = 1.0 - f0_guess / (fs * DEFAULT_MEMORY_PERIODS) if forgetting is None \
            else float(forgetting)
        if not 0.0 < lam < 1.0:
            raise InputError(f"stream: the forgetting factor must lie in (0, 1); got {lam}")
        if 1.0 / (1.0 - lam) < 2 * (2 * h + 1):
            raise InputError(f"stream: forgetting {lam} keeps a memory of "
                             f"{1 / (1 - lam):.3g} samples, less than twice the "
                             f"{2 * h + 1} regressors of {h} harmonics")
        if abs(f0_guess / model.f0 - 1.0) > FREQUENCY_MISMATCH:
            warnings.warn(f"stream: drive at {f0_guess:.4g} Hz but the scan model was measured "
                          f"at {model.f0:.4g} Hz; its shapes may not apply", stacklevel=2)
        self.rig = rig
        self.model = model
        self.fs = float(fs)
        self.lam = lam
        self.prior = PRIOR
        self.n_harmonics = h
        self.f0_guess = float(f0_guess)
        self.track_frequency = bool(track_frequency)
        self.ac_coupled = bool(ac_coupled)
        self.channel_names: tuple[str, ...] = (*rig.gauge_names, *rig.sensor_names,
                                               rig.actuator.current)
        self.force_names: tuple[str, ...] = tuple(rig.force_names)
        self._scale = np.array([g.scale for g in rig.gauges] + [s.scale for s in rig.sensors]
                               + [rig.actuator.current_scale])[:, None]
        self._n_g, self._n_s = len(rig.gauges), len(rig.sensors)
        self._pinv = np.linalg.pinv(force_matrix(rig))                   # (n_f, n_g)
        n_f = self._pinv.shape[0]
        self._n_f = n_f
        tare = np.zeros(self._n_g) if tare_dc is None else np.asarray(tare_dc, dtype=float)
        if tare.shape != (self._n_g,):
            raise DimensionError(f"stream: tare_dc has shape {tare.shape}; expected "
                                 f"({self._n_g},), one DC per gauge")
        self._offset = (self._pinv @ tare)[:, None]
        self._shaped = self._shape_terms(sensor_std)
        self._force_harmonics = sorted(
            ({0} if not ac_coupled else set()) | {n for n, _ in self._shaped}
            | {int(n) for n in extra_harmonics if 1 <= int(n) <= h})
        # frequency loop
        self.grid = max(1, round(fs / f0_guess))
        self._piece = min(self.grid, chunk_limit(lam))
        memory_s = 1.0 / ((1.0 - lam) * fs)
        w_loop = min(1.0 / (LOOP_MEMORIES * memory_s), LOOP_MAX_STEP * fs / self.grid)
        self._kp, self._ki = 2.0 * LOOP_DAMPING * w_loop, w_loop**2
        # the window's phase lags by its mean age lam / (1 - lam) samples: the loop adds that
        # lead (in grid steps) to act on the phase of the latest sample
        self._lead = lam / (1.0 - lam) / self.grid
        # the loop starts once the window is well conditioned (spans whole periods)
        self._engage = math.ceil(max(ENGAGE_MEMORIES / (1.0 - lam),
                                     ENGAGE_PERIODS * fs / f0_guess))
        self._loop_phase: float | None = None
        self._loop_x1 = 0j
        self._loop_integral = 0.0
        self._warned = False
        self._state = harmonic_start(len(self.channel_names), h, f0_guess, fs, t0)
        self._t0 = float(t0)
        self._retune()

    def _retune(self) -> None:
        """Readout, mixing and per-sample tables for the state's frequency."""
        step = self._state.step
        self._readout = self._force_readout(2 * np.pi * step * self.fs)
        self._kappa = _mixing(self._readout, self.lam, step, self.n_harmonics)

    # ------------------------------------------------------------------ set-up

    def _shape_terms(self, sensor_std) -> list[tuple[int, np.ndarray]]:
        """[(n, B_n)], B_n (n_f, n_s) complex: F_n gains -(n w)^2 B_n S_n from the probes."""
        rig, model = self.rig, self.model
        if sensor_std is None:
            weight = np.ones(self._n_s)
        else:
            std = np.asarray(sensor_std, dtype=float)
            if std.shape != (self._n_s,) or np.any(std <= 0):
                raise InputError(f"stream: sensor_std must hold {self._n_s} positive values; "
                                 f"got {std}")
            weight = 1.0 / std**2
        terms = []
        for k, n in enumerate(model.harmonics):
            n = int(n)
            if n > self.n_harmonics:
                continue
            gain = sensor_gain(model, rig, n)
            if gain < MIN_SENSOR_GAIN:
                raise ConditioningError(
                    f"stream: sensors {', '.join(rig.sensor_names)} sit near a node of the "
                    f"harmonic-{n} shape (they see {gain:.1%} of its peak; at least "
                    f"{MIN_SENSOR_GAIN:.0%} is needed): move a sensor")
            phi = sensor_rows(model, rig, n)
            coef = weight * np.conj(phi) / np.sum(weight * np.abs(phi) ** 2)
            terms.append((n, np.outer(self._pinv @ model.couplings[k], coef)))
        return terms

    def _force_readout(self, w: float) -> np.ndarray:
        """(n_out, n_channels, p) readout of the forces (and, AC-coupled, of the static DC)."""
        n_f, n_g, n_s = self._n_f, self._n_g, self._n_s
        n_out = 2 * n_f if self.ac_coupled else n_f
        c = np.zeros((n_out, len(self.channel_names), 2 * self.n_harmonics + 1))
        for n in self._force_harmonics:
            c[:n_f, :n_g, 0 if n == 0 else 2 * n - 1] = -self._pinv
        for n, b in self._shaped:
            a = -((n * w) ** 2) * b
            c[:n_f, n_g:n_g + n_s, 2 * n - 1] = a.real
            c[:n_f, n_g:n_g + n_s, 2 * n] = -a.imag
        if self.ac_coupled:
            c[n_f:, :n_g, 0] = -self._pinv
        return c

    # ------------------------------------------------------------------ properties

    @property
    def state(self) -> HarmonicState:
        """The current :class:`HarmonicState` (read only; fixed size)."""
        return self._state

    @property
    def frequency(self) -> float:
        """[Hz] the tracked drive frequency."""
        return self._state.step * self.fs

    @property
    def memory(self) -> float:
        """[samples] memory 1 / (1 - lambda) of the forgetting."""
        return 1.0 / (1.0 - self.lam)

    @property
    def latency_periods(self) -> float:
        """Group delay lambda / (1 - lambda) samples of the estimate, in drive periods."""
        return self.lam / (1.0 - self.lam) * self._state.step

    def settling_periods(self, fraction: float = 1e-3) -> float:
        """Drive periods after which a step has settled to ``fraction`` of its size."""
        return math.log(fraction) / math.log(self.lam) * self._state.step

    @property
    def phasors(self) -> np.ndarray:
        """(n_channels, H+1) complex [SI] phasors of the last sample, referred to the tracked
        phase (the batch convention while the frequency has not moved)."""
        u = _last_coefficients(self._state, self.lam, self.prior)
        rot = np.exp(-2j * np.pi * self._state.phase * np.arange(self.n_harmonics + 1))
        return _to_complex(u[..., None])[..., 0] * rot

    @property
    def channel_std(self) -> np.ndarray:
        """(n_channels,) [SI] residual std of every channel over the window (NaN before the
        window holds more samples than regressors)."""
        st = self._state
        u = _last_coefficients(st, self.lam, self.prior)
        h = self.n_harmonics
        rot = np.exp(-2j * np.pi * st.phase * np.arange(h + 1))
        beta = _to_real((st.demod * rot.conj())[..., None])[..., 0]
        rss = np.maximum(st.energy - np.sum(beta * u, axis=1), 0.0)
        weight = (1.0 - self.lam**st.count) / (1.0 - self.lam)
        dof = weight - (2 * h + 1)
        return np.sqrt(rss / dof) if dof > 0 else np.full(len(self.channel_names), np.nan)

    def noise_std(self, channel_std: Sequence[float] | np.ndarray) -> np.ndarray:
        """(n_forces,) [N] steady-state std of each force estimate for white noise.

        Parameters
        ----------
        channel_std : (n_channels,) [SI] noise std of each channel (:attr:`channel_std`)
        """
        sigma = np.asarray(channel_std, dtype=float)
        cov = _stationary(self.lam, self._state.step, self.n_harmonics)[2]
        k = self._readout[:self._n_f]                                    # (n_f, n_ch, p)
        var = np.einsum("fcp,pq,fcq->fc", k, cov, k)
        return np.sqrt(var @ sigma**2)

    # ------------------------------------------------------------------ streaming

    def _samples(self, block: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
        if isinstance(block, Mapping):
            missing = [n for n in self.channel_names if n not in block]
            if missing:
                raise DataError(f"stream: channel '{missing[0]}' named in the rig is missing "
                                f"from the block (found: {', '.join(sorted(block))})")
            rows = [np.asarray(block[n], dtype=float).ravel() for n in self.channel_names]
            lengths = {len(r) for r in rows}
            if len(lengths) != 1:
                raise DimensionError("stream: the channels of a block differ in length: "
                                     + ", ".join(f"{n} {len(r)}" for n, r in
                                                 zip(self.channel_names, rows, strict=True)))
            y = np.stack(rows)
        else:
            y = np.asarray(block, dtype=float)
            if y.shape == (len(self.channel_names),):                 # a single sample
                y = y[:, None]
            if y.ndim != 2 or y.shape[0] != len(self.channel_names):
                raise DimensionError(f"stream: a block must be ({len(self.channel_names)}, n) "
                                     f"for channels {', '.join(self.channel_names)}; got shape "
                                     f"{y.shape}")
        if not np.isfinite(y).all():
            bad = ~np.isfinite(y)
            row, col = np.argwhere(bad)[0]
            t = self._t0 + (self._state.count + col) / self.fs
            raise DataError(f"stream: channel '{self.channel_names[row]}' has "
                            f"{int(bad[row].sum())} NaN or infinite samples in this block, "
                            f"the first at t={t:.6g} s")
        return y * self._scale

    def process(self, block: Mapping[str, np.ndarray] | np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Forces of every sample of a block.

        Parameters
        ----------
        block : {channel name: (n,) raw samples} or (n_channels, n) raw samples in the order
            of :attr:`channel_names` ((n_channels,) for a single sample)

        Returns
        -------
        force : (n_forces, n) [N] sum_n Re(F_n(k) exp(j n theta_k)) with the phasors of each
            sample (inertia compensated)
        static : (n_forces, n) [N] the reactions-only estimate -Psi^+ R(t_k), sample by sample
        """
        y = self._samples(block)
        n = y.shape[1]
        out = np.empty((self._readout.shape[0], n))
        pos = 0
        while pos < n:
            stop = min(n, pos + self.grid - self._state.count % self.grid, pos + self._piece)
            # tables as long as the piece (rounded up to a power of two), cached per frequency
            length = min(self._piece, 1 << (stop - pos - 1).bit_length())
            tables = _tables(self.lam, self._state.step, self.n_harmonics, length)
            self._state, out[:, pos:stop] = _kernel(
                self._state, y[:, pos:stop], self.lam, tables, self._readout, self._kappa,
                self.prior)
            pos = stop
            if self._state.count % self.grid == 0:
                self._on_grid()
        force = out[:self._n_f]
        static = -(self._pinv @ y[:self._n_g])
        if self.ac_coupled:
            static -= out[self._n_f:]
        else:
            force += self._offset
            static += self._offset
        return force, static

    def _on_grid(self) -> None:
        """The frequency loop, once per grid step."""
        st = self._state
        if not self.track_frequency or st.count < self._engage:
            return
        ic = len(self.channel_names) - 1
        u = _last_coefficients(replace(st, demod=st.demod[ic:], energy=st.energy[ic:]),
                               self.lam, self.prior)[0]
        x1 = complex(u[1], u[2]) * np.exp(-2j * np.pi * st.phase)
        # lock: |X_1| against its noise, from the current's residual over the window
        rot = np.exp(-2j * np.pi * st.phase * np.arange(self.n_harmonics + 1))
        beta = _to_real((st.demod[ic] * rot.conj())[:, None])[:, 0]
        weight = (1.0 - self.lam**st.count) / (1.0 - self.lam)
        dof = max(weight - u.size, 1.0)
        var = max(st.energy[ic] - beta @ u, 0.0) / dof
        cov = _stationary(self.lam, st.step, self.n_harmonics)[2]
        if abs(x1) <= LOCK_SNR * math.sqrt(var * 0.5 * (cov[1, 1] + cov[2, 2])):
            self._loop_phase = None                                   # hold; re-engage later
            return
        w0 = 2 * np.pi * self.f0_guess
        if self._loop_phase is None:                  # (re)start from the present frequency
            self._loop_phase, self._loop_x1 = 0.0, x1
            self._loop_integral = 2 * np.pi * st.step * self.fs - w0
            return
        advance = float(np.angle(x1 * np.conj(self._loop_x1)))
        self._loop_phase += advance
        self._loop_x1 = x1
        error = self._loop_phase + self._lead * advance
        dt = self.grid / self.fs
        self._loop_integral += self._ki * error * dt
        w = w0 + self._kp * error + self._loop_integral
        bounded = min(max(w, w0 * (1 - FREQUENCY_RANGE)), w0 * (1 + FREQUENCY_RANGE))
        if bounded != w:                                              # no wind-up
            self._loop_integral += bounded - w
            w = bounded
        self._state = replace(st, step=w / (2 * np.pi * self.fs))
        self._retune()
        if not self._warned and abs(self.frequency / self.model.f0 - 1) > FREQUENCY_MISMATCH:
            self._warned = True
            warnings.warn(f"stream: the drive moved to {self.frequency:.4g} Hz but the scan "
                          f"model was measured at {self.model.f0:.4g} Hz; its shapes may not "
                          "apply", stacklevel=3)


# --------------------------------------------------------------------------------------------
# recorded runs


def replay(rig: Rig, model: SpatialModel, run: Run, block: int = 256, *,
           f0_guess: float | None = None, n_harmonics: int | None = None,
           forgetting: float | None = None, track_frequency: bool = True,
           sensor_std: Sequence[float] | np.ndarray | None = None, tare: Run | None = None,
           ac_coupled: bool = False, extra_harmonics: Sequence[int] = ()
           ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Feed a recorded run block by block, as a live acquisition would.

    Parameters
    ----------
    block : samples per block
    f0_guess : [Hz] start of the frequency tracking (default: the scan model's fundamental)
    tare : a zero-current record whose gauge DC is subtracted (as in the batch estimate)
    others : as :class:`StreamEstimator`

    Returns
    -------
    time : (n_samples,) [s]
    forces : {force name: (n_samples,) [N]}
    static : {force name: (n_samples,) [N]} reactions-only
    """
    if int(block) != block or block < 1:
        raise InputError(f"stream: block must be a positive whole number of samples; "
                         f"got {block}")
    block = int(block)
    tare_dc = None
    if tare is not None:
        tare_dc = [g.scale * tare.channel(g.name).mean() for g in rig.gauges]
    est = StreamEstimator(rig, model, f0_guess or model.f0, run.fs, n_harmonics=n_harmonics,
                          forgetting=forgetting, t0=run.t0, track_frequency=track_frequency,
                          sensor_std=sensor_std, tare_dc=tare_dc, ac_coupled=ac_coupled,
                          extra_harmonics=extra_harmonics)
    raw = np.stack([run.channel(name) for name in est.channel_names])
    n = raw.shape[1]
    force = np.empty((len(est.force_names), n))
    static = np.empty_like(force)
    for start in range(0, n, block):
        force[:, start:start + block], static[:, start:start + block] = \
            est.process(raw[:, start:start + block])
    names = est.force_names
    return (run.time, {k: force[i] for i, k in enumerate(names)},
            {k: static[i] for i, k in enumerate(names)})


def write_stream_csv(path: str | Path, time: np.ndarray, forces: Mapping[str, np.ndarray],
                     static: Mapping[str, np.ndarray]) -> Path:
    """Write a streamed estimate with the columns of ``reconstruct``'s ``NAME.forces.csv``:
    ``time``, one per force, ``total``, then the same with suffix ``_static`` [N].

    A path ending in ``.h5``/``.hdf5`` is written as HDF5 (one dataset per column, the
    layout of a run file), which is an order of magnitude faster than text for long streams.
    """
    if list(forces) != list(static):
        raise InputError(f"table '{path}': forces {list(forces)} and static {list(static)} "
                         "name different forces")
    cols = {name: np.asarray(v, dtype=float) for name, v in forces.items()}
    cols["total"] = np.sum(list(cols.values()), axis=0)
    stat = {f"{name}_static": np.asarray(v, dtype=float) for name, v in static.items()}
    stat["total_static"] = np.sum(list(stat.values()), axis=0)
    if Path(path).suffix.lower() in (".h5", ".hdf5"):
        return write_table_hdf5(path, time, {**cols, **stat})
    return write_table_csv(path, time, {**cols, **stat})
