"""Containers for recorded data: an SLDV scan (time records, the spectra of a frequency-domain
export, or a broadband scan's FRFs with their coherence) and a run recording.

All hold SI values (conversion happens once, in :mod:`forcecal.io`), time on the last axis.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import DataError, DimensionError

__all__ = ["FRF_PHASE", "Run", "Scan", "ScanFRF", "ScanSpectra"]

SPECTRUM_AMPLITUDES = ("peak", "rms")
"""What a spectrum line holds for a sinusoid A cos(2 pi f t + phi) on it: A exp(j phi) (peak) or
(A / sqrt 2) exp(j phi) (rms)."""


class _ScanPoints:
    """What every scan form shares: its points (n_points, n_dim) [m] and their count."""

    points: np.ndarray

    @property
    def x(self) -> np.ndarray:
        """(n_points,) first coordinate of every point [m]."""
        return self.points[:, 0]

    @property
    def n_points(self) -> int:
        """Number of scan points (records)."""
        return self.points.shape[0]


def _set_points(scan: Any) -> np.ndarray:
    """A frozen scan's ``points`` as a float (n_points, n_dim) array, set back on it."""
    pts = np.asarray(scan.points, dtype=float)
    if pts.ndim == 1:
        pts = pts[:, None]
    object.__setattr__(scan, "points", pts)
    return pts


def _check_quantity(quantity: str, where: str) -> None:
    """DimensionError unless ``quantity`` is velocity or displacement."""
    if quantity not in ("velocity", "displacement"):
        raise DimensionError(f"{where}: quantity '{quantity}' is neither velocity nor "
                             "displacement")


_MOST_NAMES = 8
"""Channel names a record's repr lists before it counts the rest."""


def _names(names: Any) -> str:
    """Names joined by commas, the first :data:`_MOST_NAMES` of them and a count of the rest."""
    names = [str(n) for n in names]
    more = len(names) - _MOST_NAMES
    return ", ".join(names[:_MOST_NAMES]) + (f", ... ({more} more)" if more > 0 else "")


def _lines(frequencies: np.ndarray) -> str:
    """A spectrum's lines in a few words: count, span [Hz]."""
    return f"{frequencies.size} lines {frequencies[0]:g}-{frequencies[-1]:g} Hz"


@dataclass(frozen=True)
class Scan(_ScanPoints):
    """A sequential SLDV scan: one response record and one reference record per point.

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        Coordinates of the scan points in the rig's axes (n_dim = 1 for a beam, 2 for a plate;
        a body's records are located by (x, y, z, dx, dy, dz), n_dim = 6).
    response : (n_points, n_samples) array [m/s] or [m]
        The vibration records, velocity or displacement according to ``quantity``.
    reference : (n_points, n_samples) array [A]
        The coil current recorded in the same acquisition as each response record.
    fs : float [Hz]
        Sampling rate, common to all records.
    quantity : {"velocity", "displacement"}
        What the response records hold.
    source : str
        Where the scan was read from, for messages.
    """

    points: np.ndarray
    response: np.ndarray
    reference: np.ndarray
    fs: float
    quantity: str = "velocity"
    source: str = "<scan>"

    def __post_init__(self) -> None:
        pts = _set_points(self)
        resp = np.atleast_2d(np.asarray(self.response, dtype=float))
        ref = np.atleast_2d(np.asarray(self.reference, dtype=float))
        object.__setattr__(self, "response", resp)
        object.__setattr__(self, "reference", ref)
        if resp.shape != ref.shape or resp.shape[0] != pts.shape[0]:
            raise DimensionError(
                f"scan '{self.source}': {pts.shape[0]} points, response {resp.shape}, "
                f"reference {ref.shape}; expected one response and one reference record per point"
            )
        _check_quantity(self.quantity, f"scan '{self.source}'")

    @property
    def n_samples(self) -> int:
        """Number of samples per record."""
        return self.response.shape[1]

    def __repr__(self) -> str:
        """One line: the source, points by samples, the sampling rate, a record's duration."""
        return (f"Scan('{self.source}', {self.n_points} points x {self.n_samples} samples at "
                f"{self.fs:g} Hz ({self.n_samples / self.fs:g} s a record), {self.quantity})")


