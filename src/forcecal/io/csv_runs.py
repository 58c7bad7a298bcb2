"""CSV tables with a time column: runs as DAQ software exports them, and forcecal's own tables.

The layout: a header row whose first column is the time, then one numeric column per channel.
What lab exports add is understood:

- the delimiter is sniffed from the header: ``,``, ``;`` or tab;
- with ``;`` or tab, a decimal comma (``0,125``) is recognised from the first rows;
- a unit in the header, ``Time (s)``, ``time [ms]``, ``R1 [N]`` (in square brackets, or in
  parentheses after a space): the column is named without it (``R1``), and the header as
  written is another name of the channel;
- a units row under the header (``s, N, N, m``): every cell a unit or empty, none a number;
- the time named ``time``, ``t``, ``Zeit``, ``X_Value`` or ``Timestamp`` (any case), or
  anywhere under the rig's ``[channels] time``; in s, ms or us (converted to s), or as
  dates and times (ISO 8601: seconds from the first);
- a byte order mark, blank lines, spaces around the cells, quoted cells.

The numbers are read by pandas' C parser (values exactly as written: correctly rounded).
Anything it does not take (a text cell, a row of another length, NaN, a blank row of commas)
sends the file through a careful reader, slower, that says which row and column is at fault,
or reads what pandas would not (``nan``, ``inf``, rows of empty cells).
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import DataError, InputError
from ._time_column import (
    date_seconds,
    date_texts,
    first_non_date,
    is_date,
    is_time_name,
    mapped_time,
    missing_time,
)

if TYPE_CHECKING:
    from ..rig import Rig

__all__: list[str] = []

TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6}
"""Units of the time column understood, and their factor to s."""

_HEAD_BYTES = 1 << 16  # the start of the file from which the dialect is sniffed
_SNIFF_ROWS = 20  # data rows looked at for a decimal comma
_UNIT_CELL = re.compile(r"[\[(]?\s*[A-Za-zµμ%°/*^\-.0-9 ]{0,16}\s*[\])]?")
_WITH_UNIT = re.compile(r"(.*?\S)(?:\s*\[\s*([^\[\]()]*?)\s*\]|\s+\(\s*([^\[\]()]*?)\s*\))")
_DECIMAL_COMMA = re.compile(r"\s*[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?\s*")


@dataclass
class CsvColumns:
    """The columns of a CSV table, as read by :func:`read_csv_columns`.

    Attributes
    ----------
    path : Path
        The file.
    names : list of str
        Column names without their units; the first is the time column.
    labels : list of str
        The header cells as written (``"R1 [N]"``).
    units : list of str
        Each column's unit from the header or the units row, ``""`` when none is given.
    values : (n_rows, n_columns) array
        The numbers, time as written (see ``units[0]``; dates as seconds from the first).
    """

    path: Path
    names: list[str]
    labels: list[str]
    units: list[str]
    values: np.ndarray
    _dialect: tuple[str, str, int] = (",", ".", 0)
    _rows: list[int] | None = field(default=None, repr=False)
    _texts: list[str] | None = field(default=None, repr=False)
    _time: int = 0  # the time's column in the file

    def row(self, k: int) -> str:
        """``"row N"``: the file's line number of data row ``k`` (the header is row 1 when the
        file starts with it)."""
        if self._rows is None:
            self._rows = _careful(self.path, "run", *self._dialect)[2]
        return f"row {self._rows[k]}"

    def time_texts(self) -> list[str]:
        """The time cells as written, with a decimal point."""
        if self._texts is None:
            pd = _pandas()
            delimiter, decimal, skip = self._dialect
            try:
                column = pd.read_csv(self.path, sep=delimiter, header=None, skiprows=skip,
                                     usecols=[self._time], dtype=str, na_filter=False,
                                     encoding="utf-8-sig")[self._time].tolist()
            except (ValueError, pd.errors.ParserError):
                column = [row[self._time]
                          for row in _careful(self.path, "run", *self._dialect)[1]]
            self._texts = [t.replace(",", ".") for t in column] if decimal == "," else column
        return self._texts


def read_csv_columns(path: Path, what: str, rig: Rig | None = None) -> CsvColumns:
    """Read a CSV table with a time column: the first, or the one the rig names.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        ``"run"`` or ``"table"``, the kind of file in the messages.
    rig : Rig, optional
        Its ``[channels] time`` names the time column (anywhere in the header); without it
        the first column is the time, under one of the names of
        :data:`~forcecal.io._time_column.TIME_NAMES`.

    Returns
    -------
    CsvColumns
        The time column first.

    Raises
    ------
    InputError
        A file that is not UTF-8 text, a header without a time column first, a column without
        a name or named twice, a time unit not understood.
    DataError
        An empty file, no data rows, a row that is not CSV or has another number of cells than
        the header, a cell that is not a number (named by row and column), a time column the
        rig names that the header lacks.
    """
    head = _head_text(path, what)
    delimiter = _sniff_delimiter(head)
    header, first_rows, header_lines = _head_rows(head, delimiter, path, what)
    labels = [cell.strip() for cell in header]
    split = [_split_unit(label) for label in labels]
    names = [name for name, _ in split]
    units = [unit for _, unit in split]
    decimal = "," if delimiter != "," and _has_decimal_comma(first_rows) else "."
    skip = header_lines
    if first_rows and _is_units_row(first_rows[0][1], decimal):
        row_units = [cell.strip().strip("[]()").strip() for cell in first_rows[0][1]]
        units = _merge_units(units, row_units, names, path, what)
        skip = first_rows[0][0]
    time = _time_index(labels, names, path, what, rig)
    _check_header(labels, names, path, what)
    dates = _date_column(first_rows, skip, time, decimal)
    fast = _fast(path, delimiter, decimal, skip, len(names), dates)
    columns = CsvColumns(path, names, labels, units, np.empty((0, len(names))),
                         _dialect=(delimiter, decimal, skip), _time=time)
    if fast is None:
        _, cells, rows = _careful(path, what, delimiter, decimal, skip)
        values, columns._texts = _careful_values(cells, names, rows, path, what, decimal,
                                                 (time, dates))
        columns._rows = rows
    else:
        values, columns._texts = fast
    columns.values = values
    if dates is not None:
        columns.units[time] = "s"
    return _time_first(columns)


def _time_index(labels: list[str], names: list[str], path: Path, what: str,
                rig: Rig | None) -> int:
    """The time's column: the one the rig names (by name or as written), else the first,
    which must bear a time column's name."""
    mapped = mapped_time(rig)
    if mapped is not None:
        for k, (label, name) in enumerate(zip(labels, names, strict=True)):
            if mapped in (label, name):
                return k
        raise missing_time(path, mapped, rig, names)
    if not is_time_name(names[0]):
        raise InputError(f"{what} '{path}': the first column is {labels[0]!r}; expected 'time' "
                         "(or 't', 'Zeit', 'X_Value', 'Timestamp', in any case; the rig's "
                         "[channels] time = \"NAME\" names the time column otherwise)")
    return 0


