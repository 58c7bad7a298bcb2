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
from typing import TYPE_CHECKING

import numpy as np

from ..errors import DataError, DimensionError, InputError
from ..records import Run, Scan

if TYPE_CHECKING:
    from ..rig import Rig

__all__ = [
    "MIN_SAMPLES",
    "NOISE_BLOCK",
    "AboveBand",
    "WorstHalfSecond",
    "channel_noise",
    "check_channel_noise",
    "check_clipping",
    "check_equal_lengths",
    "check_finite",
    "check_plausible",
    "check_record_length",
    "check_run_for_rig",
    "check_sample_count",
    "check_scan_length",
    "check_scan_values",
]


# --- from checks ---
MIN_SAMPLES = 16
"""Fewest samples a run's channel may hold."""

MAX_RAW_SAMPLE = 1e30
"""Largest magnitude of a raw sample in any file (ADC counts of 64 bits stay below 1e19);
anything beyond is a damaged file, and its squares would overflow."""
SPIKE_FACTOR = 1e6
"""A sample farther from a channel's median than this many times the channel's robust span
(the 0.1 to 99.9 percentile range) is a damaged value, not a measurement (a 24-bit ADC spans
1.7e7 levels; its noise floor is many levels wide)."""
MIN_SIGNAL = 1e-30
"""Smallest plausible non-zero peak of a rig's channel in SI (a probe's 1e-30 m is far below
any sensor's noise): smaller values come from a wrong scale and underflow in the fits."""
RIG_SPIKE_FACTOR = 1e3
"""The same for the channels a rig names (gauges, probes, current, flux): continuous signals
of a steady drive, where a sample a thousand times the signal's span away is a glitch that
would dominate every harmonic."""
PHYSICAL_LIMITS = {"gauge": (1e7, "N"), "sensor": (1.0, "m"), "current": (1e5, "A"),
                   "flux": (10.0, "Wb")}
"""Largest plausible magnitude of a channel in SI, after the rig's scale: a force gauge's
10 MN, a proximity probe's 1 m, a coil's 100 kA, a pole's 10 Wb. A value beyond says the
scale or the file's unit is wrong (e.g. a probe in um read as m)."""

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


def check_plausible(values: np.ndarray, name: str, source: str | Path, t0: float,
                    fs: float, what: str = "run", factor: float = SPIKE_FACTOR) -> None:
    """Raise DataError when a channel holds an absurd sample: beyond :data:`MAX_RAW_SAMPLE`,
    or :data:`SPIKE_FACTOR` times the channel's robust span away from its median.

    Parameters
    ----------
    values : (n_samples,) array
        Finite channel values (see :func:`check_finite`).
    name : str
        Channel name, for the message.
    source : str or Path
        The file, for the message.
    t0 : float
        Time stamp of the first sample [s].
    fs : float
        Sampling rate [Hz].
    what : str
        "run" or "scan", the kind of file in the message.
    factor : float
        How many robust spans away from the median a sample may lie.

    Raises
    ------
    DataError
        Naming the file, the channel, the value and when it occurs.
    """
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0:
        return
    big = np.flatnonzero(np.abs(v) > MAX_RAW_SAMPLE)
    if big.size:
        k = int(big[0])
        raise DataError(f"{what} '{source}': channel {name!r} holds {v[k]:.6g} at "
                        f"t={t0 + k / fs:.6g} s ({big.size} such samples); expected magnitudes "
                        f"below {MAX_RAW_SAMPLE:g} (a damaged file?)")
    lo, mid, hi = np.percentile(v, [0.1, 50.0, 99.9])
    span = hi - lo
    if span <= 0:
        return
    off = np.subtract(v, mid)                  # |v - mid| in one temporary of the record's length
    far = np.flatnonzero(np.abs(off, out=off) > factor * span)
    del off
    if far.size:
        k = int(far[0])
        raise DataError(f"{what} '{source}': channel {name!r} holds {v[k]:.6g} at "
                        f"t={t0 + k / fs:.6g} s, {abs(v[k] - mid) / span:.3g} times its "
                        f"robust span {span:.3g} away from its median {mid:.6g}; expected at "
                        f"most {factor:g} times (a damaged value?)")


