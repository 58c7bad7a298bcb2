"""Run files read block by block, for the streaming estimator: memory flat in record length.

:func:`open_run_blocks` reads what it can in blocks and the rest whole:

- HDF5 with the rate in the root attribute ``fs``: every channel dataset is sliced;
- CSV in the plain layout (comma-separated, a time header cell, ``time`` or another of
  ``TIME_NAMES``, then channel names without units, times in s): pandas' C parser in chunks,
  with the whole-file reader's parameters, so the numbers are the same; the time stamps are
  first read on their own (one column) for the rate;
- anything else (TDMS, UFF, CSV dialects, HDF5 timed by a dataset, a time column the rig
  names), and any file the block readers find something odd in (a text cell, a short row,
  irregular stamps, a damaged dataset): ``read_run``, whole, which says what is wrong.

The channels are named as :func:`~forcecal.io.run_files.read_run` names them given the rig
(its ``[channels]`` map applied). :func:`check_run_blocks` applies the checks of a read run and
of :func:`forcecal.signals.checks.check_run_for_rig` in a first pass: on the whole record up to
:data:`CHECK_WINDOW` samples (so exactly as for a run read whole), and beyond that on windows
of one to two :data:`CHECK_WINDOW` (the robust span of the spike check, the clipping share and
"every channel constant" are then taken per window), so that nothing is streamed from a file
that a whole read would refuse for a damaged sample.
"""

from __future__ import annotations

import csv
import itertools
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..errors import DataError, InputError
from ..records import Run
from ..rig import Rig
from ..signals.checks import MIN_SAMPLES, check_record_length, check_run_for_rig
from ._run_values import ABSOLUTE_TIME, RunFile, finish_run, first_line
from ._time_column import is_time_name, mapped_time
from .run_channels import apply_rig
from .run_files import read_run

__all__ = ["RunBlocks", "check_run_blocks", "open_run_blocks"]

READ_BLOCK = 1 << 16
"""Samples per channel read at once."""
CHECK_WINDOW = 1 << 16
"""Records up to this many samples are checked whole; longer ones in windows of one to two."""
_UNIFORM_RTOL = 1e-6  # a time step may deviate from the mean step by this much (as read_run)
_PLAIN_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.:-]*")


