"""Output files of ``reconstruct`` (INTERFACES.md section 5)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..forces.estimate import Estimate
from .result_formats import (
    SERIES_FORMATS,
    SERIES_SUFFIXES,
    series_blocks,
    series_json,
    write_series,
)

__all__ = ["write_estimate"]


MAX_FORCE_N = 1e8
"""Largest force written [N]; an estimate beyond comes from inputs that are not what they
claim, and is refused rather than written."""


def write_estimate(est: Estimate, out_dir: str | Path, source: str | None = None,
                   fmt: str = "csv", provenance: dict | None = None) -> tuple[Path, Path]:
    """Write the force series ``OUT/NAME.forces.<ext>`` and ``OUT/NAME.json`` of either
    drive's estimate, atomically.

    The series (:meth:`~forcecal.forces.estimate.Estimate.columns`): ``time`` [s]; every force
    and ``total``; the same with suffix ``_static`` (reactions only); the same with suffix
    ``_std`` (standard uncertainty at each instant), all in N. Both files appear together or
    neither: nothing is written when a value is not finite or a force exceeds
    :data:`MAX_FORCE_N` (DataError naming the run and the column), or when writing fails; the
    JSON is strict (no NaN or Infinity) and names the series file and its columns' units
    (``series``).

    Parameters
    ----------
    est : Estimate
        The run's estimate: harmonic (steady drive) or sample by sample (any drive).
    out_dir : str or Path
        The output folder OUT, created when missing.
    source : str, optional
        The run file, for messages (default: the run's name).
    fmt : {"csv", "hdf5", "mat", "uff"}
        Format of the series: ``NAME.forces.csv``, ``.h5``, ``.mat`` (MATLAB) or ``.uff``
        (dataset-58 time records); see :mod:`forcecal.io.result_formats`. An estimate under
        any drive is written as CSV.
    provenance : dict, optional
        Written as the JSON's ``provenance``: version, date, command line, input digests
        (default: the estimate's own, when it has one).

    Returns
    -------
    series : Path
        The force series.
    json : Path
        The estimate's :meth:`~forcecal.forces.estimate.Estimate.summary`, with the ``series``
        entry and, when given, the ``provenance`` (:func:`forcecal.provenance.provenance`).

    Raises
    ------
    InputError
        An unknown format, one the estimate is not written in, or force names the format
        cannot hold.
    DataError
        A value that is not finite or a force beyond :data:`MAX_FORCE_N`.
    """
    where = f"run '{source or est.run_name}'"
    if fmt not in SERIES_SUFFIXES:
        raise InputError(f"{where}: output format {fmt!r} is not one of "
                         f"{', '.join(SERIES_FORMATS)}")
    if fmt not in est.formats:
        raise InputError(f"{where}: a force series sample by sample (any drive) is written as "
                         f"{' or '.join(est.formats)}, not {fmt}")
    out_dir = Path(out_dir)
    names = _checked_columns(est, where)
    try:
        doc = est.summary()
        doc["series"] = series_json(est, fmt, dict.fromkeys(names))
        origin = provenance if provenance is not None else est.provenance
        if origin is not None:
            doc["provenance"] = origin
        text = json.dumps(doc, indent=1, allow_nan=False)
    except ValueError:
        raise DataError(f"{where}: the estimate's summary holds non-finite values; nothing "
                        "written") from None
    series = out_dir / f"{est.run_name}{SERIES_SUFFIXES[fmt]}"
    js = out_dir / f"{est.run_name}.json"
    with atomic_path(js) as tmp_js, atomic_path(series) as tmp_series:  # series moved first
        write_series(est, tmp_series, fmt)       # made a block of rows at a time
        tmp_js.write_text(text, encoding="utf-8")
    return series, js


def _checked_columns(est: Estimate, where: str) -> list[str]:
    """The names of the series' columns, once every time and force is known finite and every
    force within :data:`MAX_FORCE_N`; else DataError naming the first column at fault (time
    first, then the columns in order) and its first such sample. The columns are made a block
    of rows at a time (:func:`~forcecal.io.result_formats.series_blocks`): the memory of a
    block, whatever the record's length."""
    first: dict[str, tuple[int, float]] = {}
    _first_bad("time", np.asarray(est.time, dtype=float), 0, first)
    names: list[str] = []
    for start, _, cols in series_blocks(est):
        names = names or list(cols)
        for name, values in cols.items():
            if name not in first:
                _first_bad(name, np.asarray(values, dtype=float), start, first)
    for name in ["time", *names]:
        if name in first:
            k, value = first[name]
            raise DataError(f"{where}: the estimate's {name!r} is {value:.4g} at sample {k}, "
                            f"not a finite force within {MAX_FORCE_N:g} N; nothing written (are "
                            "the inputs what they claim?)")
    return names


def _first_bad(name: str, v: np.ndarray, start: int, first: dict[str, tuple[int, float]]
               ) -> None:
    """Note in ``first`` the first sample of ``v`` (samples ``start`` on of column ``name``)
    that is not finite or, but for the time, beyond :data:`MAX_FORCE_N`."""
    bad = ~np.isfinite(v) | ((np.abs(v) > MAX_FORCE_N) if name != "time" else False)
    if np.any(bad):
        k = int(np.argmax(bad))
        first[name] = (start + k, float(v[k]))
