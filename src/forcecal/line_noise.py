"""The noise level at each harmonic, from the spectral lines around it (METHOD.md section 6).

A harmonic's phasor is disturbed by the noise *at its frequency*, not by the record's noise on
average: 1/f noise is stronger near 0 Hz, and mains hum puts its power on a few lines that a
harmonic away from them never sees. So both readers of harmonics estimate each harmonic's noise
from the lines of a spectrum around it:

- a spectrum scan (:mod:`forcecal.scan_spectra`) from the exported lines themselves;
- a time record (:func:`forcecal.harmonics.fit_harmonics`) from the spectrum of its fit's
  residual (rectangular window, as the least-squares fit itself: for noise whose spectrum is
  flat around n f0, E|X_k|^2 / N is the sigma^2 for which Re and Im of X_n have the
  variance sigma^2 (A^T A)^-1 of the fit).

A harmonic's noise lines lie around its own line, leaving out :data:`GUARD` lines either side of
every harmonic (where the signal, or the fit's removal of it, sits). Their power is modelled as
a record's level times a harmonic's profile, var(k, n) = a_k b_n: the level (the record's gain,
a spot's speckle) from the record's lines at every harmonic, the profile (the noise's colour,
common to the records of one fit) from every record's lines at that harmonic; each a median over
its lines divided by the expected median of as many exponential variables (of as many averages
of exponentials, when the lines are averaged over segments): unbiased for Gaussian noise,
hardly moved by a hum line or its leakage, and pooled, so that a few lines per harmonic still
give a steady estimate.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.special import gammaincinv

__all__ = ["GUARD", "RUNNING", "STRONG", "clear_lines", "expected_median", "line_power",
           "noise_power", "noise_windows", "strong_lines"]

GUARD = 2
"""Lines either side of every harmonic's line left out of its noise estimate."""
STRONG = 20.0
"""A line is a tone (:func:`strong_lines`) when its power exceeds this many times the local noise
level: noise alone does so once in e^20 (5e8) lines."""
RUNNING = 33
"""Lines of the blocks whose medians give the local noise level of their lines."""


def clear_lines(n_lines: int, avoid: np.ndarray) -> np.ndarray:
    """The lines of a spectrum of ``n_lines`` more than :data:`GUARD` lines from every position
    in ``avoid`` (the harmonics, 0 Hz included): the lines that may hold only noise."""
    k = np.arange(n_lines)
    out: np.ndarray = k[_distance(k, np.sort(np.asarray(avoid, dtype=float))) > GUARD]
    return out


def noise_windows(centres: np.ndarray, avoid: np.ndarray, spacing: float, n_lines: int,
                  min_lines: int = 0) -> list[np.ndarray]:
    """The noise lines of each harmonic: those within half a harmonic spacing of its line
    (widened a line at a time on both sides while fewer than ``min_lines``), more than
    :data:`GUARD` lines from every line of ``avoid``, inside the spectrum.

    Parameters
    ----------
    centres : (m,) float array
        Each harmonic's position in lines (fractional for a record that does not span a whole
        number of periods).
    avoid : (p,) float array
        The positions of every harmonic, 0 Hz and the one above the last included.
    spacing : float
        The harmonics' spacing in lines, f0 / df.
    n_lines : int
        The spectrum's number of lines.
    min_lines : int
        Fewest lines wanted per harmonic; 0: the half spacing only.

    Returns
    -------
    list of int arrays
        One per centre; shorter than ``min_lines`` only when the spectrum has no more lines.
    """
    usable = clear_lines(n_lines, avoid)
    windows = []
    for c in np.asarray(centres, dtype=float):
        half = spacing / 2
        while True:
            w = usable[np.abs(usable - c) <= half]
            if w.size >= min_lines or w.size == usable.size:
                break
            half += 1.0
        windows.append(w)
    return windows


