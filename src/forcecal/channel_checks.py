"""What the channels of a run under any drive say of themselves (METHOD.md section 7).

- every channel's white-noise level, read from its spectrum above the scan's band, where the
  drive does not reach (:func:`channel_noise`): the probes' weights and the smoothers' gains
  of :mod:`forcecal.transient` rest on it;
- a gauge or probe that changes while the run goes on, its noise above the band moving far
  from its usual level in some half second (:func:`check_channel_noise`): died, saturated or
  come loose; refused where it happens, in batch and in a stream;
- the drive's force above the scan's band (:class:`AboveBand`): a biased magnet pulls at twice
  its drive's frequencies, where the scan has no operating shape; noted. Its half-second
  reading (:class:`WorstHalfSecond`) serves other notes too
  (:class:`forcecal.inertia_errors.ScanNoiseShare`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.signal

from .errors import DataError, InputError

__all__ = ["ABOVE_BAND", "NOISE_BLOCK", "NOISE_CHANGE", "AboveBand", "WorstHalfSecond",
           "channel_noise", "check_channel_noise"]


def channel_noise(x: np.ndarray, fs: float, band: tuple[float, float]) -> np.ndarray:
    """Each channel's white-noise variance per sample, from its spectrum above the band.

    Parameters
    ----------
    x : (n_channels, N) array
    fs : float [Hz]
    band : (low, high) [Hz]

    Returns
    -------
    (n_channels,) array [unit^2]
        The median one-sided density between 2 x the band's top (at most 0.6 of Nyquist) and
        0.9 of Nyquist, times fs / 2 (Welch's averages are nearly Gaussian, so their median is
        their mean), at least 1e-20 of the channel's mean square (a noise-free channel still
        has a weight).

    Raises
    ------
    InputError
        When the sampling leaves no room above the band.
    """
    nperseg = int(min(x.shape[-1], max(256, 2 ** int(np.log2(fs / 10)))))
    f, p = scipy.signal.welch(x, fs=fs, nperseg=nperseg, axis=-1)
    lo, hi = min(2 * band[1], 0.3 * fs), 0.45 * fs
    sel = (f >= lo) & (f <= hi)
    if np.count_nonzero(sel) < 4:
        raise InputError(f"sampling at {fs:g} Hz leaves no lines above the band's top "
                         f"{band[1]:g} Hz to measure the noise")
    level = np.median(p[..., sel], axis=-1) * fs / 2
    floor = 1e-20 * np.mean(x**2, axis=-1) + np.finfo(float).tiny
    return np.maximum(level, floor)


NOISE_BLOCK = 0.5
"""[s] the stretch over which every channel's noise is checked."""
NOISE_CHANGE = 10.0
"""A channel whose noise variance above the band is this many times (3.2 times in standard
deviation) above or below its usual level in some stretch has changed: died, saturated or come
loose. The level of half a second is read to a few percent."""


def check_channel_noise(gauges: np.ndarray, probes: np.ndarray, names: Sequence[str],
                        fs: float, band: tuple[float, float], t0: float, source: str,
                        reference: np.ndarray | None = None) -> None:
    """Refuse a record in which some gauge or probe changes while it runs: every channel's
    noise above the band (:func:`channel_noise`) over each :data:`NOISE_BLOCK`, against its
    usual level, a change of :data:`NOISE_CHANGE` times either way. A channel whose level is
    its floor (a noise-free record) is not checked.

    Parameters
    ----------
    gauges : (n_gauges, N) array [N]
    probes : (n_probes, N) array [m]
    names : sequence of str
        The gauges' then the probes' channel names.
    fs : float [Hz]
    band : (low, high) [Hz]
    t0 : float [s]
        The time of the first sample.
    source : str
        The run, for the message.
    reference : (n_gauges + n_probes,) array or None
        The usual levels (a stream's, from its first seconds); None takes the median over the
        record's stretches.

    Raises
    ------
    DataError
        Naming the channel, the stretch and the change.
    """
    x = np.vstack([gauges, probes])
    n = int(round(NOISE_BLOCK * fs))
    starts = range(0, x.shape[-1] - n + 1, n)
    if not starts:
        return
    levels = np.column_stack([channel_noise(x[:, k:k + n], fs, band) for k in starts])
    usual = np.median(levels, axis=1) if reference is None else reference
    live = usual > 1e-18 * np.mean(x**2, axis=-1) + np.finfo(float).tiny
    ratio = levels / usual[:, None]
    bad = live[:, None] & ((ratio > NOISE_CHANGE) | (ratio < 1.0 / NOISE_CHANGE))
    if np.any(bad):
        block = int(np.flatnonzero(bad.any(axis=0))[0])
        k = int(np.flatnonzero(bad[:, block])[0])
        when = t0 + block * NOISE_BLOCK
        raise DataError(f"run '{source}': channel '{names[k]}' from {when:.3g} s to "
                        f"{when + NOISE_BLOCK:.3g} s: its noise above the band is "
                        f"{np.sqrt(ratio[k, block]):.3g} times its usual level; a sensor that "
                        "died, saturated or came loose cannot follow any drive")


