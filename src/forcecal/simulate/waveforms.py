"""Broadband coil drives: a swept sine, a periodic chirp, multi-tone and band-limited random.

A :class:`.magnet.Drive` with a ``waveform`` reads ``dc + waveform(t)`` (its ``ac`` sine is
replaced). Every waveform evaluates on arrays (:meth:`value`); the stepper takes a run's
drive at all its steps at once.

Each states when it starts and whether it repeats:

``onset``
    The time [s] before which the waveform is zero (the rig rests at its DC equilibrium), or
    None for a stationary waveform that has always played.
``period``
    The period [s] of a periodic waveform (a window of whole periods has no leakage), or None.
``band``
    (lo, hi) [Hz], the frequencies the waveform excites.

"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__: list[str] = []

_TWO_PI = 2 * math.pi
TABLE_OVERSAMPLING = 256
"""Samples of a :class:`BandLimitedRandom` table per period of its highest line (at least):
linear interpolation between them changes a line's amplitude by at most ``(pi / 256)^2 / 3``
(5e-5)."""


def _check(condition: bool, message: str) -> None:
    if not condition:
        raise ValueError(message)


@dataclass(frozen=True)
class SweptSine:
    """A sine swept linearly in frequency: ``amplitude * sin(phi(t))``.

    Over ``0 <= t <= duration`` the instantaneous frequency rises (or falls) linearly from
    ``f_start`` to ``f_stop``: ``phi(t) = 2 pi (f_start t + (f_stop - f_start) t^2 / (2
    duration))``. Before t = 0 the sine plays at ``f_start`` for ``lead_in`` seconds, its
    amplitude faded in by a raised cosine over the first half of the lead-in, so that a record
    starting at t = 0 starts on the settled response to the first frequency (zero before
    ``-lead_in``). After the sweep, ``after = "hold"`` keeps the sine at ``f_stop`` (phase
    continuous); ``"stop"`` ends it (zero from ``duration`` on).

    Attributes
    ----------
    amplitude : float [A] or [V]
    f_start, f_stop : float [Hz]
    duration : float [s]
    lead_in : float [s]
    after : {"hold", "stop"}
    """

    amplitude: float
    f_start: float
    f_stop: float
    duration: float
    lead_in: float = 0.5
    after: str = "hold"

    def __post_init__(self) -> None:
        _check(self.f_start > 0 and self.f_stop > 0, "a sweep's frequencies must be positive")
        _check(self.duration > 0, "a sweep's duration must be positive")
        _check(self.lead_in >= 0, "a sweep's lead-in must not be negative")
        _check(self.after in ("hold", "stop"), f"a sweep ends by 'hold' or 'stop', not "
               f"{self.after!r}")

    @property
    def rate(self) -> float:
        """(f_stop - f_start) / duration [Hz/s]."""
        return (self.f_stop - self.f_start) / self.duration

    @property
    def onset(self) -> float | None:
        """-lead_in [s]: zero before."""
        return -self.lead_in

    @property
    def period(self) -> float | None:
        """None: a sweep does not repeat."""
        return None

    @property
    def band(self) -> tuple[float, float]:
        """(lo, hi) [Hz]."""
        return (min(self.f_start, self.f_stop), max(self.f_start, self.f_stop))

    def instantaneous_frequency(self, t: np.ndarray | float) -> np.ndarray:
        """The frequency [Hz] at times t [s]: f_start before the sweep, f_stop after."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return self.f_start + self.rate * tt

    def value(self, t: np.ndarray | float) -> np.ndarray:
        """The waveform at times t [s] (shaped like t)."""
        tt = np.asarray(t, dtype=float)
        amp, f0, dur, lead = self.amplitude, self.f_start, self.duration, self.lead_in
        fade = 0.5 * lead
        out = np.zeros_like(tt)
        before = (tt < 0.0) & (tt >= -lead)
        tb = tt[before]
        ramp = np.where(tb < fade - lead, 0.5 * (1.0 - np.cos(np.pi * (tb + lead) / fade)), 1.0)
        out[before] = amp * np.sin(_TWO_PI * f0 * tb) * ramp
        during = (tt >= 0.0) & (tt <= dur)
        ts = tt[during]
        out[during] = amp * np.sin(_TWO_PI * (f0 * ts + 0.5 * self.rate * ts * ts))
        if self.after == "hold":
            after = tt > dur
            phi_end = _TWO_PI * (f0 * dur + 0.5 * self.rate * dur * dur)
            out[after] = amp * np.sin(phi_end + _TWO_PI * self.f_stop * (tt[after] - dur))
        return out

    def scaled(self, level: float) -> SweptSine:
        """The same sweep with its amplitude times ``level``."""
        return SweptSine(self.amplitude * level, self.f_start, self.f_stop, self.duration,
                         self.lead_in, self.after)

    def describe(self) -> dict:
        """The parameters, for the truth files."""
        return {"kind": "swept sine (linear)", "amplitude": self.amplitude,
                "f_start_Hz": self.f_start, "f_stop_Hz": self.f_stop,
                "duration_s": self.duration, "lead_in_s": self.lead_in, "after": self.after}


