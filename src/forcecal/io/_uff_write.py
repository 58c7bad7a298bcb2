"""Writing an SLDV scan as a Universal File with pyuff, atomically: time records, or a broadband
scan's FRFs with their coherence (see :mod:`forcecal.io.uff` for the layout and the precision of
what pyuff writes).
"""

from __future__ import annotations

import gc
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pyuff

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..records import Scan, ScanFRF
from ._uff_frf import COHERENCE, FRF
from ._uff_sets import (
    FREQUENCY_ABSCISSA,
    GENERAL_ORDINATE,
    ORDINATE_OF_QUANTITY,
    PLUS_Z,
    TIME_ABSCISSA,
    TIME_RESPONSE,
)

__all__: list[str] = []


def write_scan_uff(
    scan: Scan, path: str | Path, binary: bool = False, node_offset: int = 1
) -> Path:
    """Write a scan as a Universal File, atomically.

    Dataset 2411 (nodes, coordinates [m]) then, per point, the vibration record (id line 2
    ``Vib  Velocity`` or ``Vib  Displacement``, ordinate type 11 or 8) and the reference
    record (id line 2 ``Ref1  Current``, unit A), both time records (function type 1) with
    response node = the point's node, direction +Z. A 3-D scan (points as (n, 6) locations)
    gets one node per distinct point and each record its response direction (+-X, Y, Z); a
    node's rows that share one reference record (one acquisition) get one reference record.

    Parameters
    ----------
    scan : Scan
        The scan to write (SI values).
    path : str or Path
        The ``.uff`` file, replaced atomically.
    binary : bool
        Write dataset 58b (float64 values) instead of ASCII 58 (12 significant digits).
    node_offset : int
        Node number of the first point; points are numbered consecutively.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    InputError
        A negative or fractional ``node_offset``.
    DataError
        NaN or infinite samples, or a 3-D record not along X, Y or Z.
    """
    if int(node_offset) != node_offset or node_offset < 0:
        raise InputError(f"scan '{path}': node_offset {node_offset} is not a non-negative integer")
    for name, values in (("response", scan.response), ("reference", scan.reference)):
        if not np.all(np.isfinite(values)):
            raise DataError(
                f"scan '{scan.source}': {name} holds NaN or infinite samples; a UFF cannot "
                "store them"
            )
    if scan.points.shape[1] == 6:
        sets = _located_sets(scan, int(node_offset), binary, path)
    else:
        nodes = int(node_offset) + np.arange(scan.n_points)
        sets = [_node_set(nodes, scan.points)]
        for node, response, reference in zip(nodes, scan.response, scan.reference, strict=True):
            sets.append(_vibration_set(int(node), response, scan.fs, scan.quantity, binary))
            sets.append(_reference_set(int(node), reference, scan.fs, binary))
    with atomic_path(path) as tmp:
        _write_sets(sets, tmp)
    return Path(path)


def write_frf_uff(scan: ScanFRF, path: str | Path, binary: bool = False) -> Path:
    """Write a broadband scan's FRFs and coherences as a Universal File, atomically.

    Dataset 2411 (nodes 1..n, coordinates [m]) then, per point, its FRF (function type 4, id
    line 2 ``Vib  Velocity / Ref1  Current`` or ``Vib  Displacement / Ref1  Current``, ordinate
    type 11 or 8 over the current) and its coherence (function type 6), both over the scan's
    lines [Hz] from the first, evenly spaced, response node the point's, direction +Z. The
    number of averages is not a field of dataset 58: the rig states it
    (``acquisition.scan_averages``).

    Parameters
    ----------
    scan : ScanFRF
        A beam's or a plate's scan, its lines evenly spaced.
    path : str or Path
        The ``.uff`` file, replaced atomically.
    binary : bool
        Dataset 58b (float64) instead of ASCII 58 (12 significant digits).

    Returns
    -------
    Path

    Raises
    ------
    DataError
        Lines not evenly spaced.
    """
    f = scan.frequencies
    step = float(f[1] - f[0])
    if np.max(np.abs(np.diff(f) - step)) > 1e-9 * step:
        raise DataError(f"scan '{scan.source}': FRF lines not evenly spaced; a UFF stores an "
                        "even abscissa")
    ordinate, unit, word = ORDINATE_OF_QUANTITY[scan.quantity]
    nodes = 1 + np.arange(scan.n_points)
    sets = [_node_set(nodes, scan.points)]
    for node, h, coh in zip(nodes, scan.values, scan.coherence, strict=True):
        for data, kind, ids, axis in (
                (h, FRF, ("H1", f"Vib  {word} / Ref1  Current"), (ordinate, 1, word, f"{unit}/A")),
                (coh, COHERENCE, ("Coh", "Coherence  Vib / Ref1"), (GENERAL_ORDINATE, 0,
                                                                     "Coherence", ""))):
            spec_type, length_exp, label, units = axis
            dataset = pyuff.prepare_58(
                binary=1 if binary else 0, id1=ids[0], id2=ids[1], func_type=kind,
                rsp_node=int(node), rsp_dir=PLUS_Z, ref_node=0, ref_dir=0, abscissa_spacing=1,
                abscissa_min=float(f[0]), abscissa_inc=step,
                abscissa_spec_data_type=FREQUENCY_ABSCISSA, abscissa_axis_units_lab="Hz",
                ordinate_spec_data_type=spec_type, ordinate_len_unit_exp=length_exp,
                ordinate_axis_units_lab=units, orddenom_spec_data_type=GENERAL_ORDINATE,
                z_axis_spec_data_type=0, data=np.array(data), x=f.copy())
            dataset["abscissa_axis_lab"] = "Frequency"
            dataset["ordinate_axis_lab"] = label
            sets.append(dataset)
    with atomic_path(path) as tmp:
        _write_sets(sets, tmp)
    return Path(path)


