"""Checks the method needs on recorded data, whatever file the data came from.

A record must hold enough samples (:data:`MIN_SAMPLES`), channels of one run must agree in
length, every sample must be finite, a channel must not be clipped (flat-topped) and a record
must span at least five periods of the drive. :func:`as_records` readies records for a
harmonic fit (real, finite, one-dimensional). Each check raises
:class:`~forcecal.errors.DataError` with one line that names the run (or scan), the channel and
where the problem starts.

Checks that belong to a file format (a CSV cell that is not a number, non-uniform time stamps,
a TDMS or HDF5 sampling attribute) stay in :mod:`forcecal.io`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .errors import DataError, DimensionError
from .records import Run, Scan

__all__ = [
    "MIN_SAMPLES",
    "as_records",
    "check_clipping",
    "check_equal_lengths",
    "check_finite",
    "check_periods",
    "check_record_length",
    "check_sample_count",
    "check_scan_length",
]

MIN_SAMPLES = 16
"""Fewest samples a run's channel may hold."""

_CLIP_FRACTION = 0.005  # share of samples at one extreme from which clipping is suspected
_CLIP_RUN = 3  # consecutive samples at the extreme from which clipping is suspected
_CLIP_RATIO = 4.0  # extreme count / count just inside it; a smooth peak stays below ~2.5


def check_sample_count(n: int, source: str | Path) -> None:
    """Raise DataError when a run holds no samples or fewer than :data:`MIN_SAMPLES`.

    Parameters
    ----------
    n : int
        Number of samples per channel.
    source : str or Path
        The run file, for the message.

    Raises
    ------
    DataError
        ``n`` is 0 or below :data:`MIN_SAMPLES`.
    """
    if n == 0:
        raise DataError(f"run '{source}': no samples")
    if n < MIN_SAMPLES:
        raise DataError(f"run '{source}': {n} samples; at least {MIN_SAMPLES} are needed")


def check_equal_lengths(channels: Mapping[str, np.ndarray], source: str | Path) -> None:
    """Raise DataError when the channels of one run differ in length.

    Parameters
    ----------
    channels : mapping name -> (n_samples,) array
        The channels, in file order; the first one sets the expected length.
    source : str or Path
        The run file, for the message.

    Raises
    ------
    DataError
        Naming the first channel whose length differs from the first channel's.
    """
    names = list(channels)
    n0 = len(channels[names[0]])
    for name in names[1:]:
        if len(channels[name]) != n0:
            raise DataError(
                f"run '{source}': channel {name!r} has {len(channels[name])} samples, "
                f"channel {names[0]!r} has {n0}"
            )


def check_finite(values: np.ndarray, name: str, source: str | Path, t0: float,
                 fs: float) -> None:
    """Raise DataError when a channel holds NaN or infinite samples.

    Parameters
    ----------
    values : (n_samples,) array
        Channel values.
    name : str
        Channel name, for the message.
    source : str or Path
        The run file, for the message.
    t0 : float
        Time stamp of the first sample [s].
    fs : float
        Sampling rate [Hz].

    Raises
    ------
    DataError
        Naming the channel, the count of NaN and of infinite samples and the time [s] of the
        first bad sample.
    """
    bad = ~np.isfinite(values)
    if not bad.any():
        return
    n_nan = int(np.count_nonzero(np.isnan(values)))
    n_inf = int(np.count_nonzero(bad)) - n_nan
    what = " and ".join(
        text for count, text in ((n_nan, f"{n_nan} NaN"), (n_inf, f"{n_inf} infinite")) if count
    )
    first = int(np.flatnonzero(bad)[0])
    raise DataError(
        f"run '{source}': channel {name!r} has {what} samples starting at "
        f"t={t0 + first / fs:.6g} s"
    )


def check_clipping(values: np.ndarray, name: str, source: str | Path, fs: float) -> None:
    """Raise DataError when a channel is flat-topped (saturated) at its maximum or minimum.

    A sine-like signal, quantised or not, passes through its extreme once per period and
    rounds to the extreme value only over its smooth peak, so its extreme level holds at most
    about 2.5 times as many samples as the level just inside it. A saturated signal sits at
    the extreme for many consecutive samples. The channel is flagged when, at its maximum or
    its minimum, at least 0.5 % of the samples (and at least 3 in a row) sit exactly at the
    extreme, and more than 4 times as many as lie just inside it (closer than two quantisation
    steps, the step being the distance from the extreme to the nearest other value).
    Constant channels are not flagged; the check is meant for sine-like channels, not for
    square waves or trigger lines.

    Parameters
    ----------
    values : (n_samples,) array
        Raw channel values; non-finite samples are ignored.
    name : str
        Channel name, for the message.
    source : str or Path
        The run file, for the message.
    fs : float
        Sampling rate [Hz], to say when the first flat top starts (s after the record start).

    Raises
    ------
    DataError
        Naming the channel, the share of samples at the extreme, the longest flat top and
        when the first one starts.
    """
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if v.size < MIN_SAMPLES or v.max() == v.min():
        return
    for side, level in (("maximum", v.max()), ("minimum", v.min())):
        at_level = v == level
        count = int(np.count_nonzero(at_level))
        if count < max(_CLIP_RUN, _CLIP_FRACTION * v.size):
            continue
        longest, start = _flat_runs(at_level)
        if longest < _CLIP_RUN or count <= _CLIP_RATIO * _count_just_inside(v, level):
            continue
        raise DataError(
            f"run '{source}': channel {name!r} is clipped: {count} samples "
            f"({100 * count / v.size:.2g} %) sit at its {side} {level:.6g}, up to {longest} in "
            f"a row, the first flat top at {start / fs:.6g} s after the start"
        )