@dataclass(frozen=True)
class ScanSpectra(_ScanPoints):
    """A sequential SLDV scan exported as spectra: per point the complex spectrum of the response
    and of the reference, both from one acquisition.

    The lines are one-sided and follow the forward transform exp(-j 2 pi f t) of the usual FFT:
    a sinusoid A cos(2 pi f t + phi) lying on the line at f gives that line the value
    A exp(j phi) when ``amplitude`` is "peak", (A / sqrt 2) exp(j phi) when it is "rms", with
    the phase phi referred to the record's first sample. The values are kept in the file's
    convention; :mod:`forcecal.model.scan` applies it.

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        Coordinates of the scan points, as for :class:`Scan`.
    frequencies : (n_lines,) array [Hz]
        The spectral lines, evenly spaced and increasing, at least 0 Hz.
    response : (n_points, n_lines) complex array [m/s] or [m]
        The spectrum of each vibration record, velocity or displacement as ``quantity`` says.
    reference : (n_points, n_lines) complex array [A]
        The spectrum of the coil current acquired with each response.
    quantity : {"velocity", "displacement"}
        What the response spectra hold.
    amplitude : {"peak", "rms"}
        The spectra's amplitude convention (see above).
    source : str
        Where the scan was read from, for messages.
    """

    points: np.ndarray
    frequencies: np.ndarray
    response: np.ndarray
    reference: np.ndarray
    quantity: str = "velocity"
    amplitude: str = "peak"
    source: str = "<scan>"

    def __post_init__(self) -> None:
        where = f"scan '{self.source}'"
        pts = _set_points(self)
        freq = np.asarray(self.frequencies, dtype=float)
        resp = np.atleast_2d(np.asarray(self.response, dtype=complex))
        ref = np.atleast_2d(np.asarray(self.reference, dtype=complex))
        object.__setattr__(self, "frequencies", freq)
        object.__setattr__(self, "response", resp)
        object.__setattr__(self, "reference", ref)
        if (freq.ndim != 1 or resp.shape != ref.shape or resp.shape != (pts.shape[0], freq.size)):
            raise DimensionError(
                f"{where}: {pts.shape[0]} points, {freq.size} lines, response {resp.shape}, "
                f"reference {ref.shape}; expected one response and one reference spectrum of "
                "every line per point")
        step = np.diff(freq)
        if (freq.size < 2 or not np.all(np.isfinite(freq)) or freq[0] < 0 or step[0] <= 0
                or np.max(np.abs(step - step[0])) > 1e-6 * step[0]):
            raise DimensionError(f"{where}: the spectral lines must be at least 2, evenly spaced, "
                                 f"increasing and from 0 Hz up; found {freq.size} lines from "
                                 f"{freq[0] if freq.size else float('nan'):.6g} Hz")
        _check_quantity(self.quantity, where)
        if self.amplitude not in SPECTRUM_AMPLITUDES:
            raise DimensionError(f"{where}: amplitude convention '{self.amplitude}' is neither "
                                 "'peak' nor 'rms'")

    def __repr__(self) -> str:
        """One line: the source, points by lines, the lines' span, the conventions."""
        return (f"ScanSpectra('{self.source}', {self.n_points} points x "
                f"{_lines(self.frequencies)}, {self.quantity}, {self.amplitude})")

    @property
    def n_lines(self) -> int:
        """Number of spectral lines per spectrum."""
        return self.frequencies.size

    @property
    def spacing(self) -> float:
        """The line spacing [Hz]."""
        return float(self.frequencies[1] - self.frequencies[0])


FRF_PHASE = ("whose phase at a line is relative to the reference at that same line: the "
             "harmonics' phases relative to the drive's fundamental, which the method needs, are "
             "lost, and so are their amplitudes relative to each other")
"""Why a steady drive's scan cannot be read from FRFs, for messages."""


