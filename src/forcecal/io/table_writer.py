"""Tables written block by block as they are produced: CSV (a file or standard output) and HDF5.

The layouts are those of :func:`forcecal.io.run_files.write_table_csv` and
:func:`~forcecal.io.run_files.write_table_hdf5`: a ``time`` column then the named columns;
HDF5 in the run layout (one root dataset per column, root attributes ``fs`` and ``t0``), the
datasets made at their final length when it is known (plain contiguous datasets, written block
by block) and grown by each block otherwise (chunked; HDF5 then holds more memory). A file is
written under a temporary name beside the target and renamed when the table is complete, so
that an error or an interruption leaves nothing that looks whole (standard output cannot be
taken back: what was written stays).

CSV numbers are written by :func:`forcecal.io.text_format.format_rows` (compiled), the time so
that it reads back exactly (15 significant digits when they suffice, else 17) and the columns
with ``digits``; a block is
formatted and written in a second thread while the caller computes the next one (the compiled
formatter and the file write release the interpreter's lock).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import IO, Any

import numpy as np

from .._atomic import atomic_path
from ..errors import InputError
from .text_format import format_rows

__all__ = ["CSV_DIGITS", "table_writer"]

CSV_DIGITS = 9
"""Significant digits of the columns of a streamed CSV table (``'%.9g'``)."""
_CHUNK = 1 << 16
"""HDF5 chunk length of the growing datasets [values]."""
_LINES = 1 << 11
"""CSV rows formatted at once (the text buffer stays small)."""


class TableWriter:
    """Append blocks of rows to an open table (made by :func:`table_writer`).

    Attributes
    ----------
    rows : int
        Rows written so far.
    """

    def __init__(self, kind: str, handle: Any, names: Sequence[str], digits: int,
                 rows: int | None = None) -> None:
        self._kind = kind
        self._declared = rows
        self._handle = handle
        self._names = list(names)
        self._precision = [0] + [digits] * len(self._names)
        self._datasets: list[Any] = []
        self._pool: ThreadPoolExecutor | None = None
        self._pending: Future[None] | None = None
        self.rows = 0
        if self._kind == "csv":
            handle.write((",".join(["time", *self._names]) + "\n").encode("utf-8"))
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="table")

    def write(self, time: np.ndarray, columns: np.ndarray) -> None:
        """Append rows.

        Parameters
        ----------
        time : (m,) ndarray
            [s] the rows' time stamps.
        columns : (n_columns, m) ndarray
            The rows' values, one row of ``columns`` per named column.
        """
        columns = np.asarray(columns, dtype=float)
        time = np.asarray(time, dtype=float).ravel()
        if columns.shape != (len(self._names), time.size):
            raise InputError(f"table: a block of shape {columns.shape} for columns "
                             f"{self._names} and {time.size} time stamps")
        if self._pool is not None:
            block = np.empty((time.size, len(self._names) + 1))
            block[:, 0] = time
            block[:, 1:] = columns.T
            self.flush()
            self._pending = self._pool.submit(self._emit, block)
        else:
            if not self._datasets:
                self._datasets = [self._dataset(name) for name in self._names]
            end = self.rows + time.size
            for dataset, values in zip(self._datasets, columns, strict=True):
                if self._declared is None:
                    dataset.resize((end,))
                dataset[self.rows:end] = values
        self.rows += time.size

    def _dataset(self, name: str) -> Any:
        if self._declared is not None:
            return self._handle.create_dataset(name, shape=(self._declared,), dtype=float)
        return self._handle.create_dataset(name, shape=(0,), maxshape=(None,), dtype=float,
                                           chunks=(_CHUNK,))

    def _emit(self, block: np.ndarray) -> None:
        for start in range(0, block.shape[0], _LINES):
            self._handle.write(format_rows(block[start:start + _LINES], self._precision))

    def flush(self) -> None:
        """Wait until every block given is written (raising what writing it raised)."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def close(self) -> None:
        """Finish writing and stop the writing thread."""
        try:
            self.flush()
        finally:
            if self._pool is not None:
                self._pool.shutdown()
        if self._declared is not None and self.rows != self._declared:
            raise InputError(f"table: {self._declared} rows announced, {self.rows} written")


@contextlib.contextmanager
def table_writer(target: str | Path, names: Sequence[str], fs: float, t0: float, *,
                 digits: int = CSV_DIGITS, rows: int | None = None,
                 stdout: IO[bytes] | None = None) -> Iterator[TableWriter]:
    """Open a table for writing in blocks; complete it (rename into place) on leaving.

    Parameters
    ----------
    target : str or Path
        ``NAME.csv``, ``NAME.h5``/``NAME.hdf5``, or ``-`` for CSV on standard output.
    names : sequence of str
        The columns after ``time``.
    fs : float
        [Hz] the rows' rate (the HDF5 attribute ``fs``).
    t0 : float
        [s] the first row's time (the HDF5 attribute ``t0``).
    digits : int
        Significant digits of the CSV columns (0: exact, as few as 15 when they suffice).
    rows : int, optional
        The number of rows that will be written, when known (HDF5 then writes plain datasets
        of that length; fewer or more rows are an error).
    stdout : binary file, optional
        Where ``-`` writes (default: the process's standard output).

    Yields
    ------
    TableWriter

    Raises
    ------
    InputError
        A column name the format cannot hold.
    """
    names = list(names)
    hdf5 = str(target) != "-" and Path(target).suffix.lower() in (".h5", ".hdf5")
    for name in names:
        bad = not name or name.strip().lower() == "time" or (
            "/" in name or name == "." if hdf5 else any(c in name for c in ',"\r\n'))
        if bad:
            raise InputError(f"table '{target}': column name {name!r} cannot be written to "
                             f"{'HDF5' if hdf5 else 'CSV'}")
    if str(target) == "-":
        out = stdout if stdout is not None else sys.stdout.buffer
        with _closing(TableWriter("csv", out, names, digits, rows)) as writer:
            yield writer
        out.flush()
        return
    with atomic_path(target) as tmp:
        if hdf5:
            import h5py

            with h5py.File(tmp, "w", track_order=True) as h5:
                h5.attrs["fs"] = float(fs)
                h5.attrs["t0"] = float(t0)
                with _closing(TableWriter("hdf5", h5, names, digits, rows)) as writer:
                    yield writer
                if writer.rows == 0 and not rows:
                    for name in names:
                        h5.create_dataset(name, data=np.zeros(0))
        else:
            with open(tmp, "wb", buffering=1 << 20) as f, \
                    _closing(TableWriter("csv", f, names, digits, rows)) as writer:
                yield writer


@contextlib.contextmanager
def _closing(writer: TableWriter) -> Iterator[TableWriter]:
    """The writer, closed on leaving; after an error, a failure to finish is not raised over
    it."""
    try:
        yield writer
    except BaseException:
        with contextlib.suppress(Exception):
            writer.close()
        raise
    writer.close()
