"""The force series of ``reconstruct`` in every output format: CSV, HDF5, MATLAB and UFF.

Every format holds the same series (:func:`~forcecal.forces.estimate.series_columns`): the
time [s]; per force and the ``total``, the force [N]; the same with suffix ``_static``
(reactions only) [N]; and with suffix ``_std`` the standard uncertainty of the force at each
instant [N] (:func:`waveform_std_series`). The self-describing formats add the phasors and the
fundamental:

- CSV (``NAME.forces.csv``): the header row names the columns, as INTERFACES.md section 5
  states them, new columns after the documented ones; the units are those of the contract
  (s, N) and are listed in ``NAME.json`` (``series.units``), never in the file, whose first
  row must stay the header and every other row numbers;
- HDF5 (``NAME.forces.h5``): every column a root dataset with a ``units`` attribute (the run
  layout: :func:`forcecal.io.run_files.read_run` reads it back), the phasors in the group
  ``harmonics``, the fundamental and the notes as root attributes;
- MATLAB (``NAME.forces.mat``, version 5): variables ``time``, ``forces``, ``force_std``,
  ``static`` (samples by columns ``names``), ``phasors``, ``phasor_std``, ``harmonics``, ``f0``,
  ``notes``, ``units``... (:func:`write_forces_mat`);
- UFF (``NAME.forces.uff``): one dataset-58 time record per column, ID line 1 the column's name,
  abscissa time [s], ordinate an excitation force [N] (:func:`write_forces_uff`).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..forces.estimate import SERIES_FORMATS, Estimate, ForceEstimate, series_columns
from ._uff_write import _write_sets
from .run_files import write_table_csv
from .table_writer import table_writer

__all__: list[str] = []

SERIES_SUFFIXES = dict(zip(SERIES_FORMATS, (".forces.csv", ".forces.h5", ".forces.mat",
                                           ".forces.uff"), strict=True))
"""The file ``NAME + suffix`` each format of ``reconstruct --format`` writes."""
SERIES_ROWS = 1 << 16
"""Rows of the force series made and written at once (:func:`series_blocks`): the memory of
a block, whatever the record's length."""

HDF5_FORMAT = "forcecal forces 1"
"""The root attribute ``format`` of an HDF5 force file."""
UFF_ID_CHARS = 80
"""Longest ID line of a Universal File record."""
_EXCITATION_FORCE = 13  # dataset 58 ordinate specific data type: excitation force
_TIME_ABSCISSA = 17     # abscissa specific data type: time
_TIME_RESPONSE = 1      # function type: time response
_SCALAR = 0             # response direction: scalar (the estimate carries no direction)
_QUANTITY = {"": "force", "_static": "reactions-only force", "_std": "standard uncertainty"}
_UFF_ID2 = {"": "Force", "_static": "Force  reactions only", "_std": "Force  std"}
_BLOCK = 1 << 16        # time stamps per block of the per-instant uncertainty


# --------------------------------------------------------------------------------------------
# the series


def series_units(columns: Mapping[str, object]) -> dict[str, str]:
    """The unit of ``time`` and of every column: ``{"time": "s", "F1": "N", ...}``."""
    return {"time": "s", **{name: "N" for name in columns}}