@dataclass
class RunBlocks:
    """A run file open for reading in blocks.

    Attributes
    ----------
    name : str
        The file name without its extension.
    source : str
        The path, for messages.
    fs : float
        [Hz] sampling rate.
    t0 : float
        [s] time of the first sample.
    n_samples : int
        Samples per channel.
    channel_names : tuple of str
        The channels, under the rig's names.
    run : Run or None
        The whole run when the file was read whole (None when it is read in blocks).
    offsets : mapping name -> float
        Raw values taken off those channels in every block (a zero-current record's means).
    """

    name: str
    source: str
    fs: float
    t0: float
    n_samples: int
    channel_names: tuple[str, ...]
    run: Run | None = None
    offsets: Mapping[str, float] = field(default_factory=dict)
    _read: Callable[[list[str], int, int], np.ndarray] | None = field(default=None, repr=False)
    _close: Callable[[], None] = field(default=lambda: None, repr=False)

    def blocks(self, names: Sequence[str], size: int = READ_BLOCK) -> Iterator[np.ndarray]:
        """The named channels, ``size`` samples at a time.

        Parameters
        ----------
        names : sequence of str
            Channels to read, under the rig's names.
        size : int
            Samples per block (the last block holds the rest).

        Yields
        ------
        (len(names), m) ndarray
            Raw values, as a whole read would give them, less the ``offsets``.
        """
        names = list(names)
        missing = [n for n in names if n not in self.channel_names]
        if missing:
            run = self.run if self.run is not None else Run(
                channels=dict.fromkeys(self.channel_names, np.zeros(1)), fs=self.fs,
                source=self.source)
            run.channel(missing[0])                      # the reader's own message
        zero = np.array([self.offsets.get(n, 0.0) for n in names])[:, None]
        if self.run is not None:
            data = [self.run.channel(n) for n in names]
            for start in range(0, self.n_samples, size):
                yield np.stack([d[start:start + size] for d in data]) - zero
            return
        assert self._read is not None
        for start in range(0, self.n_samples, size):
            yield self._read(names, start, min(self.n_samples, start + size)) - zero

    def close(self) -> None:
        """Release the file."""
        self._close()

    def __enter__(self) -> RunBlocks:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_run_blocks(path: str | Path, rig: Rig | None = None, *,
                    whole: bool = False) -> RunBlocks:
    """Open a run file for reading in blocks (the formats that allow it) or read it whole.

    Parameters
    ----------
    path : str or Path
        A run file, as :func:`forcecal.io.run_files.read_run` takes.
    rig : Rig, optional
        Its ``[channels]`` map renames the file's channels (as ``read_run(path, rig)``).
    whole : bool
        Read the file whole, whatever its format.

    Returns
    -------
    RunBlocks
        Close it (or use it as a context manager) when done.

    Raises
    ------
    InputError, DataError
        As :func:`~forcecal.io.run_files.read_run` for a file it refuses.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    opened = None
    if path.is_file() and not whole and mapped_time(rig) is None:
        if suffix in (".h5", ".hdf5"):
            opened = _open_hdf5(path, rig)
        elif suffix == ".csv":
            opened = _open_csv(path, rig)
    if opened is not None:
        return opened
    run = read_run(path, rig) if rig is not None else read_run(path)
    return RunBlocks(name=run.name, source=run.source, fs=run.fs, t0=run.t0,
                     n_samples=run.n_samples, channel_names=tuple(run.channels), run=run)


def check_run_blocks(rig: Rig, blocks: RunBlocks) -> RunBlocks:
    """The checks of a run read whole and of
    :func:`~forcecal.signals.checks.check_run_for_rig`, over the record in windows (see the
    module docstring).

    Parameters
    ----------
    rig : Rig
    blocks : RunBlocks
        As :func:`open_run_blocks` gave it.

    Returns
    -------
    RunBlocks
        ``blocks``; or, when a block reader met what only the whole-file reader takes, the
        run read whole (``blocks`` is then closed).

    Raises
    ------
    InputError, DataError
        As :func:`~forcecal.io.run_files.read_run` and
        :func:`~forcecal.signals.checks.check_run_for_rig`.
    """
    if blocks.run is not None:                         # read whole: checked as before
        check_run_for_rig(rig, blocks.run)
        return blocks
    n = blocks.n_samples
    names = list(blocks.channel_names)
    count = max(1, n // CHECK_WINDOW)
    edges = [k * n // count for k in range(count + 1)]
    assert blocks._read is not None
    try:
        for start, stop in itertools.pairwise(edges):
            window = blocks._read(names, start, stop)
            t0 = blocks.t0 + start / blocks.fs if start else blocks.t0
            run = finish_run(Path(blocks.source), dict(zip(names, window, strict=True)),
                             blocks.fs, t0)
            check_run_for_rig(rig, run, f0=0.0 if count > 1 else None)
    except _Fallback:
        blocks.close()
        whole = open_run_blocks(Path(blocks.source), rig, whole=True)
        return check_run_blocks(rig, whole)
    if count > 1 and rig.frequency:
        check_record_length(_shape_only(blocks), rig.frequency)
    return blocks


def _shape_only(blocks: RunBlocks) -> Run:
    """A run of the file's length and sampling whose one channel takes no memory."""
    return Run(channels={"": np.broadcast_to(np.float64(0.0), (blocks.n_samples,))},
               fs=blocks.fs, t0=blocks.t0, name=blocks.name, source=blocks.source)