def noise_power(power: np.ndarray, windows: list[np.ndarray], segments: int = 1,
                level_lines: np.ndarray | None = None) -> np.ndarray:
    """(n_records, m) expected power E|X|^2 of every record's noise at every harmonic, from the
    power of its noise lines (the model of the module docstring).

    Parameters
    ----------
    power : (n_records, n_lines) array
        |X_k|^2 of every record's lines (averaged over ``segments`` segments).
    windows : list of m int arrays
        Each harmonic's noise lines (:func:`noise_windows`).
    segments : int
        How many periodograms each line averages.
    level_lines : int array, optional
        The lines a record's level is the median of, once (every noise line of a time
        record's spectrum: its level is then steady, and the profile alone is local); by
        default the windows' lines, alternated with the profile.

    Returns
    -------
    (n_records, m) array
    """
    parts = [power[:, w] for w in windows]
    if level_lines is not None:
        level = np.median(power[:, level_lines], axis=1) / expected_median(len(level_lines),
                                                                          segments)
        fixed: np.ndarray = np.outer(level, _profile(parts, level, segments))
        return fixed
    q = sum(p.shape[1] for p in parts)
    profile = np.ones(len(parts))
    level = np.zeros(power.shape[0])
    for _ in range(3):
        pooled = np.concatenate([p / b for p, b in zip(parts, profile, strict=True)], axis=1)
        level = np.median(pooled, axis=1) / expected_median(q, segments)
        profile = _profile(parts, level, segments)
    out: np.ndarray = np.outer(level, profile)
    return out


def _profile(parts: list[np.ndarray], level: np.ndarray, segments: int) -> np.ndarray:
    """Each window's power relative to the records' levels: a median over every record's
    lines of the window."""
    unit = np.where(level > 0, level, 1.0)[:, None]
    profile = np.array([np.median(p / unit) / expected_median(p.size, segments)
                        if p.size else 1.0 for p in parts])
    out: np.ndarray = np.where(profile > 0, profile, 1.0)
    return out


