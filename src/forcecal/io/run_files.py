"""Run recordings: CSV, NI TDMS, HDF5 and UFF time records (INTERFACES.md section 3), and
result tables. A run holds the gauges, probes and coil current of METHOD.md section 1,
uniformly sampled, named channels:

- CSV: a header row whose first column is the time, then one numeric column per channel
  (dialects of lab exports: see :mod:`forcecal.io.csv_runs`);
- TDMS: one group of channels (chosen by name when the file has several), sampling from the
  ``wf_increment`` property (start from ``wf_start_offset``) or from a channel named ``time``;
- HDF5: one dataset per channel at the root or in one group (chosen by path when the file
  has several), the rate in the attribute ``fs`` [Hz] of that group or of the root
  (optionally ``t0`` [s]), or a dataset named ``time``;
- UFF: one dataset-58 time record per channel (see :mod:`forcecal.io.uff_runs`).

Given the rig, a run's channels are renamed by its ``[channels]`` map and the units the file
states are checked against the rig's scales (:mod:`forcecal.io.run_channels`). A folder stands
for the run files in it (:func:`run_paths`).

Reading checks the file's layout and time stamps and says where, in one line (no samples, a
non-numeric cell, NaN or infinite samples, non-uniform time stamps, too few samples); the
checks on the data themselves live in :mod:`forcecal.signals.checks`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
from nptdms import ChannelObject, TdmsFile, TdmsWriter

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..records import Run
from ..signals.checks import check_sample_count
from ._run_values import (
    ABSOLUTE_TIME,
    RunFile,
    check_finite_time,
    decimal_resolution,
    finish_run,
    finite_number,
    first_irregular_step,
    first_line,
    positive_number,
    run_from_time,
    sampled_run,
    sampling_from_time,
    tdms_log,
)
from ._time_column import mapped_time, since_first, time_channel
from .csv_runs import TIME_UNITS, read_csv_columns
from .run_channels import apply_rig
from .table_writer import table_writer
from .uff_runs import read_uff_run

if TYPE_CHECKING:
    from ..rig import Rig

__all__ = ["read_run", "read_table_csv", "run_paths", "write_run_csv", "write_table_csv"]

_CSV_BLOCK = 1 << 16
"""Rows formatted and written at once by :func:`write_table_csv`."""

RUN_SUFFIXES = (".csv", ".tdms", ".h5", ".hdf5", ".uff", ".unv")
OUTPUT_SUFFIXES = (".forces.csv", ".forces.h5", ".forces.mat", ".forces.uff", ".stream.csv",
                   ".stream.h5")
"""What forcecal writes beside runs; a folder of runs skips them."""


# --------------------------------------------------------------------------------------------
# reading runs


def read_run(path: str | Path, rig: Rig | None = None, *, group: str | None = None) -> Run:
    """Read one run recording, choosing the reader from the file suffix.

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.tdms``, ``.h5``, ``.hdf5``, ``.uff`` or ``.unv``.
    rig : Rig, optional
        The rig: its ``[channels]`` map renames the file's channels to the rig's names, its
        ``acquisition.group`` chooses a TDMS file's group, and the units the file states are
        checked against its scales. Without it the channels keep the file's names.
    group : str, optional
        The TDMS group, or the HDF5 group's path, to read (instead of the rig's
        ``acquisition.group``); needed when a file has several groups of channels.

    Returns
    -------
    Run
        ``channels`` name -> (n_samples,) raw values, ``fs`` [Hz], ``t0`` [s], ``name`` = the
        file stem, ``source`` = ``str(path)``.

    Raises
    ------
    InputError
        Missing file, unknown suffix, unreadable file, missing ``time`` column or sampling,
        several TDMS or HDF5 groups of channels and none chosen.
    DataError
        Empty, non-numeric, NaN/infinite, non-uniformly sampled or too short records; a
        channel of the rig's map missing from the file; a stated unit the rig's scale does not
        convert.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in RUN_SUFFIXES:
        raise InputError(
            f"run '{path}': unknown file type '{path.suffix}'; accepted: {', '.join(RUN_SUFFIXES)}"
        )
    if not path.is_file():
        raise InputError(f"run '{path}': file does not exist")
    if group is None and rig is not None:
        group = rig.run_group
    if suffix == ".csv":
        loaded = _read_csv_run(path, rig)
    elif suffix == ".tdms":
        loaded = RunFile(_read_tdms_run(path, group, rig))
    elif suffix in (".uff", ".unv"):
        loaded = read_uff_run(path)
    else:
        loaded = RunFile(_read_hdf5_run(path, group, rig))
    if rig is None:
        return loaded.run
    return apply_rig(loaded, rig)