@dataclass(frozen=True)
class ScanFRF(_ScanPoints):
    """A broadband SLDV scan exported as FRFs: per point the frequency response of the vibration
    to the reference (the coil current) and its ordinary coherence, over common lines.

    An FRF states its noise only with its coherence and the number of averages it was
    estimated from (:func:`forcecal.model.frf.scan_response`), which a Universal File does not hold:
    the rig gives it (``acquisition.scan_averages``).

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        Coordinates of the scan points, as for :class:`Scan`.
    frequencies : (n_lines,) array [Hz]
        The lines, increasing, at least 0 Hz.
    values : (n_points, n_lines) complex array [m/s per A] or [m per A]
        H = vibration / current, velocity or displacement as ``quantity`` says.
    coherence : (n_points, n_lines) array [1]
        The ordinary coherence of every line, within 0-1.
    quantity : {"velocity", "displacement"}
    source : str
        Where the scan was read from, for messages.
    """

    points: np.ndarray
    frequencies: np.ndarray
    values: np.ndarray
    coherence: np.ndarray
    quantity: str = "velocity"
    source: str = "<scan>"

    def __post_init__(self) -> None:
        where = f"scan '{self.source}'"
        pts = _set_points(self)
        freq = np.asarray(self.frequencies, dtype=float)
        values = np.atleast_2d(np.asarray(self.values, dtype=complex))
        coh = np.atleast_2d(np.asarray(self.coherence, dtype=float))
        object.__setattr__(self, "frequencies", freq)
        object.__setattr__(self, "values", values)
        if (freq.ndim != 1 or values.shape != coh.shape
                or values.shape != (pts.shape[0], freq.size)):
            raise DimensionError(f"{where}: {pts.shape[0]} points, {freq.size} lines, FRFs "
                                 f"{values.shape}, coherence {coh.shape}; expected one FRF and "
                                 "one coherence of every line per point")
        if (freq.size < 2 or not np.all(np.isfinite(freq)) or freq[0] < 0
                or np.any(np.diff(freq) <= 0)):
            raise DimensionError(f"{where}: the FRFs' lines must be at least 2, increasing and "
                                 "at 0 Hz or above")
        if not (np.all(np.isfinite(values)) and np.all(np.isfinite(coh))):
            raise DataError(f"{where}: FRFs or coherence hold NaN or infinite values")
        if coh.min() < 0.0 or coh.max() > 1.0 + 1e-6:
            raise DataError(f"{where}: a coherence lies within 0-1; found {coh.min():.4g} to "
                            f"{coh.max():.4g}")
        object.__setattr__(self, "coherence", np.minimum(coh, 1.0))
        _check_quantity(self.quantity, where)

    def __repr__(self) -> str:
        """One line: the source, points by lines, the lines' span, the quantity."""
        return (f"ScanFRF('{self.source}', {self.n_points} points x {_lines(self.frequencies)}, "
                f"{self.quantity} per A)")


@dataclass(frozen=True)
class Run:
    """One run recording: uniformly sampled named channels, raw values as in the file.

    Attributes
    ----------
    channels : mapping name -> (n_samples,) array
        Raw channel values (the rig's per-channel scale is applied later).
    fs : float [Hz]
        Sampling rate, common to all channels.
    t0 : float [s]
        Time stamp of the first sample.
    name : str
        The file name without its extension, used to name outputs.
    source : str
        The path the run was read from, for messages.
    labels : mapping column -> str
        Labels carried from the campaign manifest into the report (empty otherwise).
    """

    channels: Mapping[str, np.ndarray]
    fs: float
    t0: float = 0.0
    name: str = "run"
    source: str = "<run>"
    labels: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        where = f"run '{self.source}'"
        if not isinstance(self.channels, Mapping) or not self.channels:
            raise DataError(f"{where}: no channels; expected a mapping name -> samples")
        try:
            fs = float(self.fs)
            t0 = float(self.t0)
        except (TypeError, ValueError):
            raise DataError(f"{where}: fs = {self.fs!r} Hz and t0 = {self.t0!r} s must be "
                            "numbers") from None
        if not (np.isfinite(fs) and fs > 0):
            raise DataError(f"{where}: sampling rate fs = {self.fs!r} Hz; expected a finite "
                            "positive number")
        if not np.isfinite(t0):
            raise DataError(f"{where}: start time t0 = {self.t0!r} s; expected a finite number")
        lengths = {}
        for name, values in self.channels.items():
            arr = np.asarray(values)
            if arr.ndim != 1:
                raise DimensionError(f"{where}: channel {name!r} has shape {arr.shape}; "
                                     "expected one dimension")
            lengths[name] = arr.size
        first = next(iter(lengths))
        for name, n in lengths.items():
            if n != lengths[first]:
                raise DimensionError(f"{where}: channel {name!r} has {n} samples, channel "
                                     f"{first!r} has {lengths[first]}")
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "t0", t0)

    @property
    def n_samples(self) -> int:
        """Number of samples per channel."""
        return len(next(iter(self.channels.values())))

    def __repr__(self) -> str:
        """One line: the name, the channels, samples, sampling rate, duration and start."""
        return (f"Run('{self.name}', {len(self.channels)} channels ({_names(self.channels)}), "
                f"{self.n_samples} samples at {self.fs:g} Hz ({self.n_samples / self.fs:g} s "
                f"from t0 = {self.t0:g} s))")

    @property
    def time(self) -> np.ndarray:
        """(n_samples,) time stamps [s]."""
        return self.t0 + np.arange(self.n_samples) / self.fs

    def channel(self, name: str) -> np.ndarray:
        """Raw values of a channel.

        Parameters
        ----------
        name : str
            The channel's name, as the rig gives it.

        Returns
        -------
        (n_samples,) float array
            The raw values.

        Raises
        ------
        DataError
            Naming the run and the channel when the run has no such channel.
        """
        if name not in self.channels:
            raise DataError(
                f"run '{self.source}': channel '{name}' named in the rig is missing "
                f"(found: {', '.join(sorted(self.channels))})"
            )
        return np.asarray(self.channels[name], dtype=float)