def line_power(segment_of: Callable[[int, int], np.ndarray], n_samples: int, segment: int,
               tones: list[list[float]] | None = None, max_segments: int = 16
               ) -> tuple[np.ndarray, int]:
    """Periodograms |X_k|^2 of records (rectangular window, the fit's own), averaged over up
    to ``max_segments`` segments of ``segment`` samples spread evenly over the records,
    optionally with tones taken out.

    A tone at fractional position p (in lines) puts X_k = c e^{j pi (p - k)(L - 1)/L}
    sinc(p - k) / sinc((p - k) / L) on every line k of L samples, and its image at -p the
    conjugate amplitude: a skirt falling only as 1 / |p - k| that would lift the noise lines
    around it; ``tones`` takes each one out, c fitted to the three lines nearest p.

    Parameters
    ----------
    segment_of : callable
        ``segment_of(start, stop)`` -> (n_records, stop - start) array: the records' samples
        start..stop-1 (a long record's residual is computed a segment at a time).
    n_samples : int
        The records' length.
    segment : int
        Samples per segment (the whole record for a short one).
    tones : list (per record) of positions in lines, optional
        Tones to take out (:func:`strong_lines`).
    max_segments : int

    Returns
    -------
    power : (n_records, segment // 2 + 1) array
        E = segment sigma^2 for white noise of variance sigma^2.
    segments : int
        How many segments were averaged.
    """
    count = min(max(n_samples // segment, 1), max_segments)
    starts = np.unique(np.linspace(0, n_samples - segment, count).round().astype(int))
    k = np.arange(segment // 2 + 1)
    total: np.ndarray | None = None
    for a in starts:
        x = segment_of(int(a), int(a) + segment)
        if total is None:
            total = np.zeros((x.shape[0], len(k)))
        for r, row in enumerate(x):          # a record at a time: memory of one segment
            lines = np.fft.rfft(row)
            for p in (tones[r] if tones is not None else ()):
                lines -= _tone_lines(lines, p, k, segment)
            total[r] += np.abs(lines) ** 2
    assert total is not None
    return total / len(starts), len(starts)


def _tone_lines(lines: np.ndarray, p: float, k: np.ndarray, n: int) -> np.ndarray:
    """A real tone's lines: c K(p) + conj(c) K(-p) on every line, c fitted by least squares
    to the three lines nearest p."""
    both = np.stack([_tone_kernel(p, k, n), _tone_kernel(-p, k, n)])
    j = int(np.clip(round(p), 1, len(k) - 2))
    near = slice(j - 1, j + 2)
    columns = np.stack([both[0, near] + both[1, near], 1j * (both[0, near] - both[1, near])],
                       axis=1)
    design = np.vstack([columns.real, columns.imag])
    u, v = np.linalg.lstsq(design, np.concatenate([lines[near].real, lines[near].imag]),
                           rcond=None)[0]
    out: np.ndarray = (u + 1j * v) * both[0] + (u - 1j * v) * both[1]
    return out


def _tone_kernel(p: float, k: np.ndarray, n: int) -> np.ndarray:
    """Lines k of a unit complex tone at position p over n samples, divided by n."""
    d = p - k
    out: np.ndarray = np.exp(1j * np.pi * d * (n - 1) / n) * np.sinc(d) / np.sinc(d / n)
    return out


def expected_median(q: int, segments: int = 1) -> float:
    """Expected sample median of ``q`` independent unit-mean variables, each the mean of
    ``segments`` exponential variables (numpy's median: the mean of the two middle values when
    q is even). Exact for one segment; for averages, the distribution's median (the sample
    median's expectation for many lines)."""
    if segments > 1:
        return float(gammaincinv(segments, 0.5)) / segments

    def order(r: int) -> float:  # E of the r-th smallest of q: sum_{i=q-r+1..q} 1/i
        return float(np.sum(1.0 / np.arange(q - r + 1, q + 1)))

    return order((q + 1) // 2) if q % 2 else (order(q // 2) + order(q // 2 + 1)) / 2


def strong_lines(power: np.ndarray, segments: int, avoid: np.ndarray, ratio: float = STRONG,
                 most: int = 12) -> list[list[tuple[float, float]]]:
    """Tones standing out of each record's noise: lines whose power exceeds ``ratio`` times
    the local noise level (the median of its block of :data:`RUNNING` lines, scaled to the mean),
    local maxima more than :data:`GUARD` lines from every position in ``avoid``.

    A tone of amplitude a at fractional position p between lines k and k + 1 puts
    |X_k| = (a L / 2) |sinc(p - k)| on a rectangular window's lines, so p follows from the ratio
    of the two largest neighbouring lines, p - k = |X_k+1| / (|X_k| + |X_k+1|), exact for a
    pure tone, and then a from |X_k|.

    Parameters
    ----------
    power : (n_records, n_lines) array
        Periodograms (:func:`line_power`) of records of L samples.
    segments : int
        How many periodograms each line averages.
    avoid : (p,) float array
        Positions (in lines) of the harmonics, 0 Hz included.
    ratio : float
    most : int
        The strongest ``most`` tones of each record are kept.

    Returns
    -------
    list (per record) of (position in lines, a L / 2) pairs
    """
    n_records, n_lines = power.shape
    clear = np.zeros(n_lines, dtype=bool)
    clear[clear_lines(n_lines, avoid)] = True
    full = n_lines // RUNNING
    size = min(RUNNING, n_lines)
    blocks = np.median(power[:, :full * RUNNING].reshape(n_records, full, RUNNING), axis=2)
    tail = np.median(power[:, n_lines - size:], axis=1, keepdims=True)   # the last lines'
    level = np.concatenate([np.repeat(blocks, RUNNING, axis=1),
                            np.repeat(tail, n_lines - full * RUNNING, axis=1)], axis=1)
    level /= expected_median(size, segments)
    peak = np.zeros_like(clear)
    peak[1:-1] = clear[1:-1]
    found = (power[:, 1:-1] >= power[:, :-2]) & (power[:, 1:-1] >= power[:, 2:])
    strong = np.zeros(power.shape, dtype=bool)
    strong[:, 1:-1] = found & peak[None, 1:-1] & (power[:, 1:-1] > ratio * level[:, 1:-1])
    out: list[list[tuple[float, float]]] = []
    for p, lv, hits in zip(power, level, strong, strict=True):
        lines = np.flatnonzero(hits)
        lines = lines[np.argsort(p[lines])[::-1][:most]]
        tones = []
        for j in lines:
            side = j + 1 if p[j + 1] >= p[j - 1] else j - 1
            big, small = np.sqrt(max(p[j] - lv[j], 0.0)), np.sqrt(max(p[side] - lv[side], 0.0))
            frac = small / (big + small) if big + small > 0 else 0.0
            tones.append((float(j + frac * (side - j)), float(big / max(np.sinc(frac), 1e-3))))
        out.append(tones)
    return out


def _distance(k: np.ndarray, avoid: np.ndarray) -> np.ndarray:
    """Distance of each of ``k`` to the nearest of the sorted positions ``avoid``."""
    i = np.clip(np.searchsorted(avoid, k), 1, len(avoid) - 1) if len(avoid) > 1 else None
    if i is None:
        return np.abs(k - avoid[0]) if len(avoid) else np.full(k.shape, np.inf)
    out: np.ndarray = np.minimum(np.abs(k - avoid[i - 1]), np.abs(k - avoid[i]))
    return out
