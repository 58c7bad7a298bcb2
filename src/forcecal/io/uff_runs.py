"""Runs recorded as Universal File dataset-58 time records (``.uff``, ``.unv``; ASCII or 58b).

One record per channel: function type 1 (time response), an even abscissa in s (abscissa
data type 17, time; the increment gives the rate and the abscissa minimum the start time) or
an uneven one that is uniform. A channel is named

- by its ID line 1, when every record has one of its own (``"R1"``, ``"Probe s1"``);
- else by its response node and direction, ``"node 12 +Z"`` (see
  :func:`forcecal.rig.node_channel`).

Either way the other is a name of the channel too, as is any ID line (2 to 5) that no other
record shares, so the rig's ``[channels]`` table may name a record by node and direction or by
an ID line. Values are taken as the file holds them (the rig's scales convert them); the
ordinate's unit label is kept for the rig's unit checks. Records of other function types
(spectra, FRFs) are ignored.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..schema.channels import node_channel
from ._run_values import RunFile, run_from_time, sampled_run
from ._uff_read import _rate_from_increment
from ._uff_sets import TIME_ABSCISSA, TIME_RESPONSE, read_sets, set_type, type_list
from .csv_runs import TIME_UNITS

__all__: list[str] = []

_ABSENT = {"", "NONE"}  # pyuff writes NONE for an ID line or label not given
_STEP_RTOL = 1e-6  # records' increments agree to the 6 digits a UFF writes


def read_uff_run(path: Path) -> RunFile:
    """Read a run from the dataset-58 time records of a Universal File.

    Parameters
    ----------
    path : Path
        The ``.uff``/``.unv`` file.

    Returns
    -------
    RunFile
        The run, the other names of its channels (node and direction, ID lines) and the
        ordinates' unit labels.

    Raises
    ------
    InputError
        Not a Universal File, no time records, an abscissa that is not time or a time unit not
        understood.
    DataError
        Two records of one name, complex values, records that disagree in sampling, start or
        length, non-uniform abscissae, and what every run reader refuses (NaN, too short).
    """
    sets = read_sets(path, "run")
    records = [s for s in sets if set_type(s) == 58]
    if not records:
        raise InputError(f"run '{path}': no time records (dataset 58); found datasets "
                         f"{type_list(sets)}")
    times = [r for r in records if r.get("func_type") == TIME_RESPONSE]
    if not times:
        kinds = ", ".join(sorted({str(r.get("func_type")) for r in records}))
        raise InputError(f"run '{path}': none of the {len(records)} dataset-58 records is a "
                         f"time record (function type 1; found function types {kinds})")
    names, aliases = _names(times, path)
    channels = {name: _values(r, name, path) for name, r in zip(names, times, strict=True)}
    units = {name: _text(r.get("ordinate_axis_units_lab"))
             for name, r in zip(names, times, strict=True)}
    units = {name: unit for name, unit in units.items() if unit}
    factors = [_time_factor(r, name, path) for name, r in zip(names, times, strict=True)]
    first = times[0]
    if first.get("abscissa_spacing", 1) != 1:
        time = np.asarray(first.get("x", []), dtype=float) * factors[0]
        for name, r, factor in zip(names, times, factors, strict=True):
            x = np.asarray(r.get("x", []), dtype=float) * factor
            if x.shape != time.shape or not np.allclose(x, time, rtol=0, atol=1e-9 * np.ptp(x)):
                raise DataError(f"run '{path}': record {name!r} has other time stamps than "
                                f"record {names[0]!r}; a run's channels share one sampling")
        return RunFile(run_from_time(path, time, channels), aliases, units)
    step0 = _number(first, "abscissa_inc", names[0], path)
    start0 = _number(first, "abscissa_min", names[0], path) * factors[0]
    for name, r, factor in zip(names, times, factors, strict=True):
        step = _number(r, "abscissa_inc", name, path)
        if r.get("abscissa_spacing", 1) != 1 or not (
                abs(step * factor - step0 * factors[0]) <= _STEP_RTOL * step0 * factors[0]):
            raise DataError(f"run '{path}': record {name!r} is sampled every "
                            f"{step * factor:.6g} s, record {names[0]!r} every "
                            f"{step0 * factors[0]:.6g} s; a run's channels share one rate")
        start = _number(r, "abscissa_min", name, path) * factor
        if abs(start - start0) > 0.5 * step0 * factors[0]:
            raise DataError(f"run '{path}': record {name!r} starts at t={start:.6g} s, record "
                            f"{names[0]!r} at t={start0:.6g} s; a run's channels start together")
    if not step0 > 0:
        raise DataError(f"run '{path}': record {names[0]!r} gives the abscissa increment "
                        f"{step0!r}; expected a positive number of s")
    fs = _rate_from_increment(step0) / factors[0]
    return RunFile(sampled_run(path, channels, fs, start0), aliases, units)


def _text(value: object) -> str:
    text = str(value if value is not None else "").strip()
    return "" if text in _ABSENT else text


def _names(records: list[dict], path: Path) -> tuple[list[str], dict[str, str]]:
    """Each record's channel name, and the other names of the channels."""
    nodes = []
    for r in records:
        try:
            nodes.append(node_channel(int(r.get("rsp_node", 0)), int(r.get("rsp_dir", 0))))
        except (TypeError, ValueError):
            raise InputError(f"run '{path}': a time record's response node or direction "
                             f"({r.get('rsp_node')!r}, {r.get('rsp_dir')!r}) is not a "
                             "number") from None
    ids = [_text(r.get("id1")) for r in records]
    by_id = all(ids) and len(set(ids)) == len(ids)
    names = ids if by_id else nodes
    counts = Counter(names)
    twice = next((k for k, n in enumerate(names) if counts[n] > 1), None)
    if twice is not None:
        same = [k for k, n in enumerate(names) if n == names[twice]]
        raise DataError(f"run '{path}': time records {same[0] + 1} and {same[1] + 1} are both "
                        f"{names[twice]!r} (ID line 1 {ids[twice]!r}); a run holds one record "
                        "per channel, named by a distinct ID line 1 or node and direction")
    aliases: dict[str, str] = {}
    lines = [[_text(r.get(f"id{k}")) for k in range(1, 6)] for r in records]
    seen = Counter(t for texts in lines for t in set(texts) if t) + Counter(nodes)
    for name, node, texts in zip(names, nodes, lines, strict=True):
        for other in (node, *texts):
            if other and other != name and seen[other] == 1 and other not in counts:
                aliases[other] = name
    return names, aliases