def _date_column(first_rows: list[tuple[int, list[str]]], skip: int, time: int,
                 decimal: str) -> int | None:
    """``time`` when the first data row writes the time as a date and time, else None."""
    data = [row for line, row in first_rows if line > skip]
    if not data or time >= len(data[0]):
        return None
    cell = data[0][time]
    return time if _number(cell, decimal) is None and is_date(cell) else None


def _time_first(columns: CsvColumns) -> CsvColumns:
    """The columns with the time moved first (where the rig named another column)."""
    k = columns._time
    if k == 0:
        return columns
    order = [k, *(j for j in range(len(columns.names)) if j != k)]
    columns.names = [columns.names[j] for j in order]
    columns.labels = [columns.labels[j] for j in order]
    columns.units = [columns.units[j] for j in order]
    columns.values = columns.values[:, order]
    return columns


# --------------------------------------------------------------------------------------------
# the dialect


def _head_text(path: Path, what: str) -> str:
    """The file's first lines as text (whole lines; a byte order mark removed)."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES)
        if b"\n" not in head:                   # a first line longer than the head
            head += f.read()
        more = bool(f.read(1))
    if more:
        head = head[: head.rindex(b"\n") + 1]
    try:
        return head.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if more and exc.start >= len(head) - 4:  # a character cut at the end of the head
            return head[: exc.start].decode("utf-8-sig")
        raise InputError(f"{what} '{path}': not a text (UTF-8) CSV file") from None


def _sniff_delimiter(head: str) -> str:
    """``;`` or tab when the first non-blank line holds them (the most of them), else ``,``."""
    line = next((ln for ln in head.splitlines() if ln.strip()), "")
    counts = {d: line.count(d) for d in (";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] > 0 and counts[best] >= line.count(",") else ","


def _head_rows(head: str, delimiter: str, path: Path, what: str
               ) -> tuple[list[str], list[tuple[int, list[str]]], int]:
    """Header cells, the first data rows with the line count through each, and the line count
    through the header."""
    reader = csv.reader(io.StringIO(head, newline=None), delimiter=delimiter)
    header: list[str] | None = None
    header_lines = 0
    rows: list[tuple[int, list[str]]] = []
    try:
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            if header is None:
                header, header_lines = row, reader.line_num
                continue
            rows.append((reader.line_num, row))
            if len(rows) >= _SNIFF_ROWS:
                break
    except csv.Error as exc:
        if header is None:
            raise DataError(f"{what} '{path}': row {reader.line_num + 1} cannot be read as CSV "
                            f"({exc})") from None
        # a later row: the careful reader says where
    if header is None:
        raise DataError(f"{what} '{path}': the file is empty")
    return header, rows, header_lines


def _has_decimal_comma(rows: list[tuple[int, list[str]]]) -> bool:
    """Whether the first rows write numbers with a decimal comma (and none with a point)."""
    cells = [c for _, row in rows for c in row]
    comma = any(_DECIMAL_COMMA.fullmatch(c) for c in cells)
    point = any(_number(c, ".") is not None and "." in c for c in cells)
    return comma and not point


def _number(cell: str, decimal: str) -> float | None:
    text = cell.replace(",", ".") if decimal == "," else cell
    if "_" in text:
        return None
    try:
        return float(text)
    except ValueError:
        return None


def _is_units_row(row: list[str], decimal: str) -> bool:
    """A row of units: some cell not empty, none a number, every cell short and unit-like."""
    cells = [c.strip() for c in row]
    return (any(cells) and all(_number(c, decimal) is None for c in cells if c)
            and all(_UNIT_CELL.fullmatch(c) for c in cells))


def _split_unit(label: str) -> tuple[str, str]:
    """``"Time (s)"`` -> ``("Time", "s")``; a label without a unit is returned with ``""``."""
    match = _WITH_UNIT.fullmatch(label)
    unit = (match.group(2) or match.group(3) or "") if match else ""
    if match is None or not re.search(r"[^\d\s.]", unit):  # "phi(1)", "R1 (2)": names
        return label, ""
    return match.group(1), unit


def _merge_units(units: list[str], row: list[str], names: list[str], path: Path,
                 what: str) -> list[str]:
    merged = []
    for k, unit in enumerate(units):
        other = row[k] if k < len(row) else ""
        if unit and other and unit != other:
            raise InputError(f"{what} '{path}': column {names[k]!r} is in {unit!r} by the "
                             f"header and in {other!r} by the units row")
        merged.append(unit or other)
    return merged


def _check_header(labels: list[str], names: list[str], path: Path, what: str) -> None:
    if len(names) < 2:
        raise DataError(f"{what} '{path}': no channel columns after 'time'")
    seen: set[str] = set()
    for column, name in enumerate(names, start=1):
        if not name:
            raise InputError(f"{what} '{path}': column {column} has no name in the header")
        if name in seen:
            raise InputError(f"{what} '{path}': column {name!r} appears twice in the header")
        seen.add(name)


# --------------------------------------------------------------------------------------------
# the numbers


def _fast(path: Path, delimiter: str, decimal: str, skip: int, n_columns: int,
          dates: int | None = None) -> tuple[np.ndarray, list[str] | None] | None:
    """(n_rows, n_columns) numbers by pandas' C parser, and the time's texts when column
    ``dates`` holds dates and times (then made seconds from the first); None when it finds
    anything else in rows of ``n_columns`` cells."""
    pd = _pandas()
    dtype: Any = np.float64 if dates is None else {
        j: str if j == dates else np.float64 for j in range(n_columns)}
    try:
        frame = pd.read_csv(path, sep=delimiter, decimal=decimal, header=None, skiprows=skip,
                            dtype=dtype, na_filter=False, engine="c",
                            encoding="utf-8-sig", skip_blank_lines=True)
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError):
        return None
    texts = None
    if dates is not None:
        if frame.shape[1] != n_columns:
            return None
        column = frame[dates].tolist()
        seconds = date_seconds(column, pd)
        if seconds is None:
            return None
        texts = date_texts(column, seconds)
        frame[dates] = seconds
    values = frame.to_numpy(dtype=float)
    if values.ndim != 2 or values.shape[1] != n_columns or values.shape[0] == 0:
        return None
    return values, texts


def _pandas() -> Any:
    """pandas, imported on use (it takes a while to import)."""
    import pandas  # type: ignore[import-untyped]

    return pandas


def _careful(path: Path, what: str, delimiter: str, decimal: str, skip: int
             ) -> tuple[list[str], list[list[str]], list[int]]:
    """Header cells, data rows (cells as text) and their 1-based line numbers in the file;
    one line saying what is wrong otherwise."""
    del decimal  # the cells stay text here
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} '{path}': not a text (UTF-8) CSV file") from exc
    reader = csv.reader(io.StringIO(text), delimiter=delimiter)
    header: list[str] | None = None
    cells: list[list[str]] = []
    rows: list[int] = []
    try:
        for row in reader:
            if header is None:
                if any(cell.strip() for cell in row):
                    header = [cell.strip() for cell in row]
                continue
            if reader.line_num <= skip or not any(cell.strip() for cell in row):
                continue                         # the units row; blank lines
            cells.append(row)
            rows.append(reader.line_num)
    except csv.Error as exc:  # e.g. a cell beyond the field size limit, a NUL byte
        raise DataError(f"{what} '{path}': row {reader.line_num + 1} cannot be read as CSV "
                        f"({exc})") from None
    if header is None:
        raise DataError(f"{what} '{path}': the file is empty")
    if not cells:
        raise DataError(f"{what} '{path}': a header but no data rows")
    for row, number in zip(cells, rows, strict=True):
        if len(row) != len(header):
            raise DataError(
                f"{what} '{path}': row {number} has {len(row)} cells, the header {len(header)}"
            )
    return header, cells, rows


def _careful_values(cells: list[list[str]], names: list[str], rows: list[int], path: Path,
                    what: str, decimal: str, time: tuple[int, int | None]
                    ) -> tuple[np.ndarray, list[str]]:
    """(n_rows, n_columns) numbers of the careful reader's cells, and the time's texts; the
    time column ``time[0]``, when it holds dates and times (``time[1]``), as seconds from the
    first."""
    at, dates = time
    if dates is None:
        texts = [row[at].replace(",", ".") if decimal == "," else row[at] for row in cells]
        return _numeric(cells, names, rows, path, what, decimal, at), texts
    column = [row[dates] for row in cells]
    seconds = date_seconds(column, _pandas())
    if seconds is None:
        k = first_non_date(column, _pandas())
        raise DataError(f"{what} '{path}': row {rows[k]}, column {names[dates]!r}: "
                        f"{column[k].strip()!r} is not a date and time like the first row's "
                        "(ISO 8601: 2024-05-01T12:00:00.0001)")
    numbers = [[*row[:dates], "0", *row[dates + 1:]] for row in cells]
    values = _numeric(numbers, names, rows, path, what, decimal, at)
    values[:, dates] = seconds
    return values, date_texts(column, seconds)


def _numeric(cells: list[list[str]], names: list[str], rows: list[int], path: Path, what: str,
             decimal: str, time: int = 0) -> np.ndarray:
    """(n_rows, n_columns) float array; DataError naming row and column of a bad cell."""
    texts = [[c.replace(",", ".") for c in row] for row in cells] if decimal == "," else cells
    if not any("_" in cell for row in texts for cell in row):  # float() takes '1_000'
        try:
            return np.array(texts, dtype=float)
        except ValueError:
            pass
    for row, number in zip(cells, rows, strict=True):
        for column, (cell, name) in enumerate(zip(row, names, strict=True)):
            if _number(cell, decimal) is None:
                raise DataError(
                    f"{what} '{path}': row {number}, column {name!r}: {cell.strip()!r} is not "
                    "a number" + (" of seconds nor a date and time (ISO 8601: "
                                  "2024-05-01T12:00:00.0001)" if column == time else "")
                )
    raise DataError(f"{what} '{path}': a cell is not a number")  # pragma: no cover