def check_run_for_rig(rig: Rig, run: Run, f0: float | None = None) -> None:
    """The checks every estimate needs of a run against its rig, whatever the estimator.

    Every channel the rig names is present, finite and within :data:`PHYSICAL_LIMITS` after
    its scale, not clipped; at least one of them is driven; the record spans five periods of
    ``f0`` (default: the rig's nominal frequency).

    Parameters
    ----------
    rig : Rig
        The rig, with its channels' names and scales.
    run : Run
        The recording.
    f0 : float, optional
        Drive frequency [Hz].

    Raises
    ------
    DataError
        Naming the run, the channel and the rig key at fault.
    """
    act = rig.actuator
    items: list[tuple[str, float, str, str]] = []
    items += [(g.name, g.scale, "gauge", f"gauges[{k}].scale") for k, g in enumerate(rig.gauges)]
    items += [(s.name, s.scale, "sensor", f"sensors[{k}].scale")
              for k, s in enumerate(rig.sensors)]
    items.append((act.current, act.current_scale, "current", "actuator.current_scale"))
    items += [(name, act.flux_scale, "flux", "actuator.flux_scale")
              for name in rig.flux_channels if name in run.channels]
    driven = False
    for name, scale, kind, key in items:
        raw = run.channel(name)
        check_finite(raw, name, run.source, run.t0, run.fs)
        check_plausible(raw, name, run.source, run.t0, run.fs, factor=RIG_SPIKE_FACTOR)
        si = raw if scale == 1.0 else raw * scale     # 1.0 x raw is raw: no copy
        limit, unit = PHYSICAL_LIMITS[kind]
        peak = max(float(si.max()), -float(si.min())) if si.size else 0.0   # max |si|
        if not peak <= limit:
            k = int(np.argmax(np.abs(si)))
            raise DataError(
                f"run '{run.source}': channel {name!r} reaches {si[k]:.4g} {unit} at "
                f"t={run.t0 + k / run.fs:.6g} s (raw {raw[k]:.4g} x {key} = {scale:g}); a "
                f"{kind} beyond {limit:g} {unit} is not plausible: check the scale and the "
                "file's unit")
        if 0 < peak < MIN_SIGNAL:
            raise DataError(
                f"run '{run.source}': channel {name!r} peaks at {peak:.3g} {unit} (raw x {key} "
                f"= {scale:g}); a signal below {MIN_SIGNAL:g} {unit} is not plausible: check "
                "the scale and the file's unit")
        check_clipping(si, name, run.source, run.fs)
        driven = driven or bool(np.std(si) > 1e-9 * (peak + 1e-300))
    if not driven:
        raise DataError(f"run '{run.source}': every channel the rig names is constant; "
                        "nothing is driven")
    f = f0 if f0 is not None else rig.frequency
    if f is not None and f > 0:
        check_record_length(run, f)


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
    finite = np.isfinite(v)
    if not finite.all():                       # a copy only when some samples are dropped
        v = v[finite]
    del finite
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


SCAN_LIMITS = {"velocity": (1e3, "m/s"), "displacement": (1.0, "m"), "reference": (1e5, "A")}
"""Largest plausible magnitude of a scan's records: a vibration of 1 km/s or 1 m, a coil
current of 100 kA; beyond, the file's unit (or its ``fs``) is wrong."""


FRF_LIMITS = {"velocity": (1e6, "m/s per A"), "displacement": (1e3, "m per A")}
"""Largest plausible magnitude of a broadband scan's FRF: the vibrations of SCAN_LIMITS at a
drive of 1 mA."""


SCAN_FLOORS = {"response": 1e-15, "reference": 1e-12}
"""Below these peaks (m/s or m; A) a scan's records hold no signal at all."""


def check_scan_values(scan: Scan) -> None:
    """Raise DataError when a scan's sampling or records are not finite or not plausible.

    Parameters
    ----------
    scan : Scan
        The scan as read.

    Raises
    ------
    DataError
        Naming the scan file, the record (point number and coordinates) and the value.
    """
    where = f"scan '{scan.source}'"
    if not (np.isfinite(scan.fs) and 0 < scan.fs <= 1e9):
        raise DataError(f"{where}: sampling rate {scan.fs:.6g} Hz; expected a positive rate up "
                        "to 1e9 Hz")
    if not np.all(np.isfinite(scan.points)):
        k = int(np.flatnonzero(~np.all(np.isfinite(scan.points), axis=1))[0])
        raise DataError(f"{where}: point {k + 1} has coordinates {scan.points[k].tolist()}; "
                        "expected finite numbers (m)")
    for key, records in (("response", scan.response), ("reference", scan.reference)):
        kind = "reference" if key == "reference" else scan.quantity
        limit, unit = SCAN_LIMITS[kind]
        for k, rec in enumerate(records):
            at = f"{where}: {key} record of point {k + 1} (x = {scan.points[k, 0]:.4g} m)"
            bad = ~np.isfinite(rec)
            if bad.any():
                raise DataError(f"{at} holds {int(bad.sum())} NaN or infinite samples, the first "
                                f"at t={int(np.flatnonzero(bad)[0]) / scan.fs:.6g} s")
            peak = float(np.max(np.abs(rec))) if rec.size else 0.0
            if peak > limit:
                raise DataError(f"{at} reaches {peak:.4g} {unit}; a {kind} beyond {limit:g} "
                                f"{unit} is not plausible (a wrong unit or a damaged file?)")
        check_plausible(records.ravel(), key, scan.source, 0.0, scan.fs, what="scan")
        peak = float(np.max(np.abs(records))) if records.size else 0.0
        floor = SCAN_FLOORS[key]
        if not peak > floor:
            raise DataError(f"{where}: every {key} record stays within {peak:.3g} (at most "
                            f"{floor:g} in SI units); no signal was recorded (a wrong unit?)")


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
            raise DataError(f"record {i} holds {int(bad.sum())} NaN or infinite samples, the "
                            f"first at sample {int(np.flatnonzero(bad)[0])}")
    return out


# --- from channel_checks ---
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
    import scipy.signal  # on use: a steady stream starts without it

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
        import scipy.signal  # on use: a steady stream starts without it

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