def _values(record: dict, name: str, path: Path) -> np.ndarray:
    data = np.asarray(record.get("data", []))
    if np.iscomplexobj(data):
        raise DataError(f"run '{path}': record {name!r} holds complex values; a run's time "
                        "records are real")
    try:
        return data.astype(float).ravel()
    except (TypeError, ValueError):
        raise DataError(f"run '{path}': record {name!r} holds values that are not "
                        "numbers") from None


def _time_factor(record: dict, name: str, path: Path) -> float:
    """The abscissa's factor to s; InputError when it is not time."""
    kind = record.get("abscissa_spec_data_type", TIME_ABSCISSA)
    if kind not in (TIME_ABSCISSA, 0, None):
        raise InputError(f"run '{path}': record {name!r} has an abscissa of data type {kind}, "
                         f"not time ({TIME_ABSCISSA})")
    unit = _text(record.get("abscissa_axis_units_lab"))
    if unit not in TIME_UNITS:
        raise InputError(f"run '{path}': record {name!r} gives its time in {unit!r}; expected "
                         "s, ms or us")
    return TIME_UNITS[unit]


def _number(record: dict, key: str, name: str, path: Path) -> float:
    try:
        value = float(record.get(key, 0.0))
    except (TypeError, ValueError):
        value = float("nan")
    if not np.isfinite(value):
        raise DataError(f"run '{path}': record {name!r} gives {key} = {record.get(key)!r}; "
                        "expected a finite number")
    return value