def run_paths(paths: Sequence[str | Path]) -> tuple[list[str], list[str]]:
    """The run files named: a folder stands for every run file in it, sorted by name.

    Parameters
    ----------
    paths : sequence of str or Path
        Run files and folders of runs.

    Returns
    -------
    runs : list of str
        The run files, folders expanded in place.
    notes : list of str
        One line per folder that held other entries, naming what was skipped: files of other
        types, sub-folders and forcecal's own outputs (``NAME.forces.csv``, ...); hidden
        entries are skipped silently.

    Raises
    ------
    InputError
        A folder that holds no run file.
    """
    runs: list[str] = []
    notes: list[str] = []
    for item in paths:
        folder = Path(item)
        if not folder.is_dir():
            runs.append(str(item))
            continue
        found, skipped = [], []
        for entry in sorted(folder.iterdir(), key=lambda e: e.name):
            name = entry.name
            if name.startswith("."):
                continue
            if entry.is_file() and name.lower().endswith(RUN_SUFFIXES) \
                    and not name.lower().endswith(OUTPUT_SUFFIXES):
                found.append(str(entry))
            else:
                skipped.append(name + ("/" if entry.is_dir() else ""))
        if not found:
            raise InputError(f"run folder '{folder}': no run files in it (expected "
                             f"{', '.join(RUN_SUFFIXES)})")
        runs += found
        if skipped:
            shown = ", ".join(repr(n) for n in skipped[:5])
            more = f" and {len(skipped) - 5} more" if len(skipped) > 5 else ""
            notes.append(f"run folder '{folder}': {len(found)} run files; skipped {shown}"
                         f"{more} (not run files)")
    return runs, notes


def _read_csv_run(path: Path, rig: Rig | None) -> RunFile:
    table = read_csv_columns(path, "run", rig)
    unit = table.units[0]
    if unit not in TIME_UNITS:
        raise InputError(f"run '{path}': the time column is in {unit!r}; expected s, ms or us")
    factor = TIME_UNITS[unit]
    time = table.values[:, 0] * factor if factor != 1.0 else table.values[:, 0]
    if time.size and time[0] >= ABSOLUTE_TIME:  # since an epoch: exactly, from the digits
        time = since_first(table.time_texts()) * factor
    check_sample_count(time.size, path)
    check_finite_time(time, path, table.row)
    resolution = np.zeros_like(time)
    if first_irregular_step(time, resolution) is not None:  # allow for the digits written
        resolution = decimal_resolution(table.time_texts(), table.values[:, 0]) * factor
    fs, t0 = sampling_from_time(time, path, resolution, table.row)
    names = table.names[1:]
    channels = {name: table.values[:, j] for j, name in enumerate(names, start=1)}
    aliases = {label: name for label, name in zip(table.labels[1:], names, strict=True)
               if label != name}
    units = {name: u for name, u in zip(names, table.units[1:], strict=True) if u}
    return RunFile(finish_run(path, channels, fs, t0), aliases, units)


def _read_tdms_run(path: Path, group: str | None, rig: Rig | None) -> Run:
    with tdms_log() as messages:
        try:
            tdms = TdmsFile.read(path)
            chosen = _tdms_group(tdms, path, group)
            raw = {ch.name: ch for ch in chosen.channels()}
            time_name = time_channel(list(raw), mapped_time(rig), path, rig)
            channels = {n: _tdms_values(ch, path) for n, ch in raw.items() if n != time_name}
            time = _tdms_time(raw[time_name], path) if time_name is not None else None
        except (InputError, DataError):
            raise
        except Exception as exc:  # npTDMS raises assorted errors on a malformed file
            raise InputError(f"run '{path}': not a readable TDMS file ({first_line(exc)})"
                             ) from exc
    if messages:
        raise InputError(f"run '{path}': a damaged TDMS file (npTDMS: {messages[0]})")
    if not channels:
        raise DataError(f"run '{path}': group {chosen.name!r} holds no signal channels")
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
        return sampled_run(path, channels, 1.0 / increment, t0)
    if time is None:
        raise InputError(
            f"run '{path}': no 'wf_increment' property and no 'time' channel; "
            "cannot tell the sampling"
        )
    return run_from_time(path, time, channels)


