"""Run recordings: CSV, NI TDMS and HDF5 (INTERFACES.md section 3), and result tables.

A run file holds uniformly sampled, named channels:

- CSV: a header row whose first column is ``time`` [s], then one numeric column per channel;
- TDMS: one group, one channel per signal, sampling from the ``wf_increment`` property
  (start from ``wf_start_offset``) or from a channel named ``time``;
- HDF5: one root dataset per channel, the rate in the root attribute ``fs`` [Hz] (optionally
  ``t0`` [s]), or a root dataset named ``time``.

Reading checks what would silently spoil an estimate and says where, in one line: no samples,
a non-numeric cell, NaN or infinite samples, non-uniform time stamps, fewer than
:data:`forcecal.checks.MIN_SAMPLES` samples. The checks on the data themselves (sample count,
equal lengths, finite samples, and :func:`forcecal.checks.check_clipping` for saturated
channels) live in :mod:`forcecal.checks`; the ones on the file's layout and time stamps live here.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping
from pathlib import Path

import h5py
import numpy as np
from nptdms import ChannelObject, TdmsFile, TdmsWriter

from .._atomic import atomic_path, write_text_atomic
from ..checks import check_equal_lengths, check_finite, check_plausible, check_sample_count
from ..errors import DataError, InputError
from ..records import Run
from ._run_values import decimal_resolution, finite_number, positive_number, tdms_log

__all__ = [
    "RUN_SUFFIXES",
    "read_run",
    "read_table_csv",
    "write_run_csv",
    "write_run_hdf5",
    "write_run_tdms",
    "write_table_csv",
    "write_table_hdf5",
]

RUN_SUFFIXES = (".csv", ".tdms", ".h5", ".hdf5")
_UNIFORM_RTOL = 1e-6  # allowed deviation of a time step from the mean step, relative
_ROUNDING_CAP = 0.25  # rounded stamps excuse at most this share of a step
_MIN_RATE = 1e-3  # Hz: one sample in 17 minutes; slower is a damaged increment
_MAX_RATE = 1e9  # Hz: no DAQ samples faster; a larger rate is a damaged or mis-scaled file
_MAX_T0 = 1e10  # s: about 300 years; a later start is a damaged stamp


# --------------------------------------------------------------------------------------------
# reading runs


def read_run(path: str | Path) -> Run:
    """Read one run recording, choosing the reader from the file suffix.

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.tdms``, ``.h5`` or ``.hdf5``.

    Returns
    -------
    Run
        ``channels`` name -> (n_samples,) raw values, ``fs`` [Hz], ``t0`` [s], ``name`` = the
        file stem, ``source`` = ``str(path)``.

    Raises
    ------
    InputError
        Missing file, unknown suffix, unreadable file, missing ``time`` column or sampling.
    DataError
        Empty, non-numeric, NaN/infinite, non-uniformly sampled or too short records.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    readers = {
        ".csv": _read_csv_run,
        ".tdms": _read_tdms_run,
        ".h5": _read_hdf5_run,
        ".hdf5": _read_hdf5_run,
    }
    if suffix not in readers:
        raise InputError(
            f"run '{path}': unknown file type '{path.suffix}'; accepted: {', '.join(RUN_SUFFIXES)}"
        )
    if not path.is_file():
        raise InputError(f"run '{path}': file does not exist")
    return readers[suffix](path)


def _read_csv_run(path: Path) -> Run:
    header, cells, rows = _parse_csv(path, "run")
    values = _numeric(cells, header, rows, path, "run")
    time = values[:, 0]
    check_sample_count(time.size, path)

    def where(k: int) -> str:
        return f"row {rows[k]}"

    _check_finite_time(time, path, where)
    resolution = np.zeros_like(time)
    if _first_irregular_step(time, resolution) is not None:  # allow for the digits written
        resolution = decimal_resolution([row[0] for row in cells], time)
    fs, t0 = _sampling_from_time(time, path, resolution, where)
    channels = {name: values[:, j] for j, name in enumerate(header[1:], start=1)}
    return _finish(path, channels, fs, t0)