@dataclass(frozen=True)
class PeriodicChirp:
    """A linear sweep from ``f_start`` to ``f_stop`` repeated every ``period`` seconds.

    Within each period (tau = t mod period) it reads ``amplitude * sin(2 pi (f_start tau +
    (f_stop - f_start) tau^2 / (2 period)) + phi0)``, ``phi0 = pi / 2 - pi P`` (modulo 2 pi),
    ``P = period (f_start + f_stop) / 2`` (the cycles of one sweep), which makes the value
    continuous where one sweep ends and the next begins. It has always played (stationary): a
    window of whole periods has no leakage, its lines at multiples of ``1 / period``.

    Attributes
    ----------
    amplitude : float [A] or [V]
    f_start, f_stop : float [Hz]
    period : float [s]
    """

    amplitude: float
    f_start: float
    f_stop: float
    period: float

    def __post_init__(self) -> None:
        _check(self.f_start > 0 and self.f_stop > 0, "a chirp's frequencies must be positive")
        _check(self.period > 0, "a chirp's period must be positive")

    @property
    def onset(self) -> float | None:
        """None: stationary."""
        return None

    @property
    def band(self) -> tuple[float, float]:
        """(lo, hi) [Hz]."""
        return (min(self.f_start, self.f_stop), max(self.f_start, self.f_stop))

    @property
    def start_phase(self) -> float:
        """phi0 [rad] (in [-pi, pi]), the phase at the start of every period."""
        return math.remainder(math.pi / 2 - math.pi * self.period * (self.f_start + self.f_stop)
                              / 2, 2 * math.pi)

    def value(self, t: np.ndarray | float) -> np.ndarray:
        """The waveform at times t [s] (shaped like t)."""
        tt = np.asarray(t, dtype=float)
        period = self.period
        half_rate = 0.5 * (self.f_stop - self.f_start) / period
        tau = tt - period * np.floor(tt / period)
        return self.amplitude * np.sin(_TWO_PI * (self.f_start * tau + half_rate * tau * tau)
                                       + self.start_phase)

    def scaled(self, level: float) -> PeriodicChirp:
        """The same chirp with its amplitude times ``level``."""
        return PeriodicChirp(self.amplitude * level, self.f_start, self.f_stop, self.period)

    def describe(self) -> dict:
        """The parameters, for the truth files."""
        return {"kind": "periodic chirp (linear)", "amplitude": self.amplitude,
                "f_start_Hz": self.f_start, "f_stop_Hz": self.f_stop, "period_s": self.period,
                "start_phase_rad": self.start_phase}


@dataclass(frozen=True)
class MultiTone:
    """A sum of sines ``sum_k amplitudes[k] * sin(2 pi frequencies[k] t + phases[k])``.

    Stationary; not taken as periodic (its tones need not be commensurate).

    Attributes
    ----------
    frequencies : tuple of float [Hz]
    amplitudes : tuple of float [A] or [V]
    phases : tuple of float [rad]
        Empty: every tone at phase 0.
    """

    frequencies: tuple[float, ...]
    amplitudes: tuple[float, ...]
    phases: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        _check(len(self.frequencies) > 0, "a multi-tone needs at least one tone")
        _check(len(self.amplitudes) == len(self.frequencies)
               and len(self.phases) in (0, len(self.frequencies)),
               "a multi-tone needs one amplitude (and one phase, or none) per frequency")
        _check(all(f > 0 for f in self.frequencies), "a tone's frequency must be positive")

    @property
    def onset(self) -> float | None:
        """None: stationary."""
        return None

    @property
    def period(self) -> float | None:
        """None: not taken as periodic."""
        return None

    @property
    def band(self) -> tuple[float, float]:
        """(lowest, highest) tone [Hz]."""
        return (min(self.frequencies), max(self.frequencies))

    def _tones(self) -> tuple[tuple[float, float, float], ...]:
        phases = self.phases or (0.0,) * len(self.frequencies)
        return tuple((_TWO_PI * float(f), float(a), float(p))
                     for f, a, p in zip(self.frequencies, self.amplitudes, phases, strict=True))

    def value(self, t: np.ndarray | float) -> np.ndarray:
        """The waveform at times t [s] (shaped like t)."""
        tt = np.asarray(t, dtype=float)
        out = np.zeros_like(tt)
        for w, amp, ph in self._tones():
            out += amp * np.sin(w * tt + ph)
        return out

    def scaled(self, level: float) -> MultiTone:
        """The same tones with every amplitude times ``level``."""
        return MultiTone(self.frequencies, tuple(a * level for a in self.amplitudes),
                         self.phases)

    def describe(self) -> dict:
        """The parameters, for the truth files."""
        return {"kind": "multi-tone", "frequencies_Hz": list(self.frequencies),
                "amplitudes": list(self.amplitudes), "phases_rad": list(self.phases)}