def _tdms_group(tdms, path: Path, group: str | None):
    """The group of channels to read: the one chosen, else the only one with channels."""
    if group is not None:
        by_name = {g.name: g for g in tdms.groups()}
        if group not in by_name:
            names = ", ".join(repr(g) for g in by_name) or "none"
            raise InputError(f"run '{path}': no group {group!r} (the group chosen for the runs); "
                             f"the file's groups: {names}")
        return by_name[group]
    groups = [g for g in tdms.groups() if g.channels()]
    if len(groups) != 1:
        names = ", ".join(repr(g.name) for g in groups) or "none with channels"
        hint = ("; choose one with --group NAME or [acquisition] group = \"NAME\" in the rig"
                if groups else "")
        raise InputError(f"run '{path}': expected one group of channels, found {names}{hint}")
    return groups[0]


def _read_hdf5_run(path: Path, group: str | None, rig: Rig | None) -> Run:
    try:
        with h5py.File(path, "r") as h5:
            where = _hdf5_group(h5, path, group)
            attrs = {key: where.attrs[key] if key in where.attrs else h5.attrs[key]
                     for key in ("fs", "t0") if key in where.attrs or key in h5.attrs}
            data = {n: where[n][()] for n in where if isinstance(where[n], h5py.Dataset)}
    except InputError:
        raise
    except Exception as exc:  # h5py raises OSError, KeyError, RuntimeError... on damage
        raise InputError(f"run '{path}': not a readable HDF5 file ({first_line(exc)})") from exc
    time_name = time_channel(list(data), mapped_time(rig), path, rig)
    channels = {n: _hdf5_values(v, n, path) for n, v in data.items() if n != time_name}
    if not channels:
        raise DataError(f"run '{path}': no channel datasets at the file root")
    if "fs" in attrs:
        fs = positive_number(attrs["fs"], "root attribute 'fs'", path)
        t0 = finite_number(attrs.get("t0", 0.0), "root attribute 't0'", path)
        return sampled_run(path, channels, fs, t0)
    if time_name is None:
        raise InputError(
            f"run '{path}': no 'fs' attribute on the file root and no 'time' dataset; "
            "cannot tell the sampling"
        )
    return run_from_time(path, _hdf5_values(data[time_name], time_name, path), channels)


def _hdf5_group(h5: h5py.File, path: Path, group: str | None) -> h5py.Group:
    """The group whose datasets are the channels: the one chosen (a path such as ``"Data"`` or
    ``"rig1/run3"``), else the root when it holds datasets, else its only group that does."""
    if group is not None:
        found = h5.get(group)
        if not isinstance(found, h5py.Group):
            names = ", ".join(repr(n) for n in _hdf5_channel_groups(h5)) or "none"
            raise InputError(f"run '{path}': no group {group!r} (the group chosen for the runs); "
                             f"the file's groups of datasets: {names}")
        return found
    if any(isinstance(v, h5py.Dataset) for v in h5.values()):
        return h5
    groups = _hdf5_channel_groups(h5)
    if len(groups) != 1:
        names = ", ".join(repr(n) for n in groups) or "none with datasets"
        hint = ("; choose one with --group NAME or [acquisition] group = \"NAME\" in the rig"
                if groups else "")
        raise InputError(f"run '{path}': expected one group of channels, found {names}{hint}")
    found = h5[groups[0]]
    assert isinstance(found, h5py.Group)
    return found


def _hdf5_channel_groups(h5: h5py.File) -> list[str]:
    """Every group (at any depth) that holds datasets, by path."""
    names: list[str] = []

    def visit(name: str, obj: object) -> None:
        if isinstance(obj, h5py.Group) and any(isinstance(v, h5py.Dataset)
                                               for v in obj.values()):
            names.append(name)

    h5.visititems(visit)
    return names


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
    return data.astype(float, copy=False)     # float64 as read: no second copy of the channel


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
    table = read_csv_columns(path, "table")
    time = table.values[:, 0] * TIME_UNITS.get(table.units[0], 1.0)
    return time, {name: table.values[:, j] for j, name in enumerate(table.names[1:], start=1)}


def write_table_csv(path: str | Path, time: np.ndarray, columns: Mapping[str, np.ndarray]) -> Path:
    """Write ``time`` and named columns as CSV, atomically, every value exactly (15 significant
    digits when they read back exactly, else 17), block by block (memory flat in the length).

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
    n = time.size
    with table_writer(path, names, 1.0, 0.0, digits=0, rows=n) as writer:
        for start in range(0, n, _CSV_BLOCK):
            stop = min(n, start + _CSV_BLOCK)
            writer.write(time[start:stop], np.array([c[start:stop] for c in table[1:]],
                                                    dtype=float).reshape(len(names), -1))
    return Path(path)


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
