"""The campaign manifest: which runs, at which gaps, which are tare records (INTERFACES.md 4).

A CSV with a header row. ``run`` (required) is a run file path relative to the manifest's
folder; ``gap`` [m] overrides every force point's static gap for that run and
``gap_<force name>`` [m] one point's; ``tare`` (true/false, 1/0, yes/no; empty = false) marks a
zero-current record; every other column is a label carried into the report.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._atomic import write_text_atomic
from ..errors import InputError

__all__ = ["GAP_RATIO", "ManifestEntry", "read_manifest", "write_manifest"]

MAX_GAP_M = 0.1
"""Largest static gap a manifest may give [m]; a larger one is probably in mm."""
GAP_RATIO = 10.0
"""A run's gap must lie within this factor of the rig's static gap either way (see
:func:`forcecal.campaign.rig_for_entry`)."""

_TRUE = frozenset({"true", "1", "yes", "y", "t"})
_FALSE = frozenset({"false", "0", "no", "n", "f", ""})


@dataclass(frozen=True)
class ManifestEntry:
    """One manifest row.

    Attributes
    ----------
    run : Path
        The run file, resolved against the manifest's folder.
    gap : float or None [m]
        Static gap at every force point for this run, if given.
    gaps : dict force name -> float [m]
        Per-point static gaps from ``gap_<force name>`` columns (non-empty cells only).
    tare : bool
        True for a zero-current (tare) record.
    labels : dict column -> str
        Every other column, as written (stripped).
    row : int
        Its row number in the manifest file (the header is row 1), for messages.
    """

    run: Path
    gap: float | None = None
    gaps: dict[str, float] = field(default_factory=dict)
    tare: bool = False
    labels: dict[str, str] = field(default_factory=dict)
    row: int = field(default=0, compare=False)


def read_manifest(path: str | Path) -> list[ManifestEntry]:
    """Read a campaign manifest.

    Parameters
    ----------
    path : str or Path
        The manifest CSV.

    Returns
    -------
    list of ManifestEntry
        In file order.

    Raises
    ------
    InputError
        Missing file, no ``run`` column, no rows, a run file that does not exist, a gap that is
        not a positive number or an unreadable ``tare`` value; the message names the row
        (the header is row 1).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"manifest '{path}': file does not exist")
    header, rows = _read_rows(path)
    entries = [_entry(cells, number, header, path) for number, cells in rows]
    if not entries:
        raise InputError(f"manifest '{path}': no runs listed below the header")
    return entries


def write_manifest(path: str | Path, rows: Sequence[Mapping[str, object]]) -> Path:
    """Write a manifest CSV atomically.

    Parameters
    ----------
    path : str or Path
        The manifest CSV, replaced atomically.
    rows : sequence of mappings column -> value
        Each needs ``run``; columns are the union of all keys, ``run`` first, then in order of
        first appearance; a missing value or None is written as an empty cell, a float with
        its shortest exact repr, a bool as true/false.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A row without ``run`` (rows counted from 2, the header being row 1).
    """
    columns = ["run"]
    for number, row in enumerate(rows, start=2):
        if "run" not in row:
            raise InputError(f"manifest '{path}': row {number} has no 'run'")
        columns += [str(key) for key in row if str(key) not in columns]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        text = {str(key): _cell_text(value) for key, value in row.items()}
        writer.writerow([text.get(column, "") for column in columns])
    return write_text_atomic(path, buffer.getvalue())


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header names and (row number, cells) of every non-blank data row."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"manifest '{path}': not a text (UTF-8) CSV file") from exc
    reader = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    rows: list[tuple[int, list[str]]] = []
    for cells in reader:
        if not any(cell.strip() for cell in cells):
            continue
        if header is None:
            header = [cell.strip() for cell in cells]
        else:
            rows.append((reader.line_num, [cell.strip() for cell in cells]))
    if header is None:
        raise InputError(f"manifest '{path}': the file is empty")
    if "run" not in header:
        raise InputError(
            f"manifest '{path}': no 'run' column (found: {', '.join(map(repr, header)) or 'none'})"
        )
    if "gap_" in header:
        raise InputError(f"manifest '{path}': column 'gap_' names no force point")
    if len(set(header)) != len(header):
        twice = sorted({name for name in header if header.count(name) > 1})
        raise InputError(f"manifest '{path}': column {twice[0]!r} appears twice in the header")
    return header, rows


def _entry(cells: list[str], number: int, header: list[str], path: Path) -> ManifestEntry:
    where = f"manifest '{path}' row {number}"
    if len(cells) > len(header):
        raise InputError(f"{where}: {len(cells)} cells, the header names {len(header)}")
    values = dict(zip(header, cells + [""] * (len(header) - len(cells)), strict=True))
    run_text = values.pop("run")
    if not run_text:
        raise InputError(f"{where}: the 'run' cell is empty")
    run = _existing_run(path.parent / run_text)
    if run is None:
        raise InputError(f"{where}: run {run_text!r} does not exist")
    gap_text = values.pop("gap", "")
    gap = _positive_gap(gap_text, "gap", where) if gap_text else None
    gaps = {
        column[len("gap_") :]: _positive_gap(text, column, where)
        for column, text in values.items()
        if column.startswith("gap_") and text
    }
    tare = _flag(values.pop("tare", ""), where)
    labels = {k: v for k, v in values.items() if not k.startswith("gap_")}
    return ManifestEntry(run=run, gap=gap, gaps=gaps, tare=tare, labels=labels, row=number)


def _existing_run(candidate: Path) -> Path | None:
    """The resolved run file, or None when there is no such file (or no such path)."""
    try:
        run = candidate.resolve()
        return run if run.is_file() else None
    except (OSError, ValueError):  # e.g. a NUL byte in the cell
        return None


def _positive_gap(text: str, column: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{where}: {column} {text!r} is not a positive number (m)")
    if value > MAX_GAP_M:
        raise InputError(f"{where}: {column} {text!r} m is beyond {MAX_GAP_M:g} m, not an air "
                         "gap: probably not in m (0.0008 for 0.8 mm)")
    return value


def _flag(text: str, where: str) -> bool:
    word = text.strip().lower()
    if word in _TRUE:
        return True
    if word in _FALSE:
        return False
    raise InputError(f"{where}: tare {text!r} is not one of true/false, 1/0, yes/no")


def _cell_text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, Path):
        return value.as_posix()
    return str(value)