def _read_tdms_run(path: Path) -> Run:
    with tdms_log() as messages:
        try:
            tdms = TdmsFile.read(path)
            groups = [g for g in tdms.groups() if g.channels()]
            if len(groups) != 1:
                names = ", ".join(repr(g.name) for g in groups) or "none with channels"
                raise InputError(f"run '{path}': expected one group of channels, found {names}")
            raw = {ch.name: ch for ch in groups[0].channels()}
            time_name = next((n for n in raw if n.strip().lower() == "time"), None)
            channels = {n: _tdms_values(ch, path) for n, ch in raw.items() if n != time_name}
            time = _tdms_time(raw[time_name], path) if time_name is not None else None
        except (InputError, DataError):
            raise
        except Exception as exc:  # npTDMS raises assorted errors on a malformed file
            raise InputError(f"run '{path}': not a readable TDMS file ({_first_line(exc)})"
                             ) from exc
    if messages:
        raise InputError(f"run '{path}': a damaged TDMS file (npTDMS: {messages[0]})")
    if not channels:
        raise DataError(f"run '{path}': group {groups[0].name!r} holds no signal channels")
    first_name = next(iter(channels))
    first = raw[first_name]
    if "wf_increment" in first.properties:
        increment = positive_number(first.properties["wf_increment"],
                                     f"channel {first_name!r}: property 'wf_increment'", path)
        for name in channels:
            other = raw[name].properties.get("wf_increment")
            value = positive_number(other, f"channel {name!r}: property 'wf_increment'", path)
            if abs(value - increment) > 1e-9 * increment:
                raise DataError(
                    f"run '{path}': channel {name!r} is sampled every {value:.6g} s "
                    f"('wf_increment'), channel {first_name!r} every {increment:.6g} s; a run's "
                    "channels share one rate")
        t0 = finite_number(first.properties.get("wf_start_offset", 0.0),
                            f"channel {first_name!r}: property 'wf_start_offset'", path)
        return _sampled(path, channels, 1.0 / increment, t0)
    if time is None:
        raise InputError(
            f"run '{path}': no 'wf_increment' property and no 'time' channel; "
            "cannot tell the sampling"
        )
    return _with_time_channel(path, time, channels)


def _read_hdf5_run(path: Path) -> Run:
    try:
        with h5py.File(path, "r") as h5:
            attrs = {key: h5.attrs[key] for key in ("fs", "t0") if key in h5.attrs}
            data = {n: h5[n][()] for n in h5 if isinstance(h5[n], h5py.Dataset)}
    except Exception as exc:  # h5py raises OSError, KeyError, RuntimeError... on damage
        raise InputError(f"run '{path}': not a readable HDF5 file ({_first_line(exc)})") from exc
    time_name = next((n for n in data if n.strip().lower() == "time"), None)
    channels = {n: _hdf5_values(v, n, path) for n, v in data.items() if n != time_name}
    if not channels:
        raise DataError(f"run '{path}': no channel datasets at the file root")
    if "fs" in attrs:
        fs = positive_number(attrs["fs"], "root attribute 'fs'", path)
        t0 = finite_number(attrs.get("t0", 0.0), "root attribute 't0'", path)
        return _sampled(path, channels, fs, t0)
    if time_name is None:
        raise InputError(
            f"run '{path}': no 'fs' attribute on the file root and no 'time' dataset; "
            "cannot tell the sampling"
        )
    return _with_time_channel(path, _hdf5_values(data[time_name], time_name, path), channels)


def _sampled(path: Path, channels: dict[str, np.ndarray], fs: float, t0: float) -> Run:
    """A run whose sampling rate the file states: equal, long enough channels."""
    check_equal_lengths(channels, path)
    check_sample_count(len(next(iter(channels.values()))), path)
    return _finish(path, channels, fs, t0)


def _with_time_channel(path: Path, time: np.ndarray, channels: dict[str, np.ndarray]) -> Run:
    """Finish a run whose sampling comes from a time channel."""
    check_equal_lengths({"time": time, **channels}, path)
    check_sample_count(time.size, path)
    _check_finite_time(time, path, _sample_label)
    fs, t0 = _sampling_from_time(time, path, np.zeros_like(time), _sample_label)
    return _finish(path, channels, fs, t0)


def _finish(path: Path, channels: dict[str, np.ndarray], fs: float, t0: float) -> Run:
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


def _check_finite_time(time: np.ndarray, path: Path, where: Callable[[int], str]) -> None:
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


def _first_irregular_step(time: np.ndarray, resolution: np.ndarray) -> int | None:
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


def _sampling_from_time(
    time: np.ndarray, path: Path, resolution: np.ndarray, where: Callable[[int], str]
) -> tuple[float, float]:
    """(fs [Hz], t0 [s]) of uniform time stamps; DataError saying where they are not."""
    step = (time[-1] - time[0]) / (time.size - 1)
    if not step > 0:
        raise DataError(f"run '{path}': time stamps do not increase")
    k = _first_irregular_step(time, resolution)
    if k is not None:
        actual = time[k + 1] - time[k]
        raise DataError(
            f"run '{path}': time stamps are not uniform: the step of {actual:.6g} s at "
            f"t={time[k]:.6g} s ({where(k)}) differs from the mean step {step:.6g} s by "
            f"{100 * abs(actual - step) / step:.3g} %"
        )
    return 1.0 / step, float(time[0])


