"""Short-time Wiener smoothing of force estimates whose noise spectrum is known (METHOD.md
section 7, "any drive").

A drive that moves (a sweep, a chirp, a multi-tone, random) holds, at any instant, a few hertz
of the band the smoother of :mod:`forcecal.signals.kalman` lets through; the acceleration's noise,
rising as f^4, fills all of it. Over short frames (Hann, three-quarter overlap, so that the
frames add back to the record) every frequency bin of every estimate is weighted by the gain
G = max(0, 1 - 2 N / |Z|^2), N the bin's noise power known from the channels' noise and the
smoothers' frequency responses, |Z|^2 the bin's power averaged with its neighbours (3 bins by
3 frames): bins far above their noise pass unchanged, bins at their noise are set aside
(power subtraction with over-subtraction; Boll 1979, Berouti et al. 1979). Every sample keeps
a standard uncertainty, summed bin by bin over its frames: the noise the gains let through,
G^2 N, and the signal they take, (1 - G)^2 S with S = G |Z|^2 the power they keep (a bin near
its noise loses part of its signal). The signals smoothed may be any orthonormal combination
of the estimates (the forces' total and its complement): the estimates come back as
combinations of them, each source's parts added with their phases. A steady tone of known
power (mains hum) joins the noise as its window's transform at the frame's bins
(:func:`tone_density`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kalman import BandModel, smooth_states

__all__ = [
    "short_time_variance",
    "smoother_response",
    "stft_frame",
    "tone_density",
    "wiener_smooth",
]

FRAME_SECONDS = 0.2
"""Frame length aimed at: a sweep of tens of hertz per second moves a few bins within it."""


SMOOTH = (3, 3)
"""Bins and frames the power is averaged over before its gain is taken (a noise-only bin's
power then rarely reaches twice its mean)."""
OVER = 2.0
"""Over-subtraction: the gain is 1 - OVER N / |Z|^2 (noise-only bins set aside; a bin 100
times above its noise keeps 98 % of its power)."""


def stft_frame(fs: float, n: int) -> int:
    """Samples per frame: the power of two nearest ``FRAME_SECONDS`` (at most the record)."""
    frame = 2 ** int(round(np.log2(max(FRAME_SECONDS * fs, 16))))
    return int(min(frame, 2 ** int(np.log2(n))))


def smoother_response(model: BandModel, state: int, frame: int) -> np.ndarray:
    """The RTS smoother's frequency response from the measurement to one state, at the
    ``frame // 2 + 1`` bins of a ``frame``-sample transform (its impulse response, computed
    in a record four frames long, folded onto the frame)."""
    n = 4 * frame
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    h = smooth_states(model, impulse, states=(state,))[0]
    return np.fft.rfft(np.roll(h, -n // 2))[::4]


def tone_density(frame: int, fs: float, frequency: float, power: float) -> np.ndarray:
    """(frame // 2 + 1,): a steady tone of squared amplitude ``power`` at ``frequency`` [Hz]
    as :func:`wiener_smooth` takes a noise source: at every bin of a Hann frame, the amplitude
    whose power there is the tone's (A / 2)^2 |W(f_b - f)|^2 / sum(w^2), W the window's
    transform, so that over the bins it adds up to the tone's variance A^2 / 2."""
    import scipy.signal  # on use: a steady stream starts without it

    win = scipy.signal.get_window("hann", frame)
    over = 16
    shape = np.abs(np.fft.rfft(win, over * frame))                # |W| every fs / (16 frame)
    offset = np.abs(np.fft.rfftfreq(frame, 1.0 / fs) - frequency) * over * frame / fs
    at = np.interp(offset, np.arange(shape.size), shape, right=0.0)
    return 0.5 * np.sqrt(power) * at / np.sqrt(np.sum(win**2))


@dataclass(frozen=True)
class ShortTimeWiener:
    """Smoothed estimates and their standard uncertainty, sample by sample.

    Attributes
    ----------
    values : (n_outputs, N) array
        The smoothed signals' combinations asked for (by default each signal).
    std : (n_outputs, N) array
        Of each.
    total : (N,) array
        The last combination (by default the signals' sum).
    total_std : (N,) array
    passed : (n_signals,) array [1]
        Share of each signal's noise power the gains let through (over the record).
    """

    values: np.ndarray
    std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    passed: np.ndarray


def wiener_smooth(x: np.ndarray, noise: np.ndarray, fs: float, frame: int,
                  outputs: np.ndarray | None = None) -> ShortTimeWiener:
    """Short-time Wiener smoothing of signals whose noise comes from known sources.

    Parameters
    ----------
    x : (n_signals, N) array
        The estimates.
    noise : (n_signals, n_sources, frame // 2 + 1) complex array
        Each source's noise in each signal, as the amplitude of its two-sided density per
        sample at the frame's bins (sigma_s T_s(f) c_{k,s}(f): white noise of variance
        sigma_s^2 through the smoother T_s and the signal's coefficient c_{k,s}).
    fs : float [Hz]
    frame : int
        Samples per frame (:func:`stft_frame`).
    outputs : (n_outputs, n_signals) array, optional
        The combinations of the smoothed signals returned, each with its uncertainty (a
        source's parts in several signals add with their phases). By default each signal,
        then their sum as ``total``; with a last row, that row is ``total``.

    Returns
    -------
    ShortTimeWiener
    """
    import scipy.ndimage  # on use: a steady stream starts without it
    import scipy.signal

    n, k = x.shape[-1], x.shape[0]
    rows = np.vstack([np.eye(k), np.ones(k)]) if outputs is None else np.asarray(outputs)
    kw = {"fs": fs, "window": "hann", "nperseg": frame, "noverlap": 3 * frame // 4}
    t, z = scipy.signal.stft(x, boundary="even", padded=True, **kw)[1:]   # (k, bins, frames)
    win = scipy.signal.get_window("hann", frame)
    per_bin = np.sum(win**2) / np.sum(win) ** 2               # |Z|^2 per unit density
    n_pow = np.sum(np.abs(noise) ** 2, axis=1) * per_bin      # (n_signals, n_bins)
    power = scipy.ndimage.uniform_filter(np.abs(z) ** 2, size=(1, SMOOTH[0], SMOOTH[1]),
                                         mode="nearest")
    tiny = np.finfo(float).tiny
    gain = np.clip(1.0 - OVER * n_pow[:, :, None] / np.maximum(power, tiny), 0.0, 1.0)
    smoothed = scipy.signal.istft(gain * z, boundary=True, **kw)[1][..., :n]
    # the noise let through: per frame, sum over bins (both halves of the spectrum), each
    # source's parts in the signals combined with their phases
    fold = np.full(noise.shape[-1], 2.0)
    fold[0] = 1.0
    if frame % 2 == 0:
        fold[-1] = 1.0
    var = np.zeros((len(rows), gain.shape[-1]))
    for source in np.moveaxis(noise, 1, 0):                   # one at a time: memory
        let = np.einsum("ok,kb,kbt->obt", rows, source, gain)
        var += np.einsum("b,obt->ot", fold, np.abs(let) ** 2) / frame
    # what the gains take of the signal itself: (1 - G) of its amplitude, the signal's power
    # read as the power they keep, G |Z|^2 (in density units: the power above the
    # over-subtracted noise; a noise-only bin's excess over its mean is not signal), with the
    # bin's phase, so that the signals' parts add up coherently in a combination
    signal = np.sqrt(gain * power / per_bin)
    cut = np.einsum("ok,kbt->obt", rows, (1.0 - gain) * signal * np.exp(1j * np.angle(z)))
    var = var + np.einsum("b,obt->ot", fold, np.abs(cut) ** 2) / frame
    time = np.arange(n) / fs
    std = np.sqrt(np.stack([np.interp(time, t, v) for v in var]))
    values = rows @ smoothed
    own = np.einsum("kb,kbt->kt", np.sum(np.abs(noise) ** 2, axis=1) * fold, gain**2) / frame
    full = np.sum(np.abs(noise) ** 2, axis=1) @ fold
    passed = np.mean(own, axis=-1) * frame / np.maximum(full, tiny)
    return ShortTimeWiener(values=values[:-1] if outputs is None else values,
                           std=std[:-1] if outputs is None else std, total=values[-1],
                           total_std=std[-1], passed=passed)


def short_time_variance(x: np.ndarray, weight: np.ndarray, fs: float, frame: int) -> np.ndarray:
    """(k, N): sample by sample, the variance of an error that multiplies every frequency of
    the signal ``x`` (N,) by a random factor of variance ``weight`` (k, frame // 2 + 1) at the
    frame's bins (a systematic error of a frequency response, as the scan's operating shapes
    give the inertia): its power summed over each frame's bins, as :func:`wiener_smooth` sums
    the noise it lets through."""
    import scipy.signal  # on use: a steady stream starts without it

    n = x.shape[-1]
    kw = {"fs": fs, "window": "hann", "nperseg": frame, "noverlap": 3 * frame // 4}
    t, z = scipy.signal.stft(x, boundary="even", padded=True, **kw)[1:]   # (bins, frames)
    win = scipy.signal.get_window("hann", frame)
    per_bin = np.sum(win**2) / np.sum(win) ** 2
    fold = np.full(z.shape[0], 2.0)
    fold[0] = 1.0
    if frame % 2 == 0:
        fold[-1] = 1.0
    var = np.einsum("b,kb,bt->kt", fold, weight, np.abs(z) ** 2 / per_bin) / frame
    time = np.arange(n) / fs
    return np.stack([np.interp(time, t, v) for v in var])