ABOVE_BAND = 1e-4
"""A run whose drive's i^2 holds more than this share of its AC power above the scan's band,
in some half second, is noted (1 % in amplitude): that content has no operating shape."""


SIGNIFICANT = 5.0
"""A power above the white noise's counts when it exceeds this many times the scatter of the
noise's own Welch estimate summed over the same lines."""


class WorstHalfSecond:
    """The largest of a share read over every complete half second of samples fed as they come
    (:meth:`add`: the whole record in batch, block by block in a stream); a record shorter
    than half a second is read whole. Subclasses say what the share is (:meth:`_share`, of
    a block whose last axis is time).

    Parameters
    ----------
    fs : float [Hz]
    t0 : float [s]
        The time of the first sample.
    least : int
        The fewest samples read at once.
    """

    def __init__(self, fs: float, t0: float = 0.0, least: int = 1):
        self.fs, self.t0 = fs, t0
        self._n = max(int(0.5 * fs), least)
        self._buffer: np.ndarray | None = None
        self._done = 0
        self._worst = (0.0, t0)

    def add(self, samples: np.ndarray) -> None:
        """Feed the next samples (time on the last axis)."""
        self._buffer = (samples if self._buffer is None
                        else np.concatenate([self._buffer, samples], axis=-1))
        while self._buffer.shape[-1] >= self._n:
            share = self._share(self._buffer[..., :self._n])
            if share > self._worst[0]:
                self._worst = (share, self.t0 + self._done / self.fs)
            self._buffer, self._done = self._buffer[..., self._n:], self._done + self._n

    def worst(self) -> tuple[float, float]:
        """(share, the time [s] its half second starts)."""
        if not self._done and self._buffer is not None and self._buffer.shape[-1]:
            return self._share(self._buffer), self.t0
        return self._worst

    def notes(self, source: str) -> tuple[str, ...]:
        """The note on the run ``source``, if its worst half second's share exceeded
        :attr:`limit` (a record shorter than half a second read whole)."""
        share, at = self.worst()
        return () if share <= self.limit else (self._note(source, share, at),)

    limit: float = 0.0
    """The share above which the worst half second is noted."""

    def _share(self, block: np.ndarray) -> float:
        raise NotImplementedError

    def _note(self, source: str, share: float, at: float) -> str:
        raise NotImplementedError


class AboveBand(WorstHalfSecond):
    """A note when the coil current's square (the magnet's force at a fixed gap) holds more
    than ``ABOVE_BAND`` of its AC power above the scan's band in any half second, its white
    noise (:func:`channel_noise`) taken out: that content has no operating shape, so the
    smoothers set it aside and its inertia is not compensated. A biased magnet pulls at twice
    its drive's frequencies, which a scan over the drive's band alone misses.

    The current [A] is fed as it comes (:meth:`add`); every complete half second is read
    once, and the largest share is kept.

    Parameters
    ----------
    fs : float [Hz]
    band : (low, high) [Hz]
    t0 : float [s]
        The time of the first sample.
    """

    def __init__(self, fs: float, band: tuple[float, float], t0: float = 0.0):
        super().__init__(fs, t0, least=256)
        self.band = band

    limit = ABOVE_BAND

    def _note(self, source: str, share: float, at: float) -> str:
        return (f"run '{source}': the drive's force (i^2) holds {100 * np.sqrt(share):.2g} % of "
                f"its AC amplitude above the scan's band ({self.band[1]:g} Hz) in the half "
                f"second from {at:.3g} s: no operating shape is known there, so that part of "
                "the force is only what the gauges' smoother lets through, its inertia "
                "extrapolated from the band's top; scan over a band that covers it (a biased "
                "magnet pulls at twice its drive's frequencies)")

    def _share(self, current: np.ndarray) -> float:
        """The share of the AC power of i^2 above the band, both less the white noise's, or 0
        where either is within ``SIGNIFICANT`` times the noise's own scatter (a current of
        noise alone holds no drive to note)."""
        x = current**2
        nperseg = min(x.size, 1024)
        f, p = scipy.signal.welch(x, fs=self.fs, nperseg=nperseg)
        floor = 2.0 * float(channel_noise(x[None, :], self.fs, self.band)[0]) / self.fs
        averages = max(2 * x.size // nperseg - 1, 1)          # Welch's half-overlapped segments
        above, ac = f > self.band[1], f > 0

        def excess(sel: np.ndarray) -> float:
            power = float(np.sum(p[sel] - floor))
            scatter = floor * np.sqrt(np.count_nonzero(sel) / averages)
            return power if power > SIGNIFICANT * scatter else 0.0

        total = excess(ac)
        return excess(above) / total if total > 0 else 0.0
