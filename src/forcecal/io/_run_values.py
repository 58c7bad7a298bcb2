"""What every run reader shares: numbers in properties and attributes, time stamps made into
a sampling rate (with the decimal resolution of written stamps), the checks of a finished run,
and npTDMS's log turned into forcecal's messages."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import DataError, InputError
from ..records import Run
from ..signals.checks import check_equal_lengths, check_finite, check_plausible, check_sample_count

__all__: list[str] = []

_UNIFORM_RTOL = 1e-6  # allowed deviation of a time step from the mean step, relative
_ROUNDING_CAP = 0.25  # rounded stamps excuse at most this share of a step
_MIN_RATE = 1e-3  # Hz: one sample in 17 minutes; slower is a damaged increment
_MAX_RATE = 1e9  # Hz: no DAQ samples faster; a larger rate is a damaged or mis-scaled file
_MAX_T0 = 1e10  # s: about 300 years; a later start is a damaged stamp
ABSOLUTE_TIME = 1e8
"""[s] Time stamps from this on (three years) are absolute, since an epoch: the run starts
at 0, its time read as seconds from the first sample."""


class RunFile(NamedTuple):
    """A run as its file names it, before the rig's channel map.

    Attributes
    ----------
    run : Run
        The channels under the file's names, checked.
    aliases : mapping other name -> channel name
        Other names the file gives a channel (a CSV header with its unit, ``"R1 [N]"``; a UFF
        record's node and direction, ``"node 12 +Z"``, or its ID line).
    units : mapping channel name -> unit text
        The units the file states (a CSV header ``"s1 [mm]"`` or units row); others absent.
    """

    run: Run
    aliases: Mapping[str, str] = {}
    units: Mapping[str, str] = {}


@contextlib.contextmanager
def tdms_log() -> Iterator[list[str]]:
    """Collect what npTDMS logs (it prints to stderr by itself) instead of letting it print."""
    messages: list[str] = []

    class _Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            messages.append(record.getMessage())

    collect = _Collect(logging.WARNING)
    names = [n for n in list(logging.root.manager.loggerDict) if n.startswith("nptdms")]
    saved = []
    for name in names:
        logger = logging.getLogger(name)
        saved.append((logger, list(logger.handlers), logger.propagate))
        logger.handlers = [collect]
        logger.propagate = False
    try:
        yield messages
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers = handlers
            logger.propagate = propagate


def decimal_resolution(texts: Sequence[str], values: np.ndarray) -> np.ndarray:
    """(n,) resolution [s] of decimal numbers as the file writes them.

    A writer keeps either a fixed number of decimals ('%.6f': 1e-6 everywhere) or of
    significant digits ('%.6g', repr: 1e-5 at 9.87654, 1e-7 at 0.0123457); trailing zeros may
    be dropped. The finest decimal step seen and the most significant digits seen bound the
    resolution from below in either case; the larger of the two bounds is the resolution.
    """
    finest, digits = np.inf, 1
    for text in texts:
        mantissa, _, exponent = text.strip().lower().partition("e")
        whole, _, decimals = mantissa.lstrip("+-").partition(".")
        try:
            finest = min(finest, 10.0 ** (int(exponent or 0) - len(decimals)))
        except ValueError:
            continue
        digits = max(digits, len((whole + decimals).lstrip("0")))
    finest = 0.0 if not np.isfinite(finest) else finest
    with np.errstate(divide="ignore"):
        magnitude = np.floor(np.log10(np.abs(values)))
    relative = np.where(np.isfinite(magnitude), 10.0 ** (magnitude - digits + 1), 0.0)
    return np.maximum(finest, relative)


def finite_number(value: object, what: str, path: Path) -> float:
    """A finite number (a time offset); InputError naming ``what`` otherwise."""
    try:
        number = float(np.asarray(value, dtype=float).item())
    except (TypeError, ValueError):
        number = float("nan")
    if not np.isfinite(number):
        raise InputError(f"run '{path}': {what} is {value!r}; expected a finite number (s)")
    return number


def positive_number(value: object, what: str, path: Path) -> float:
    try:
        number = float(np.asarray(value, dtype=float).item())
    except (TypeError, ValueError):
        number = float("nan")
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"run '{path}': {what} is {value!r}; expected a positive number")
    return number


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when it has none)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


# --------------------------------------------------------------------------------------------
# a run from its channels and sampling


def sampled_run(path: Path, channels: dict[str, np.ndarray], fs: float, t0: float) -> Run:
    """A run whose sampling rate the file states: equal, long enough channels."""
    check_equal_lengths(channels, path)
    check_sample_count(len(next(iter(channels.values()))), path)
    return finish_run(path, channels, fs, t0)


def run_from_time(path: Path, time: np.ndarray, channels: dict[str, np.ndarray]) -> Run:
    """A run whose sampling comes from a time channel [s] (named by sample index)."""
    check_equal_lengths({"time": time, **channels}, path)
    check_sample_count(time.size, path)
    check_finite_time(time, path, _sample_label)
    fs, t0 = sampling_from_time(time, path, np.zeros_like(time), _sample_label)
    return finish_run(path, channels, fs, t0)


def finish_run(path: Path, channels: dict[str, np.ndarray], fs: float, t0: float) -> Run:
    """Check every channel for NaN/inf and absurd values, and build the Run."""
    if not (np.isfinite(fs) and _MIN_RATE <= fs <= _MAX_RATE and abs(t0) <= _MAX_T0):
        raise DataError(f"run '{path}': sampling rate {fs:.6g} Hz and start time {t0:.6g} s; "
                        f"expected a rate from {_MIN_RATE:g} to {_MAX_RATE:g} Hz and a start "
                        f"time within {_MAX_T0:g} s")
    for name, values in channels.items():
        check_finite(values, name, path, t0, fs)
        check_plausible(values, name, path, t0, fs)
    return Run(channels=channels, fs=fs, t0=t0, name=path.stem, source=str(path))


# --------------------------------------------------------------------------------------------
# time stamps


def _sample_label(k: int) -> str:
    return f"sample {k}"


def check_finite_time(time: np.ndarray, path: Path, where: Callable[[int], str]) -> None:
    """DataError at the first NaN, infinite or absurdly late time stamp (``where(k)`` names
    stamp k: a row of a CSV file, a sample of a channel)."""
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        raise DataError(
            f"run '{path}': time has {bad.size} NaN or infinite values, the first at "
            f"{where(int(bad[0]))}"
        )
    far = np.flatnonzero(np.abs(time) > _MAX_T0)
    if far.size:
        raise DataError(f"run '{path}': time {time[far[0]]:.6g} s at {where(int(far[0]))} is "
                        f"beyond {_MAX_T0:g} s; expected time stamps in s")


def first_irregular_step(time: np.ndarray, resolution: np.ndarray) -> int | None:
    """Index k of the first step time[k+1] - time[k] off the mean step, or None.

    Allowed deviation: ``_UNIFORM_RTOL`` of the mean step, or what rounding the two stamps to
    their ``resolution`` (n_samples,) [s] and to float64 can cause, whichever is larger; but
    never a quarter step, so that a dropped or repeated sample (a whole step) always shows.
    """
    step = (time[-1] - time[0]) / (time.size - 1)
    rounding = np.maximum(resolution[:-1], resolution[1:])
    rounding = rounding + 4 * np.finfo(float).eps * np.maximum(np.abs(time[:-1]), np.abs(time[1:]))
    tolerance = np.maximum(_UNIFORM_RTOL * abs(step), np.minimum(rounding, _ROUNDING_CAP * step))
    off = np.flatnonzero(np.abs(np.diff(time) - step) > tolerance)
    return int(off[0]) if off.size else None


def sampling_from_time(
    time: np.ndarray, path: Path, resolution: np.ndarray, where: Callable[[int], str]
) -> tuple[float, float]:
    """(fs [Hz], t0 [s]) of uniform time stamps; DataError saying where they are not. Absolute
    stamps (:data:`ABSOLUTE_TIME` on) give t0 = 0: seconds from the first sample."""
    step = (time[-1] - time[0]) / (time.size - 1)
    if not step > 0:
        raise DataError(f"run '{path}': time stamps do not increase")
    k = first_irregular_step(time, resolution)
    if k is not None:
        actual = time[k + 1] - time[k]
        raise DataError(
            f"run '{path}': time stamps are not uniform: the step of {actual:.6g} s at "
            f"t={time[k]:.6g} s ({where(k)}) differs from the mean step {step:.6g} s by "
            f"{100 * abs(actual - step) / step:.3g} %"
        )
    return 1.0 / step, start_time(float(time[0]))


def start_time(first: float) -> float:
    """t0 [s] of a run whose first time stamp is ``first`` [s]: 0 for an absolute one."""
    return 0.0 if first >= ABSOLUTE_TIME else first
