"""The time column of a run file: the names labs give it, the rig's own name for it
(``[channels] time = "NAME"``), and time stamps written as dates and times (ISO 8601) made
seconds from the first sample."""

from __future__ import annotations

import re
from collections.abc import Sequence
from decimal import Decimal
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import DataError

if TYPE_CHECKING:
    from ..rig import Rig

__all__: list[str] = []

TIME_NAMES = ("time", "t", "zeit", "x_value", "timestamp")
"""Names of a time column understood without a map, in any case (``X_Value``: LabVIEW's)."""
TIME_KEY = "time"
"""The rig's ``[channels]`` key that names the time column of its run files."""
_LISTED = 8  # column names listed in a message
_DATE = re.compile(r"\s*\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d*)?)?"
                   r"\s*(Z|[+-]\d{2}:?\d{2})?\s*", re.IGNORECASE)
_FRACTION = re.compile(r":\d{2}\.(\d+)")


def is_time_name(name: str) -> bool:
    """Whether ``name`` (without its unit) is a time column's name understood without a map."""
    return name.strip().lower() in TIME_NAMES


def mapped_time(rig: Rig | None) -> str | None:
    """The run files' time column the rig names (``[channels] time``), or None."""
    if rig is None:
        return None
    return dict(rig.channel_map).get(TIME_KEY)


def time_channel(names: Sequence[str], mapped: str | None, path: Path, rig: Rig | None
                 ) -> str | None:
    """The channel of a TDMS group or HDF5 group that holds the time: the one the rig maps,
    else the first whose name is a time name; None when there is none.

    Raises
    ------
    DataError
        The rig names a time channel the file does not hold.
    """
    if mapped is not None:
        if mapped not in names:
            raise missing_time(path, mapped, rig, names)
        return mapped
    return next((n for n in names if is_time_name(n)), None)


def missing_time(path: Path, mapped: str, rig: Rig | None, names: Sequence[str]) -> DataError:
    """The refusal of a time column the rig's ``[channels]`` names and the file lacks."""
    where = f" (rig '{rig.source}', key 'channels.{TIME_KEY}')" if rig is not None else ""
    shown = ", ".join(repr(n) for n in names[:_LISTED])
    more = f" and {len(names) - _LISTED} more" if len(names) > _LISTED else ""
    return DataError(f"run '{path}': time column {mapped!r}{where} is not in the file; it "
                     f"holds {shown}{more}")


def is_date(cell: str) -> bool:
    """Whether a cell writes a date and time in ISO 8601 (``2024-05-01T12:00:00.0001``,
    a space for the ``T``, a ``Z`` or an offset allowed)."""
    return _DATE.fullmatch(cell) is not None


def date_seconds(cells: Sequence[str], pandas: Any) -> np.ndarray | None:
    """(n,) [s] the dates and times ``cells`` from the first; None when one is not ISO 8601
    (:func:`first_non_date` then says which)."""
    if not all(is_date(c) for c in cells):
        return None
    try:
        stamps = pandas.to_datetime(pandas.Series(list(cells)), format="ISO8601", utc=True)
    except (ValueError, TypeError, OverflowError):
        return None
    ns = stamps.to_numpy(dtype="datetime64[ns]").astype(np.int64)
    return (ns - ns[0]).astype(float) * 1e-9


def first_non_date(cells: Sequence[str], pandas: Any) -> int:
    """Index of the first cell of ``cells`` that is not an ISO 8601 date and time."""
    for k, cell in enumerate(cells):
        if date_seconds([cell], pandas) is None:
            return k
    return 0


def since_first(texts: Sequence[str]) -> np.ndarray:
    """(n,) [as written] decimal time stamps less the first, exactly (a stamp since an epoch,
    1.7e9 s, holds only 0.2 us in a float)."""
    first = Decimal(texts[0])
    return np.array([float(Decimal(t) - first) for t in texts])


def date_texts(cells: Sequence[str], seconds: np.ndarray) -> list[str]:
    """``seconds`` written with the decimals of the seconds the dates were written with (the
    stamps' resolution, for the check of uniform steps)."""
    decimals = max((len(m.group(1)) for c in cells[:100] if (m := _FRACTION.search(c))),
                   default=0)
    return [f"{s:.{decimals}f}" for s in seconds]