def _flat_runs(mask: np.ndarray) -> tuple[int, int]:
    """(longest run of True, start index of the first run of at least ``_CLIP_RUN``)."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    lengths = ends - starts
    long_enough = np.flatnonzero(lengths >= _CLIP_RUN)
    first = int(starts[long_enough[0]]) if long_enough.size else -1
    return int(lengths.max()), first


def _count_just_inside(v: np.ndarray, level: float) -> int:
    """Samples within two quantisation steps inside ``level``, ``level`` itself excluded.

    The step is the distance from ``level`` to the nearest other value in the record.
    """
    others = v[v != level]
    gap = float(np.min(np.abs(others - level)))
    return int(np.count_nonzero(np.abs(others - level) < 2 * gap))


def check_record_length(run: Run, f0: float) -> None:
    """DataError when a record holds fewer than five periods of the drive.

    Parameters
    ----------
    run : Run
        The run recording.
    f0 : float
        Drive frequency [Hz].

    Raises
    ------
    DataError
        Naming the run, the periods the record holds and the frequency.
    """
    periods = run.n_samples / run.fs * f0
    if periods < 5:
        raise DataError(f"run '{run.source}': the record holds {periods:.1f} periods of "
                        f"{f0:.4g} Hz; at least 5 are needed")


def check_periods(lengths: np.ndarray, fs: float, f0: float) -> None:
    """Raise DataError when the shortest record holds fewer than five periods.

    Parameters
    ----------
    lengths : (n_records,) int array
        Samples of every record.
    fs : float
        Sampling rate [Hz].
    f0 : float
        Nominal fundamental frequency [Hz].

    Raises
    ------
    DataError
        Naming the shortest record (by index), its periods and samples.
    """
    i_short = int(np.argmin(lengths))
    periods = lengths[i_short] / fs * f0
    if periods < 5.0:
        raise DataError(
            f"record {i_short} holds {periods:.1f} periods of {f0:.6g} Hz "
            f"({lengths[i_short]} samples at {fs:.6g} Hz); at least 5 periods are needed to "
            "refine the fundamental"
        )


def check_scan_length(scan: Scan, f0: float) -> None:
    """Raise DataError when the records of a scan hold fewer than five periods of the drive.

    Parameters
    ----------
    scan : Scan
        The scan; every record holds ``scan.n_samples`` samples.
    f0 : float
        Nominal drive frequency [Hz].

    Raises
    ------
    DataError
        Naming the scan, the periods each record holds and the frequency.
    """
    periods = scan.n_samples / scan.fs * f0
    if periods < 5:
        raise DataError(f"scan '{scan.source}': each record holds {periods:.1f} periods of "
                        f"{f0:.4g} Hz; at least 5 are needed")


def as_records(records: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    """Records as a list of real, finite, one-dimensional float arrays.

    Parameters
    ----------
    records : (n_records, n_samples) or (n_samples,) array, or sequence of 1-D arrays
        Records of any unit; records in a sequence may differ in length.

    Returns
    -------
    list of (n_samples,) float arrays
        One per record, in order.

    Raises
    ------
    DataError
        Complex values, no record at all, or non-finite samples (the record is named by its
        index).
    DimensionError
        An array of more than two dimensions, or a record that is not one-dimensional.
    """
    if any(np.iscomplexobj(rec) for rec in records):
        raise DataError("records must be real-valued samples; got complex values")
    if isinstance(records, np.ndarray):
        arr = np.asarray(records, dtype=float)
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2:
            raise DimensionError(
                f"records must be (n_records, n_samples) or a list of 1-D arrays; "
                f"got shape {arr.shape}"
            )
        out = list(arr)
    else:
        out = [np.asarray(rec, dtype=float) for rec in records]
    if not out:
        raise DataError("no records given")
    for i, rec in enumerate(out):
        if rec.ndim != 1:
            raise DimensionError(f"record {i} must be one-dimensional; got shape {rec.shape}")
        bad = ~np.isfinite(rec)
        if bad.any():
            raise DataError(f"record {i} contains {int(bad.sum())} non-finite samples")
    return out