def _renamed(path: Path, names: list[str], n: int, fs: float, t0: float,
             rig: Rig | None) -> dict[str, str] | None:
    """{rig name: file name} as ``read_run(path, rig)`` would name the channels; None when
    the map or the sampling is not what the block reader can take (read whole then)."""
    if rig is None:
        return {name: name for name in names}
    marks = {name: np.broadcast_to(np.float64(k), (n,)) for k, name in enumerate(names)}
    try:
        run = apply_rig(RunFile(Run(channels=marks, fs=fs, t0=t0, name=path.stem,
                                    source=str(path))), rig)
    except Exception:                                  # the whole reader says what is wrong
        return None
    return {name: names[int(values[0])] for name, values in run.channels.items()}


# --------------------------------------------------------------------------------------------
# HDF5


def _open_hdf5(path: Path, rig: Rig | None) -> RunBlocks | None:
    try:
        h5 = h5py.File(path, "r")
    except Exception:
        return None
    try:
        opened = _hdf5_blocks(h5, path, rig)
    except Exception:
        opened = None
    if opened is None:
        h5.close()
    return opened


def _hdf5_blocks(h5: Any, path: Path, rig: Rig | None) -> RunBlocks | None:
    if "fs" not in h5.attrs:
        return None
    fs = float(np.asarray(h5.attrs["fs"], dtype=float).item())
    t0 = float(np.asarray(h5.attrs.get("t0", 0.0), dtype=float).item())
    datasets = {n: h5[n] for n in h5 if isinstance(h5[n], h5py.Dataset)}
    datasets.pop(next((n for n in datasets if is_time_name(n)), ""), None)  # as read_run
    if not (datasets and np.isfinite(fs) and fs > 0 and np.isfinite(t0)):
        return None
    lengths = {d.shape[0] if d.ndim == 1 else -1 for d in datasets.values()}
    if len(lengths) != 1 or any(d.dtype.kind not in "iuf" for d in datasets.values()):
        return None
    n = lengths.pop()
    if n < MIN_SAMPLES:
        return None
    mapping = _renamed(path, list(datasets), n, fs, t0, rig)
    if mapping is None:
        return None

    def read(names: list[str], start: int, stop: int) -> np.ndarray:
        out = np.empty((len(names), stop - start))
        try:
            for row, name in zip(out, names, strict=True):
                row[:] = datasets[mapping[name]][start:stop]
        except Exception as exc:           # h5py: OSError, RuntimeError... on a damaged file
            raise InputError(f"run '{path}': not a readable HDF5 file ({first_line(exc)})"
                             ) from exc
        return out

    return RunBlocks(name=path.stem, source=str(path), fs=fs, t0=t0, n_samples=n,
                     channel_names=tuple(mapping), _read=read, _close=h5.close)


# --------------------------------------------------------------------------------------------
# CSV


class _Fallback(DataError):
    """The chunked CSV reader met something only the whole-file reader handles."""

    def __init__(self, path: Path) -> None:
        super().__init__(f"run '{path}': the file changed while it was read")


def _open_csv(path: Path, rig: Rig | None) -> RunBlocks | None:
    try:
        return _csv_blocks(path, rig)
    except (_Fallback, ValueError, UnicodeDecodeError, OSError):
        return None


def _csv_header(path: Path) -> tuple[list[str], int] | None:
    """The header cells and the lines before the data, for the plain layout only."""
    with open(path, encoding="utf-8-sig", newline="") as f:
        for number, line in enumerate(f, start=1):
            if not line.strip():
                continue
            if '"' in line or ";" in line or "\t" in line:
                return None
            cells = [c.strip() for c in next(csv.reader([line]))]
            plain = is_time_name(cells[0]) and len(cells) >= 2 and len(set(cells)) == len(cells) \
                and all(_PLAIN_NAME.fullmatch(c) for c in cells[1:])
            return (cells, number) if plain else None
    return None


