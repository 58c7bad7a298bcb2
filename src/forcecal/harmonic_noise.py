"""The standard uncertainty of a time record's harmonics, from its fit's residual (METHOD.md
section 6): what :func:`forcecal.harmonics.fit_harmonics` states as ``phasor_std``.

Two parts, added in variance:

1. **The noise at the harmonic's frequency.** Re and Im of X_n have the variance
   sigma_n^2 diag (A^T A)^-1 of the least-squares fit, sigma_n the level of the residual's
   spectrum around n f0 (:mod:`forcecal.line_noise`: the lines within half a harmonic spacing,
   clear of every harmonic, at least :data:`MIN_NOISE_LINES`, of the periodogram with the
   tones of part 2 taken out, whose skirts would lift the lines around them). A record's
   level is the median of all its noise lines; the harmonic's profile, relative to it, is
   pooled over the records of one fit (a scan's points share their noise's colour). 1/f
   noise and hum away from n f0 do not count: they do not disturb X_n; an impulse anywhere
   in the record does, and lifts every line. For white noise sigma_n is the residual's
   standard deviation. The mean (n = 0) takes at least the level of the lowest
   :data:`LOWEST` lines: the noise at 0 Hz is not in the residual (its line 0 is the fitted
   mean), and 1/f noise rises towards it.
2. **Tones leaking into it.** A record that does not span a whole number of periods of both a
   harmonic and a tone (a mains line, a harmonic of the drive above the last fitted) lets the
   tone leak into the harmonic's phasor: the fit's response to a cosine and to a sine at the
   tone's frequency, P_c and P_s, gives, for a tone of amplitude a and random phase, the
   variance a^2 (|P_c,n|^2 + |P_s,n|^2) / 4 on Re and on Im of X_n (a^2 (P_c,0^2 + P_s,0^2) / 2
   on the mean). The tones are the residual's lines that stand :data:`~.line_noise.STRONG`
   times above the local level (:func:`~forcecal.line_noise.strong_lines`). A record longer
   than :data:`~forcecal.fundamental.LONG_RECORD` samples is read in segments of
   :data:`SEGMENT` samples (up to 16, spread over it), which tell the
   tone's frequency only to a segment's line, not to the whole record's: there the fit's
   response is taken as the Dirichlet kernel's envelope averaged over its oscillation,
   a^2 / (4 (pi (f - n f0) T)^2) on Re and on Im (at most a^2 / 4).

A tone within :data:`~forcecal.line_noise.GUARD` lines of a harmonic cannot be told from it and
is not counted (a drive on a mains harmonic; see the guide's section on lab conditions).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .fundamental import LONG_RECORD
from .line_noise import clear_lines, line_power, noise_power, noise_windows, strong_lines

__all__ = ["LOWEST", "MIN_NOISE_LINES", "SEGMENT", "phasor_noise"]

MIN_NOISE_LINES = 32
"""Fewest spectral lines a harmonic's noise level is estimated from."""
SEGMENT = 1 << 15
"""Samples per segment of a record longer than :data:`~forcecal.fundamental.LONG_RECORD`."""
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
    (part 2 of the module docstring)."""
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
