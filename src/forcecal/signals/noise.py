"""The standard uncertainty of a time record's harmonics, from its fit's residual (METHOD.md
section 6): what :func:`forcecal.signals.harmonics.fit_harmonics` states as ``phasor_std``.

Two parts, added in variance:

1. **The noise at the harmonic's frequency.** Re and Im of X_n have the variance
   sigma_n^2 diag (A^T A)^-1 of the least-squares fit, sigma_n the level of the residual's
   spectrum around n f0 (at least :data:`MIN_NOISE_LINES` lines clear of every harmonic, the
   tones of part 2 taken out; the harmonic's profile pooled over the records of one fit, a
   record's level the median of all its noise lines). The mean (n = 0) takes at least the
   level of the lowest :data:`LOWEST` lines: 1/f noise rises towards 0 Hz.
2. **Tones leaking into it** (a mains line, a harmonic of the drive above the last fitted):
   the residual's lines that stand :data:`STRONG` times above the local level
   (:func:`strong_lines`), each through the fit's response to a tone of random phase
   (:func:`_leakage`); a record longer than :data:`~forcecal.signals.fundamental.LONG_RECORD`
   samples is read in segments of :data:`SEGMENT` samples.

A tone within :data:`GUARD` lines of a harmonic cannot be told from it and is not counted (a
drive on a mains harmonic; see the guide's section on lab conditions).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .fundamental import LONG_RECORD

__all__ = ["GUARD", "noise_power", "noise_windows"]


# --- from line_noise ---
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
    power of its noise lines.

    A harmonic's phasor is disturbed by the noise at its own frequency (1/f noise is stronger
    near 0 Hz; mains hum sits on a few lines), so its noise lines lie around its own line,
    leaving out :data:`GUARD` lines either side of every harmonic. Their power is modelled as
    a record's level times a harmonic's profile, var(k, n) = a_k b_n: the level (the record's
    gain, a spot's speckle) from the record's lines at every harmonic, the profile (the
    noise's colour, common to the records of one fit) from every record's lines at that
    harmonic; each a median over its lines divided by the expected median of as many
    exponential variables (of as many averages of exponentials, when the lines are averaged
    over segments): unbiased for Gaussian noise, hardly moved by a hum line or its leakage,
    and pooled, so that a few lines per harmonic still give a steady estimate.

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
        from scipy.special import gammaincinv  # on use: a steady stream starts without it

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


# --- from harmonic_noise ---
MIN_NOISE_LINES = 32
"""Fewest spectral lines a harmonic's noise level is estimated from."""
SEGMENT = 1 << 15
"""Samples per segment of a record longer than :data:`~forcecal.signals.fundamental.LONG_RECORD`."""
LOWEST = 4
"""Lines above 0 Hz whose mean power bounds the mean's noise level from below."""