def _located_sets(scan: Scan, node_offset: int, binary: bool,
                  path: str | Path) -> list[dict]:
    """Datasets of a 3-D scan (rows located by (x, y, z, dx, dy, dz)): one node per distinct
    point, a vibration record per row with its response direction, and one reference record
    per node when its rows share the acquisition (equal references), else one per row."""
    pts = scan.points[:, :3]
    unique, node_of_row = np.unique(pts, axis=0, return_inverse=True)
    node_of_row = node_of_row.ravel()
    nodes = node_offset + np.arange(len(unique))
    sets = [_node_set(nodes, unique)]
    for k in range(len(unique)):
        rows = np.flatnonzero(node_of_row == k)
        node = int(nodes[k])
        shared = all(np.array_equal(scan.reference[r], scan.reference[rows[0]]) for r in rows)
        for r in rows:
            d = scan.points[r, 3:]
            axis = int(np.argmax(np.abs(d)))
            if abs(d[axis]) < (1 - 1e-9) * np.linalg.norm(d):
                raise DataError(f"scan '{path}': row {r + 1} measures along {d.tolist()}; a UFF "
                                "response direction is X, Y or Z")
            code = int(np.sign(d[axis])) * (axis + 1)
            sets.append(_vibration_set(node, scan.response[r], scan.fs, scan.quantity, binary,
                                       code))
            if not shared or r == rows[0]:
                sets.append(_reference_set(node, scan.reference[r], scan.fs, binary,
                                           code if not shared else PLUS_Z))
    return sets


def _node_set(nodes: np.ndarray, points: np.ndarray) -> dict:
    """Dataset 2411 for (n_points, n_dim) coordinates [m]; missing axes are zero."""
    xyz = np.zeros((len(nodes), 3))
    n_dim = min(points.shape[1], 3)
    xyz[:, :n_dim] = points[:, :n_dim]
    zeros = np.zeros(len(nodes), dtype=int)
    return pyuff.prepare_2411(
        node_nums=np.asarray(nodes, dtype=int),
        def_cs=zeros,
        disp_cs=zeros,
        color=np.full(len(nodes), 8, dtype=int),
        x=xyz[:, 0].copy(),
        y=xyz[:, 1].copy(),
        z=xyz[:, 2].copy(),
    )


def _vibration_set(node: int, values: np.ndarray, fs: float, quantity: str, binary: bool,
                   direction: int = PLUS_Z) -> dict:
    ordinate, unit, word = ORDINATE_OF_QUANTITY[quantity]
    return _time_set(node, values, fs, binary, ("Vib", f"Vib  {word}"), (ordinate, 1, word, unit),
                     direction)


def _reference_set(node: int, values: np.ndarray, fs: float, binary: bool,
                   direction: int = PLUS_Z) -> dict:
    ordinate = (GENERAL_ORDINATE, 0, "Current", "A")
    return _time_set(node, values, fs, binary, ("Ref1", "Ref1  Current"), ordinate, direction)


def _time_set(
    node: int,
    values: np.ndarray,
    fs: float,
    binary: bool,
    ids: tuple[str, str],
    ordinate: tuple[int, int, str, str],
    direction: int = PLUS_Z,
) -> dict:
    """One dataset 58 (binary: 58b) time record with an even abscissa."""
    data = np.asarray(values, dtype=float)
    spec_type, length_exp, axis_label, unit = ordinate
    dataset = pyuff.prepare_58(
        binary=1 if binary else 0,
        id1=ids[0],
        id2=ids[1],
        func_type=TIME_RESPONSE,
        rsp_node=node,
        rsp_dir=direction,
        ref_node=0,
        ref_dir=0,
        abscissa_spacing=1,
        abscissa_inc=float(1.0 / fs),
        abscissa_spec_data_type=TIME_ABSCISSA,
        abscissa_axis_units_lab="s",
        ordinate_spec_data_type=spec_type,
        ordinate_len_unit_exp=length_exp,
        ordinate_axis_units_lab=unit,
        orddenom_spec_data_type=0,
        z_axis_spec_data_type=0,
        data=data.copy(),
        x=np.arange(data.size) / fs,
    )
    dataset["abscissa_axis_lab"] = "Time"
    dataset["ordinate_axis_lab"] = axis_label
    return dataset


def _write_sets(sets: list[dict], path: Path) -> None:
    """Write datasets with pyuff, overwriting ``path``.

    A Universal File is its datasets one after another, so each ASCII dataset is written by
    pyuff to a file of its own and the pieces are joined: pyuff re-reads the file it appends to
    after every dataset, which makes one growing file cost time quadratic in the number of
    records. Binary (58b) scans are written in one file.
    pyuff's binary writer reopens the file by name and leaves the reopened handle to the
    garbage collector; the ResourceWarning that follows is pyuff's, silenced here only.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        if any(d.get("binary") for d in sets):   # pyuff writes 58b only into a whole file
            pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
            gc.collect()
            return
    with tempfile.TemporaryDirectory() as tmp, open(path, "wb") as out:
        for k, dataset in enumerate(sets):
            piece = Path(tmp) / f"{k}.uff"
            pyuff.UFF(str(piece)).write_sets([dataset], mode="overwrite")
            out.write(piece.read_bytes())