# --------------------------------------------------------------------------------------------
# CSV parsing


def _parse_csv(path: Path, what: str) -> tuple[list[str], list[list[str]], list[int]]:
    """Header names, data rows (cells as text) and their 1-based row numbers in the file."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} '{path}': not a text (UTF-8) CSV file") from exc
    reader = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    cells: list[list[str]] = []
    rows: list[int] = []
    try:
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            if header is None:
                header = [cell.strip() for cell in row]
                continue
            cells.append(row)
            rows.append(reader.line_num)
    except csv.Error as exc:  # e.g. a cell beyond the field size limit, a NUL byte
        raise DataError(f"{what} '{path}': row {reader.line_num + 1} cannot be read as CSV "
                        f"({exc})") from None
    if header is None:
        raise DataError(f"{what} '{path}': the file is empty")
    _check_header(header, path, what)
    if not cells:
        raise DataError(f"{what} '{path}': a header but no data rows")
    for row, number in zip(cells, rows, strict=True):
        if len(row) != len(header):
            raise DataError(
                f"{what} '{path}': row {number} has {len(row)} cells, the header {len(header)}"
            )
    return header, cells, rows


def _check_header(header: list[str], path: Path, what: str) -> None:
    if header[0].lower() != "time":
        raise InputError(f"{what} '{path}': the first column is {header[0]!r}; expected 'time'")
    if len(header) < 2:
        raise DataError(f"{what} '{path}': no channel columns after 'time'")
    seen: set[str] = set()
    for column, name in enumerate(header, start=1):
        if not name:
            raise InputError(f"{what} '{path}': column {column} has no name in the header")
        if name in seen:
            raise InputError(f"{what} '{path}': column {name!r} appears twice in the header")
        seen.add(name)


def _numeric(
    cells: list[list[str]], header: list[str], rows: list[int], path: Path, what: str
) -> np.ndarray:
    """(n_rows, n_columns) float array; DataError naming row and column of a bad cell."""
    if not any("_" in cell for row in cells for cell in row):  # float() takes '1_000'
        try:
            return np.array(cells, dtype=float)
        except ValueError:
            pass
    for row, number in zip(cells, rows, strict=True):
        for cell, name in zip(row, header, strict=True):
            try:
                if "_" in cell:
                    raise ValueError(cell)
                float(cell)
            except ValueError:
                raise DataError(
                    f"{what} '{path}': row {number}, column {name!r}: {cell.strip()!r} is not "
                    "a number"
                ) from None
    raise DataError(f"{what} '{path}': a cell is not a number")  # pragma: no cover


# --------------------------------------------------------------------------------------------
# TDMS / HDF5 values


def _tdms_values(channel, path: Path) -> np.ndarray:
    data = np.asarray(channel[:])
    if not np.issubdtype(data.dtype, np.number):
        raise DataError(f"run '{path}': channel {channel.name!r} is not numeric ({data.dtype})")
    return data.astype(float)


def _tdms_time(channel, path: Path) -> np.ndarray:
    """Time channel [s]; absolute timestamps become seconds since the first one."""
    data = np.asarray(channel[:])
    if np.issubdtype(data.dtype, np.datetime64):
        return (data - data[0]) / np.timedelta64(1, "s") if data.size else data.astype(float)
    return _tdms_values(channel, path)


def _hdf5_values(value: np.ndarray, name: str, path: Path) -> np.ndarray:
    data = np.asarray(value)
    if data.ndim != 1 or not np.issubdtype(data.dtype, np.number):
        raise DataError(
            f"run '{path}': dataset {name!r} is not a numeric 1-D channel "
            f"(shape {data.shape}, {data.dtype})"
        )
    return data.astype(float)


def _rate_from_increment(increment: object, path: Path) -> float:
    return 1.0 / positive_number(increment, "property 'wf_increment'", path)


# --------------------------------------------------------------------------------------------
# result tables


def read_table_csv(path: str | Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Read a CSV table with a ``time`` column (e.g. ``NAME.forces.csv``).

    Parameters
    ----------
    path : str or Path
        The CSV file: a header row, ``time`` first.

    Returns
    -------
    time : (n_rows,) array [s]
        The ``time`` column.
    columns : dict name -> (n_rows,) array
        The other columns, in file order.

    Raises
    ------
    InputError
        A missing file or a malformed header.
    DataError
        An empty table or a cell that is not a number (named by row and column).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"table '{path}': file does not exist")
    header, cells, rows = _parse_csv(path, "table")
    values = _numeric(cells, header, rows, path, "table")
    return values[:, 0], {name: values[:, j] for j, name in enumerate(header[1:], start=1)}


def write_table_csv(path: str | Path, time: np.ndarray, columns: Mapping[str, np.ndarray]) -> Path:
    """Write ``time`` and named columns as CSV, atomically, every value exactly (shortest repr).

    Parameters
    ----------
    path : str or Path
        The CSV file, replaced atomically.
    time : (n_rows,) array [s]
        The first column.
    columns : mapping name -> (n_rows,) array
        The other columns, in order.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A column name CSV cannot hold (``time``, empty, or with a comma, quote or line
        break), or a column whose length differs from ``time``.
    """
    time = np.asarray(time, dtype=float).ravel()
    names = list(columns)
    for name in names:
        if name.strip().lower() == "time" or not name or any(c in name for c in ',"\r\n'):
            raise InputError(f"table '{path}': column name {name!r} cannot be written to CSV")
    table = [time] + [np.asarray(columns[n], dtype=float).ravel() for n in names]
    for name, column in zip(["time", *names], table, strict=True):
        if column.size != time.size:
            raise InputError(
                f"table '{path}': column {name!r} has {column.size} values, time has {time.size}"
            )
    lines = [",".join(["time", *names])]
    lines += [",".join(map(repr, row)) for row in np.column_stack(table).tolist()]
    return write_text_atomic(path, "\n".join(lines) + "\n")


# --------------------------------------------------------------------------------------------
# writing runs


def write_run_csv(run: Run, path: str | Path) -> Path:
    """Write a run as CSV (``time`` then one column per channel), atomically.

    Parameters
    ----------
    run : Run
        The recording.
    path : str or Path
        The CSV file, replaced atomically.

    Returns
    -------
    Path
        ``path``.
    """
    return write_table_csv(path, run.time, run.channels)


def write_run_tdms(run: Run, path: str | Path, group: str = "forcecal") -> Path:
    """Write a run as NI TDMS: one group, one float64 channel per signal, atomically.

    Each channel carries ``wf_increment`` = 1/fs [s], ``wf_start_offset`` = t0 [s] and
    ``wf_samples``.

    Parameters
    ----------
    run : Run
        The recording.
    path : str or Path
        The ``.tdms`` file, replaced atomically.
    group : str
        The name of the one group.

    Returns
    -------
    Path
        ``path``.
    """
    properties = {
        "wf_increment": 1.0 / run.fs,
        "wf_start_offset": float(run.t0),
        "wf_samples": run.n_samples,
    }
    objects = [
        ChannelObject(group, name, np.asarray(values, dtype=float), properties=properties)
        for name, values in run.channels.items()
    ]
    with atomic_path(path) as tmp, TdmsWriter(tmp) as writer:
        writer.write_segment(objects)
    return Path(path)


def write_run_hdf5(run: Run, path: str | Path) -> Path:
    """Write a run as HDF5: one root dataset per channel, root attributes fs, t0; atomically.

    Parameters
    ----------
    run : Run
        The recording.
    path : str or Path
        The ``.h5`` file, replaced atomically.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A channel name that cannot name an HDF5 dataset (empty, ``.`` or with a ``/``).
    """
    for name in run.channels:
        if not name or "/" in name or name == ".":
            raise InputError(f"run '{path}': channel name {name!r} cannot name an HDF5 dataset")
    with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=True) as h5:
        h5.attrs["fs"] = float(run.fs)
        h5.attrs["t0"] = float(run.t0)
        for name, values in run.channels.items():
            h5.create_dataset(name, data=np.asarray(values, dtype=float))
    return Path(path)


def write_table_hdf5(path: str | Path, time: np.ndarray,
                     columns: Mapping[str, np.ndarray]) -> Path:
    """Write ``time`` and named columns as HDF5 in the run layout, atomically.

    Root datasets, attribute ``fs`` from the mean time step and ``t0``; :func:`read_run`
    reads it back.

    Parameters
    ----------
    path : str or Path
        The ``.h5`` file, replaced atomically.
    time : (n_rows,) array [s]
        Uniform time stamps.
    columns : mapping name -> (n_rows,) array
        The columns, in order.

    Returns
    -------
    Path
        ``path``.
    """
    time = np.asarray(time, dtype=float).ravel()
    step = float(np.mean(np.diff(time))) if time.size > 1 else 1.0
    return write_run_hdf5(Run(channels=dict(columns), fs=1.0 / step,
                              t0=float(time[0]) if time.size else 0.0), path)


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when it has none)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