Respond = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``respond(freqs)`` -> the fit's phasors (n_freqs, H+1) of unit cosines and of unit sines at
``freqs`` [Hz] sampled as the record."""


def phasor_noise(segment_of: Callable[[int, int], np.ndarray], n_samples: int, fs: float,
                 f0: float, unit_std: np.ndarray, sigma: np.ndarray, respond: Respond | None
                 ) -> np.ndarray:
    """(n_records, H+1) standard uncertainty of Re and of Im of every record's X_0 .. X_H.

    Parameters
    ----------
    segment_of : callable
        ``segment_of(a, b)``: the residual's samples a..b-1 of every record, (n_records, b - a).
    n_samples : int
    fs, f0 : float [Hz]
    unit_std : (H+1,) array
        sqrt of the fit's diag (A^T A)^-1 per harmonic (Re and Im averaged).
    sigma : (n_records,) array
        The residual's standard deviation: the level of a record too short for
        :data:`MIN_NOISE_LINES` lines (then no tone is looked for either), and a floor (1 %
        of it) for the local levels (a residual of quantized or noise-free data has empty
        lines).
    respond : callable or None
        The fit's response to tones (short records); None: the envelope (long records).

    Returns
    -------
    (n_records, H+1) array
    """
    n_h = len(unit_std) - 1
    segment = n_samples if n_samples <= LONG_RECORD else SEGMENT
    spacing = f0 * segment / fs
    n_lines = segment // 2 + 1
    every = np.arange(int(np.ceil((n_lines - 1) / spacing)) + 1) * spacing  # harmonics, all
    windows = noise_windows(every[:n_h + 1], every, spacing, n_lines, MIN_NOISE_LINES)
    clear = clear_lines(n_lines, every)
    broadband = np.repeat(np.asarray(sigma, dtype=float)[:, None], n_h + 1, axis=1)
    if min(w.size for w in windows) < MIN_NOISE_LINES or clear.size < MIN_NOISE_LINES:
        out: np.ndarray = broadband * unit_std
        return out
    power, segments = line_power(segment_of, n_samples, segment)
    tones = strong_lines(power, segments, every)
    clean = power if not any(tones) else line_power(
        segment_of, n_samples, segment, [[p for p, _ in rec] for rec in tones])[0]
    level = np.maximum(np.sqrt(noise_power(clean, windows, segments, clear) / segment),
                       0.01 * broadband)
    # the mean's noise is the spectrum's at 0 Hz, beyond the residual's reach (its line 0 is
    # the fitted mean): 1/f noise rising towards it shows in the lowest lines
    lowest = np.sqrt(np.mean(clean[:, 1:1 + LOWEST], axis=1) / segment)
    level[:, 0] = np.maximum(level[:, 0], lowest)
    var = (level * unit_std) ** 2
    var += _leakage(tones, segment, n_samples, fs, f0, n_h, respond)
    std: np.ndarray = np.sqrt(var)
    return std


def _leakage(tones: list[list[tuple[float, float]]], segment: int, n_samples: int, fs: float,
             f0: float, n_h: int, respond: Respond | None) -> np.ndarray:
    """(n_records, H+1) variance on Re and on Im of every harmonic from the records' tones
    (part 2 of the module docstring).

    A record that does not span a whole number of periods of both a harmonic and a tone lets
    the tone leak into the harmonic's phasor: the fit's response to a cosine and to a sine at
    the tone's frequency, P_c and P_s (``respond``), gives, for a tone of amplitude a and
    random phase, the variance a^2 (|P_c,n|^2 + |P_s,n|^2) / 4 on Re and on Im of X_n
    (a^2 (P_c,0^2 + P_s,0^2) / 2 on the mean). A long record's segments tell the tone's
    frequency only to a segment's line, not to the whole record's: there (``respond`` None)
    the fit's response is taken as the Dirichlet kernel's envelope averaged over its
    oscillation, a^2 / (4 (pi (f - n f0) T)^2) on Re and on Im (at most a^2 / 4)."""
    var = np.zeros((len(tones), n_h + 1))
    if not any(tones):
        return var
    # a tone seen on several records at positions differing in the noise counts once
    grid = np.array(sorted({round(pos * 16) for rec in tones for pos, _ in rec})) / 16
    freqs = grid * fs / segment
    if respond is not None:
        p_c, p_s = respond(freqs)
        gain = np.abs(p_c) ** 2 + np.abs(p_s) ** 2      # (n_freqs, H+1)
        gain[:, 1:] /= 4
        gain[:, 0] /= 2
    else:
        distance = np.abs(freqs[:, None] - np.arange(n_h + 1)[None, :] * f0)
        gain = np.minimum(1.0, 1.0 / (np.pi * distance * n_samples / fs) ** 2) / 4
    for r, rec in enumerate(tones):
        for pos, half_amplitude in rec:
            a = 2 * half_amplitude / segment
            k = int(np.argmin(np.abs(grid - pos)))
            var[r] += a**2 * gain[k]
    return var
