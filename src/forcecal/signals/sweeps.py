"""A drive whose frequency moves through the record (a sweep, a chirp, a stepped sine), told
from a steady one, so that a steady rig given such records can say what the data hold.

:func:`swept_drive` follows a record's instantaneous frequency as the peak of short-time
spectra (Hann windows, overlapping by three quarters) at the window length that finds a
dominant tone in most windows. A sweep is a tone in most windows whose frequency covers a band
(most of its span visited, its top at least :data:`MIN_RATIO` times its bottom); a steady
drive (with noise, hum, harmonics or a slow drift), noise without a drive and two fixed tones
are not. The band is where the record's spectrum (smoothed over a window's line) stays within
:data:`BAND_LEVEL` of its median over the frequencies the tone visited.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["swept_drive"]

MIN_RATIO = 1.25
"""Top over bottom of the frequencies a tone visits beyond which it sweeps (less is a drift)."""
MIN_TONAL = 0.6
"""Fraction of the windows that must hold a dominant tone."""
TONE_SHARE = 0.5
"""Share of a window's power (mean removed) within two lines of its peak that makes a tone."""
BAND_LEVEL = 0.1
"""The band's edges: where the mean spectrum falls below this fraction of its median over the
visited frequencies."""
_SHORTEST = 64  # [samples] the shortest window tried
_LONGEST = 1 << 15  # [samples] the longest window tried (bounds the memory)
_WINDOWS = 128  # windows at most per length tried
_EDGE_SEGMENT = 1 << 20  # [samples] the longest periodogram of the band's edges
_CELLS = 8  # the visited span in cells...
_VISITED = 6  # ...of which a sweep visits at least these


@dataclass(frozen=True)
class Sweep:
    """The band a swept drive covered in some records.

    Attributes
    ----------
    low, high : float [Hz]
        The band, rounded outwards (whole Hz above 10 Hz).
    swept : int
        The records that sweep...
    records : int
        ...of these.
    """

    low: float
    high: float
    swept: int
    records: int

    @property
    def band(self) -> str:
        """``"[61, 184]"``: the band as a rig's ``acquisition.band`` writes it."""
        return f"[{self.low:g}, {self.high:g}]"

    @property
    def where(self) -> str:
        """``"in each record"`` or ``"in 5 of its 8 records"``."""
        if self.records == 1:
            return "over the record"
        if self.swept == self.records:
            return "in each record"
        return f"in {self.swept} of its {self.records} records"


def swept_drive(records: np.ndarray | Sequence[np.ndarray], fs: float) -> Sweep | None:
    """The band a drive sweeps through, when it does in most of ``records``.

    Parameters
    ----------
    records : (n_records, n_samples) array or sequence of 1-D arrays [any unit]
        Records of the drive (the coil current: a scan's references, a run's current).
    fs : float [Hz]
        Sampling rate.

    Returns
    -------
    Sweep or None
        None when fewer than half the records sweep (steady drives, noise, records too short
        for eight windows of :data:`_SHORTEST` samples). The band is the median of the swept
        records' bands.
    """
    bands = []
    n_records = 0
    for rec in records:
        n_records += 1
        band = _record_band(np.asarray(rec, dtype=float), fs)
        if band is not None:
            bands.append(band)
    if not bands or 2 * len(bands) < n_records:
        return None
    low, high = np.median(np.array(bands), axis=0)
    return Sweep(_outwards(float(low), math.floor), _outwards(float(high), math.ceil),
                 len(bands), n_records)


def _outwards(f: float, to: Callable[[float], int]) -> float:
    """``f`` [Hz] rounded by ``to`` (floor or ceil) to whole Hz, or to 0.1 Hz below 10 Hz."""
    step = 1.0 if f >= 10.0 else 0.1
    return round(to(f / step) * step, 1)


def _spectra(x: np.ndarray, length: int) -> np.ndarray:
    """(n_windows, length // 2 + 1) power spectra of Hann windows of ``x``, each less its
    mean, overlapping by three quarters (at most :data:`_WINDOWS`, spread over the record)."""
    count = min(4 * (x.size // length) - 3, _WINDOWS)
    starts = np.linspace(0, x.size - length, count).astype(int)
    windows = x[starts[:, None] + np.arange(length)]
    windows -= windows.mean(axis=1, keepdims=True)
    return np.abs(np.fft.rfft(windows * np.hanning(length), axis=1)) ** 2


def _track(power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(line of the peak, whether a tone) of every window: a tone holds :data:`TONE_SHARE`
    of its window's power within two lines of the peak, resolved from the mean (line 4 up)."""
    peak = np.argmax(power[:, 1:], axis=1) + 1
    near = np.clip(peak[:, None] + np.arange(-2, 3), 0, power.shape[1] - 1)
    share = np.take_along_axis(power, near, axis=1).sum(axis=1) / np.maximum(
        power.sum(axis=1), 1e-300)
    tonal = (share >= TONE_SHARE) & (peak >= 4) & (peak <= power.shape[1] - 3)
    return peak, tonal


def _record_band(x: np.ndarray, fs: float) -> tuple[float, float] | None:
    """(low, high) [Hz] of the band one record sweeps through, or None."""
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        return None
    x = x - x.mean()
    best: tuple[float, int, np.ndarray, np.ndarray, np.ndarray] | None = None
    length = _SHORTEST
    while length <= min(x.size // 8, _LONGEST):
        power = _spectra(x, length)
        peak, tonal = _track(power)
        if best is None or tonal.mean() >= best[0]:      # ties: the finer lines
            best = (float(tonal.mean()), length, power, peak, tonal)
        length *= 2
    if best is None or best[0] < MIN_TONAL:
        return None
    _, length, power, peak, tonal = best
    f = peak[tonal] * fs / length                         # [Hz] the tone's track
    lo, hi = np.percentile(f, [5, 95])
    cells = np.minimum(((f - lo) / max(hi - lo, 1e-300) * _CELLS).astype(int), _CELLS - 1)
    visited = np.unique(cells[(f >= lo) & (f <= hi)]).size
    if hi - lo < 8 * fs / length or hi < MIN_RATIO * lo or visited < _VISITED:
        return None
    return _band_edges(x, fs, length, (lo, hi), float(np.median(f)))


def _band_edges(x: np.ndarray, fs: float, length: int, visited: tuple[float, float],
                centre: float) -> tuple[float, float]:
    """(low, high) [Hz]: from ``centre`` outwards, the lines of the record's spectrum (its
    plain periodograms of up to :data:`_EDGE_SEGMENT` samples averaged, smoothed over the
    ``fs / length`` of a window's line) that stay within :data:`BAND_LEVEL` of its median over
    ``visited``."""
    segment = min(x.size, _EDGE_SEGMENT)
    mean = np.zeros(segment // 2 + 1)
    for start in range(0, x.size - segment + 1, segment):    # untapered: a taper would
        part = x[start:start + segment]                        # fade a sweep's ends
        mean += np.abs(np.fft.rfft(part - part.mean())) ** 2
    width = max(1, round(segment / length))
    mean = np.convolve(mean, np.ones(width) / width, mode="same")
    spacing = fs / segment
    f = np.arange(mean.size) * spacing
    level = BAND_LEVEL * float(np.median(mean[(f >= visited[0]) & (f <= visited[1])]))
    a = b = int(round(centre / spacing))
    while a > 1 and mean[a - 1] >= level:
        a -= 1
    while b < mean.size - 1 and mean[b + 1] >= level:
        b += 1
    return float(f[a]), float(f[b])