@dataclass(frozen=True)
class BandLimitedRandom:
    """Periodic band-limited random noise: Gaussian, flat between ``f_lo`` and ``f_hi``.

    A random-phase multisine: every line ``k / period`` with ``f_lo <= k / period <= f_hi``
    at one amplitude and a phase drawn uniformly from ``seed``; with many lines the values are
    Gaussian, the spectrum is exactly flat and the RMS exactly ``rms``. It repeats every
    ``period`` seconds (a window of whole periods has no leakage) and has always played
    (stationary). One period is tabulated at a power of two of samples, at least
    :data:`TABLE_OVERSAMPLING` per period of the highest line, and interpolated linearly in
    time: the drive is deterministic, and cheap at any time.

    Attributes
    ----------
    rms : float [A] or [V]
    f_lo, f_hi : float [Hz]
    period : float [s]
    seed : int
    """

    rms: float
    f_lo: float
    f_hi: float
    period: float = 8.0
    seed: int = 0
    _table: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check(0 <= self.f_lo < self.f_hi, "a random drive needs 0 <= f_lo < f_hi")
        _check(self.period > 0, "a random drive's period must be positive")
        lines = self.lines
        _check(len(lines) > 0, "no line k / period falls between f_lo and f_hi: lengthen the "
               "period")
        n = 1 << max(int(math.ceil(math.log2(TABLE_OVERSAMPLING * self.f_hi * self.period))),
                     int(lines[-1]).bit_length() + 2)
        phases = np.random.default_rng(self.seed).uniform(0.0, _TWO_PI, len(lines))
        spectrum = np.zeros(n // 2 + 1, dtype=complex)
        spectrum[lines] = np.exp(1j * phases) * (n / 2)            # unit lines
        table = np.fft.irfft(spectrum, n) * (self.rms / math.sqrt(len(lines) / 2))
        object.__setattr__(self, "_table", np.append(table, table[0]))

    @property
    def lines(self) -> np.ndarray:
        """The line numbers k (frequencies k / period) [1]."""
        lo = max(int(math.ceil(self.f_lo * self.period - 1e-9)), 1)
        hi = int(math.floor(self.f_hi * self.period + 1e-9))
        return np.arange(lo, hi + 1)

    @property
    def onset(self) -> float | None:
        """None: stationary."""
        return None

    @property
    def band(self) -> tuple[float, float]:
        """(f_lo, f_hi) [Hz]."""
        return (self.f_lo, self.f_hi)

    def value(self, t: np.ndarray | float) -> np.ndarray:
        """The waveform at times t [s] (shaped like t)."""
        tab = self._table
        n = len(tab) - 1
        x = np.asarray(t, dtype=float) * (n / self.period)
        k = np.floor(x)
        i = np.mod(k, n).astype(np.int64)
        a = tab[i]
        return a + (x - k) * (tab[i + 1] - a)

    def scaled(self, level: float) -> BandLimitedRandom:
        """The same noise with its RMS times ``level``."""
        return BandLimitedRandom(self.rms * level, self.f_lo, self.f_hi, self.period, self.seed)

    def describe(self) -> dict:
        """The parameters, for the truth files."""
        return {"kind": "band-limited random (random-phase multisine)", "rms": self.rms,
                "f_lo_Hz": self.f_lo, "f_hi_Hz": self.f_hi, "period_s": self.period,
                "seed": self.seed, "lines": len(self.lines)}


Waveform = SweptSine | PeriodicChirp | MultiTone | BandLimitedRandom
"""Any of the broadband drives."""