def _pandas_chunks(path: Path, skip: int, size: int, columns: list[int] | None = None
                   ) -> Iterator[np.ndarray]:
    """(m, n_columns) blocks of numbers as the whole-file reader parses them; _Fallback at
    anything else (a text cell, a row of another length, NaN or infinite)."""
    import pandas as pd  # type: ignore[import-untyped]

    try:
        reader = pd.read_csv(path, sep=",", decimal=".", header=None, skiprows=skip,
                             dtype=np.float64, na_filter=False, engine="c",
                             encoding="utf-8-sig", skip_blank_lines=True, usecols=columns,
                             chunksize=size)
        with reader:
            for frame in reader:
                values = frame.to_numpy(dtype=float)
                if not np.isfinite(values).all():
                    raise _Fallback(path)
                yield values
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as exc:
        raise _Fallback(path) from exc


def _csv_blocks(path: Path, rig: Rig | None) -> RunBlocks | None:
    found = _csv_header(path)
    if found is None:
        return None
    header, skip = found
    n, first, last = 0, 0.0, 0.0
    for chunk in _pandas_chunks(path, skip, READ_BLOCK, [0]):     # the time stamps alone
        if n == 0:
            first = float(chunk[0, 0])
        n += chunk.shape[0]
        last = float(chunk[-1, 0])
    if n < MIN_SAMPLES or not last > first or max(abs(first), abs(last)) > 1e10 \
            or first >= ABSOLUTE_TIME:                 # stamps since an epoch: read whole
        return None
    step = (last - first) / (n - 1)
    before = None
    for chunk in _pandas_chunks(path, skip, READ_BLOCK, [0]):
        stamps = chunk[:, 0] if before is None else np.concatenate([[before], chunk[:, 0]])
        if not _uniform(stamps, step):
            return None
        before = stamps[-1]
    names = header[1:]
    mapping = _renamed(path, names, n, 1.0 / step, first, rig)
    if mapping is None:
        return None
    column = {name: names.index(mapping[name]) + 1 for name in mapping}
    state: dict[str, Any] = {"next": -1}

    def read(wanted: list[str], start: int, stop: int) -> np.ndarray:
        """Sequential: a new pass over the file whenever ``start`` is not where the last
        read stopped."""
        if state["next"] != start:
            state["chunks"] = _pandas_chunks(path, skip, READ_BLOCK)
            state["rows"] = np.empty((0, len(header)))
            for _ in range(start // READ_BLOCK):
                next(state["chunks"])
            state["rows"] = _take(state, start % READ_BLOCK, path, len(header))[1]
        rows, state["rows"] = _take(state, stop - start, path, len(header))
        state["next"] = stop
        return np.ascontiguousarray(rows[:, [column[w] for w in wanted]].T)

    return RunBlocks(name=path.stem, source=str(path), fs=1.0 / step, t0=first, n_samples=n,
                     channel_names=tuple(mapping), _read=read)


def _take(state: dict[str, Any], count: int, path: Path,
          width: int) -> tuple[np.ndarray, np.ndarray]:
    """(the next ``count`` rows, the rows read beyond them)."""
    rows = state["rows"]
    while rows.shape[0] < count:
        chunk = next(state["chunks"], None)
        if chunk is None or chunk.shape[1] != width:
            raise _Fallback(path)
        rows = np.concatenate([rows, chunk]) if rows.size else chunk
    return rows[:count], rows[count:]


def _uniform(stamps: np.ndarray, step: float) -> bool:
    """Steps as uniform as :func:`~forcecal.io.run_files.read_run` wants them without allowing
    for written digits (otherwise the whole reader decides: it allows for them, or says where
    the stamps are off)."""
    rounding = 4 * np.finfo(float).eps * np.maximum(np.abs(stamps[:-1]), np.abs(stamps[1:]))
    tolerance = np.maximum(_UNIFORM_RTOL * abs(step), np.minimum(rounding, 0.25 * step))
    return not np.any(np.abs(np.diff(stamps) - step) > tolerance)