def write_series(est: Estimate, path: str | Path, fmt: str,
                 columns: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write the force series of ``est`` to ``path`` in format ``fmt``.

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    path : str or Path
        The file; written in place (the caller makes the write atomic).
    fmt : {"csv", "hdf5", "mat", "uff"}
        The format.
    columns : mapping, optional
        :func:`~forcecal.forces.estimate.series_columns` of ``est``, when already computed.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        An unknown format, or a force name the format cannot hold.
    """
    if fmt == "csv":
        if columns is None:                  # made and written a block of rows at a time
            return _write_csv_blocks(est, path)
        return write_table_csv(path, est.time, dict(columns))
    assert isinstance(est, ForceEstimate)  # the other formats hold the phasors too
    writers = {"hdf5": write_forces_hdf5, "mat": write_forces_mat, "uff": write_forces_uff}
    if fmt not in writers:
        raise InputError(f"run '{est.run_name}': output format {fmt!r} is not one of "
                         f"{', '.join(SERIES_FORMATS)}")
    if fmt == "hdf5":
        return write_forces_hdf5(est, path, columns)
    return writers[fmt](est, path, dict(columns) if columns is not None else est.columns())


def series_blocks(est: Estimate, rows: int = SERIES_ROWS
                  ) -> Iterator[tuple[int, int, dict[str, np.ndarray]]]:
    """The columns of the force series (:meth:`~forcecal.forces.estimate.Estimate.columns`)
    a block of rows at a time: ``(start, stop, the columns' rows start..stop-1)``, at least
    one block (an empty one for an empty series). A harmonic estimate's columns are made a
    block at a time (:func:`~forcecal.forces.estimate.series_columns`: the whole's values, in
    the memory of a block); another estimate's are cut from the whole."""
    n = len(est.time)
    whole = None if isinstance(est, ForceEstimate) else est.columns()
    for start in range(0, max(n, 1), rows):
        stop = min(n, start + rows)
        if whole is None:
            assert isinstance(est, ForceEstimate)
            yield start, stop, series_columns(est, start, stop)
        else:
            yield start, stop, {name: np.asarray(v)[start:stop] for name, v in whole.items()}


def _write_csv_blocks(est: Estimate, path: str | Path) -> Path:
    """The series as :func:`~forcecal.io.run_files.write_table_csv` writes it (every value
    exactly), its columns made and written a block of rows at a time (:func:`series_blocks`)."""
    time = np.asarray(est.time, dtype=float).ravel()
    blocks = series_blocks(est)
    first = next(blocks)
    names = list(first[2])
    with table_writer(path, names, 1.0, 0.0, digits=0, rows=time.size) as writer:
        for start, stop, cols in itertools.chain([first], blocks):
            writer.write(time[start:stop], np.array(list(cols.values()), dtype=float)
                         .reshape(len(names), -1))
    return Path(path)


def _per_force(est: ForceEstimate) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Names (forces then ``total``), phasors and their stds, (n_forces + 1, H+1) [N]."""
    names = [*est.force_names, "total"]
    return (names, np.vstack([est.force, est.total[None, :]]),
            np.vstack([est.force_std, est.total_std[None, :]]))


# --------------------------------------------------------------------------------------------
# HDF5


def write_forces_hdf5(est: ForceEstimate, path: str | Path,
                      columns: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write the force series as HDF5.

    Root datasets ``time`` [s] and one per column of
    :func:`~forcecal.forces.estimate.series_columns` [N], each with the attributes ``units``
    and ``quantity`` (``force``, ``reactions-only force`` or ``standard uncertainty``); a
    force's dataset also names its ``std`` and ``static`` datasets. Root attributes:
    ``format``, ``run``, ``fundamental_hz``, ``fundamental_std_hz``, ``waveform_std_n``,
    ``dc_observed``, ``notes``. The group ``harmonics`` holds ``harmonic``, ``frequency_hz``,
    ``kept``, ``with_inertia`` (H+1,) and per force and ``total`` the phasors (complex [N], the
    convention of :mod:`forcecal.signals.harmonics`) and, suffixed ``_std``, their standard
    uncertainties (of Re and of Im) [N].

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    path : str or Path
        The ``.h5`` file, written in place.
    columns : mapping, optional
        :func:`~forcecal.forces.estimate.series_columns` of ``est``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A force name that cannot name an HDF5 dataset (empty, ``.`` or with a ``/``).
    """
    import h5py

    # without ``columns``, they are made and written a block of rows at a time
    blocks = series_blocks(est) if columns is None else iter([(0, len(est.time),
                                                               dict(columns))])
    first = next(blocks)
    cols = first[2]
    for name in cols:
        if not name or "/" in name or name == ".":
            raise InputError(f"run '{est.run_name}': force name {name!r} cannot name an HDF5 "
                             "dataset; choose another output format or rename the force")
    names, phasors, std = _per_force(est)
    text = h5py.string_dtype()
    with h5py.File(path, "w", track_order=True) as h5:
        h5.attrs["format"] = HDF5_FORMAT
        h5.attrs["run"] = est.run_name
        h5.attrs["fundamental_hz"] = float(est.f0)
        h5.attrs["fundamental_std_hz"] = float(est.f0_std)
        h5.attrs["waveform_std_n"] = float(est.waveform_std)
        h5.attrs["dc_observed"] = bool(est.dc_observed)
        h5.attrs.create("notes", data=list(est.notes), shape=(len(est.notes),), dtype=text)
        h5.create_dataset("time", data=np.asarray(est.time, dtype=float))
        h5["time"].attrs["units"] = "s"
        for name in cols:
            ds = h5.create_dataset(name, shape=(len(est.time),), dtype=float)
            ds.attrs["units"] = "N"
            ds.attrs["quantity"] = _QUANTITY[_kind(name, names)[1]]
        for start, stop, part in itertools.chain([first], blocks):
            for name, values in part.items():
                h5[name][start:stop] = np.asarray(values, dtype=float)
        for name in names:
            h5[name].attrs["std"] = f"{name}_std"
            h5[name].attrs["static"] = f"{name}_static"
        group = h5.create_group("harmonics", track_order=True)
        group.create_dataset("harmonic", data=np.asarray(est.harmonics, dtype=np.int64))
        group.create_dataset("frequency_hz", data=np.asarray(est.harmonics) * float(est.f0))
        group["frequency_hz"].attrs["units"] = "Hz"
        group.create_dataset("kept", data=np.asarray(est.kept, dtype=bool))
        group.create_dataset("with_inertia", data=np.asarray(est.with_inertia, dtype=bool))
        for k, name in enumerate(names):
            group.create_dataset(name, data=phasors[k].astype(complex))
            group.create_dataset(f"{name}_std", data=std[k].astype(float))
            group[name].attrs["units"] = group[f"{name}_std"].attrs["units"] = "N"
    return Path(path)


# --------------------------------------------------------------------------------------------
# MATLAB


def write_forces_mat(est: ForceEstimate, path: str | Path,
                     columns: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write the force series as a MATLAB file (version 5, compressed).

    ``S = load('NAME.forces.mat')`` gives: ``run_name``; ``names`` (cell, the forces then
    ``total``); ``time`` (n x 1) [s]; ``forces``, ``force_std`` (standard uncertainty at each
    instant) and ``static`` (reactions only), (n x numel(names)) [N], one column per name;
    ``harmonics`` (H+1 x 1); ``phasors`` (H+1 x numel(names), complex [N], x(t) = X_0 +
    sum Re(X_n exp(1i n 2 pi f0 t))) and ``phasor_std`` [N]; ``kept``, ``with_inertia``
    (H+1 x 1, 0 or 1); ``f0``, ``f0_std`` [Hz]; ``waveform_std`` [N]; ``dc_observed``;
    ``notes`` (cell); ``units`` (struct: the unit of each variable). No variable shadows a
    MATLAB function (``std``, ``run``).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    path : str or Path
        The ``.mat`` file, written in place.
    columns : mapping, optional
        :func:`~forcecal.forces.estimate.series_columns` of ``est``.

    Returns
    -------
    Path
        ``path``.
    """
    from scipy.io import savemat

    cols = dict(columns) if columns is not None else est.columns()
    names, phasors, std = _per_force(est)

    def block(suffix: str) -> np.ndarray:
        return np.column_stack([np.asarray(cols[f"{n}{suffix}"], dtype=float) for n in names])

    units = {"time": "s", "forces": "N", "force_std": "N", "static": "N", "phasors": "N",
             "phasor_std": "N", "f0": "Hz", "f0_std": "Hz", "waveform_std": "N",
             "harmonics": "1"}
    doc = {
        "run_name": est.run_name,
        "names": _cell(names, row=True),
        "time": np.asarray(est.time, dtype=float)[:, None],
        "forces": block(""),
        "force_std": block("_std"),
        "static": block("_static"),
        "harmonics": np.asarray(est.harmonics, dtype=float)[:, None],
        "phasors": phasors.T.astype(complex),
        "phasor_std": std.T.astype(float),
        "kept": np.asarray(est.kept, dtype=np.uint8)[:, None],
        "with_inertia": np.asarray(est.with_inertia, dtype=np.uint8)[:, None],
        "f0": float(est.f0),
        "f0_std": float(est.f0_std),
        "waveform_std": float(est.waveform_std),
        "dc_observed": int(bool(est.dc_observed)),
        "notes": _cell(list(est.notes), row=False),
        "units": units,
    }
    with open(path, "wb") as fh:
        savemat(fh, doc, do_compression=True, oned_as="column")
    return Path(path)


def _cell(texts: list[str], row: bool) -> np.ndarray:
    """A MATLAB cell array of strings (1 x n when ``row``, else n x 1)."""
    cell = np.empty((1, len(texts)) if row else (len(texts), 1), dtype=object)
    for k, text in enumerate(texts):
        cell.flat[k] = text
    return cell


# --------------------------------------------------------------------------------------------
# UFF


def write_forces_uff(est: ForceEstimate, path: str | Path,
                     columns: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write the force series as a Universal File of dataset-58 time records (ASCII).

    One record per column of :func:`~forcecal.forces.estimate.series_columns`: function
    type 1 (time response), ID line 1 the column's name, ID line 2 what it holds (``Force``,
    ``Force  reactions only``, ``Force  std``), ID line 4 the run, ID line 5 the fundamental;
    response node k + 1 for the k-th force (the total after the forces, its ``_static`` and
    ``_std`` records on the same node), direction 0 (scalar); an even abscissa in s (data
    type 17, time; minimum the first time stamp); ordinate data type 13 (excitation force,
    force exponent 1), unit label ``N``. ``pyuff.UFF(path).read_sets()`` reads it back, and so
    does :func:`forcecal.io.run_files.read_run` (channels named by ID line 1). Values have 12
    significant digits; the abscissa minimum and increment 6 (see :mod:`forcecal.io.uff`).

    Parameters
    ----------
    est : ForceEstimate
        The run's estimate.
    path : str or Path
        The ``.uff`` file, written in place.
    columns : mapping, optional
        :func:`~forcecal.forces.estimate.series_columns` of ``est``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        A column name longer than an ID line (80 characters), or fewer than two samples.
    """
    import pyuff

    cols = dict(columns) if columns is not None else est.columns()
    time = np.asarray(est.time, dtype=float)
    if time.size < 2:
        raise InputError(f"run '{est.run_name}': a UFF time record needs two samples or more")
    names = [*est.force_names, "total"]
    run_line = f"run {est.run_name}"[:UFF_ID_CHARS]
    f0_line = f"f0 {float(est.f0)!r} Hz +- {float(est.f0_std):.3g} Hz"
    sets = []
    for name, values in cols.items():
        if len(name) > UFF_ID_CHARS:
            raise InputError(f"run '{est.run_name}': column name {name!r} is longer than a UFF "
                             f"ID line ({UFF_ID_CHARS} characters); rename the force")
        base, kind = _kind(name, names)
        dataset = pyuff.prepare_58(
            binary=0, id1=name, id2=_UFF_ID2[kind], id4=run_line, id5=f0_line,
            func_type=_TIME_RESPONSE, rsp_node=names.index(base) + 1, rsp_dir=_SCALAR,
            ref_node=0, ref_dir=0, abscissa_spacing=1, abscissa_min=float(time[0]),
            abscissa_inc=float(time[1] - time[0]), abscissa_spec_data_type=_TIME_ABSCISSA,
            abscissa_len_unit_exp=0, abscissa_force_unit_exp=0, abscissa_temp_unit_exp=0,
            abscissa_axis_units_lab="s", ordinate_spec_data_type=_EXCITATION_FORCE,
            ordinate_len_unit_exp=0, ordinate_force_unit_exp=1, ordinate_temp_unit_exp=0,
            ordinate_axis_units_lab="N", orddenom_spec_data_type=0, z_axis_spec_data_type=0,
            data=np.asarray(values, dtype=float).copy(), x=time.copy())
        dataset["abscissa_axis_lab"] = "Time"
        dataset["ordinate_axis_lab"] = "Force"
        sets.append(dataset)
    _write_sets(sets, Path(path))
    return Path(path)


def _kind(name: str, names: list[str]) -> tuple[str, str]:
    """The force or total a column belongs to, and its suffix (``""``, ``_static``, ``_std``)."""
    for suffix in ("_static", "_std"):
        if name.endswith(suffix) and name[: -len(suffix)] in names:
            return name[: -len(suffix)], suffix
    return name, ""


def series_json(est: Estimate, fmt: str, columns: Mapping[str, object]) -> dict:
    """The ``series`` entry of ``NAME.json``: the file, its format and every column's unit."""
    return {"file": f"{est.run_name}{SERIES_SUFFIXES[fmt]}", "format": fmt,
            "units": series_units(columns)}

