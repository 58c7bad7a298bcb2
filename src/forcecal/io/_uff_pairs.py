"""The records of an SLDV scan file paired by node: per scan point one vibration record and one
reference record, of one function type (time records or spectra; see :mod:`forcecal.io.uff`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ._uff_sets import PLUS_Z, QUANTITY_OF_ORDINATE

__all__: list[str] = []

MIN_MEASURED_SHARE = 0.5
"""Fewest of the geometry's nodes, as a share, that a scan must measure (else it was cut)."""

Row = tuple[int, int, dict, dict]
"""(node, response direction code, vibration record, reference record) of one scan row."""

_WARN_DEPTH = 6
"""Stack depth from the missing-points warning to the caller of ``read_scan_uff``."""


def split_records(records: Sequence[dict], path: str | Path, label: str
                  ) -> tuple[dict, dict, dict]:
    """Dataset-58 records of one function type, by response node.

    Returns three dicts node -> list of records: vibrations (velocity or displacement),
    references (id line 2 contains ``label``) and the others, which are ignored.
    """
    vibrations: dict[int, list[dict]] = {}
    references: dict[int, list[dict]] = {}
    others: dict[int, list[dict]] = {}
    for record in records:
        if label in str(record.get("id2", "")):
            target = references
        else:
            target = vibrations if vibration_quantity(record) else others
        target.setdefault(int(record.get("rsp_node", 0)), []).append(record)
    if not references:
        raise InputError(
            f"scan '{path}': no reference records (no record whose id line 2 contains '{label}')"
        )
    if not vibrations:
        raise InputError(
            f"scan '{path}': no vibration records (velocity, ordinate type 11, or displacement, "
            f"8){describe_others(others)}"
        )
    return vibrations, references, others


def scan_rows(records: tuple[dict, dict, dict], geometry: dict[int, tuple], path: str | Path,
              label: str, locations: bool, what: str) -> tuple[list[Row], np.ndarray]:
    """The scan's rows and their points.

    Parameters
    ----------
    records : tuple of dict
        :func:`split_records` of the file.
    geometry : dict
        node -> (x, y, z) [m].
    path : str or Path
        The file, for messages.
    label : str
        The reference label, for messages.
    locations : bool
        A 3-D body's rows: one per vibration record, located by (x, y, z, dx, dy, dz).
    what : str
        What the records are ("time records", "spectra"), for messages.

    Returns
    -------
    rows : list of Row
        Ordered by node (then direction).
    points : (n_rows, n_dim) array [m]
        n_dim = 1 or 2 as in :func:`scan_points`; 6 with ``locations``.
    """
    vibrations, references, _ = records
    if locations:
        rows = _located_rows(records, geometry, path, label, what)
        points = np.array([[*geometry[n], *_axis_vector(code)] for n, code, _, _ in rows])
        return rows, points
    nodes = _paired_nodes(records, geometry, path, label, what)
    rows = [(n, PLUS_Z, vibrations[n][0], references[n][0]) for n in nodes]
    return rows, scan_points(geometry, nodes)


def _paired_nodes(records: tuple[dict, dict, dict], geometry: dict[int, tuple],
                  path: str | Path, label: str, what: str) -> list[int]:
    """Sorted scan nodes, each with exactly one vibration and one reference record."""
    vibrations, references, _ = records
    for node in sorted(vibrations):
        if node not in references:
            raise DataError(
                f"scan '{path}': node {node} has a vibration record but no reference record "
                f"(id line 2 containing '{label}')"
            )
    _check_references_paired(records, path)
    for node in sorted(vibrations):
        for kind, by_node in (("vibration", vibrations), ("reference", references)):
            if len(by_node[node]) > 1:
                ids = ", ".join(repr(str(r.get("id2", "")).strip()) for r in by_node[node])
                raise DataError(
                    f"scan '{path}': node {node} has {len(by_node[node])} {kind} records "
                    f"({ids}); expected one (a more specific reference label may help)"
                )
        if node not in geometry:
            raise DataError(
                f"scan '{path}': node {node} has {what} but no coordinates "
                "(dataset 2411 or 15)"
            )
    check_no_missing_points(geometry, set(vibrations), path, what)
    return sorted(vibrations)


def check_no_missing_points(geometry: dict[int, tuple], measured: set[int],
                            path: str | Path, what: str, depth: int = 0) -> None:
    """Nodes of the geometry without records: a scan cut short (an export interrupted, a file
    truncated) would otherwise give a model from its first points only.

    DataError when fewer than :data:`MIN_MEASURED_SHARE` of the geometry's nodes are measured;
    a warning naming the unmeasured nodes otherwise (a mesh may hold nodes never scanned),
    ``depth`` calls fewer below the caller of ``read_scan_uff`` than the time records' path.
    """
    missing = sorted(set(geometry) - measured)
    if not missing:
        return
    shown = ", ".join(str(n) for n in missing[:5]) + (
        f" and {len(missing) - 5} more" if len(missing) > 5 else "")
    text = (f"scan '{path}': the geometry lists {len(geometry)} nodes but only {len(measured)} "
            f"have {what}; no records for node {shown}")
    if len(measured) < MIN_MEASURED_SHARE * len(geometry):
        raise DataError(f"{text} (a scan cut short?)")
    warnings.warn(f"{text}; the model uses the measured ones", stacklevel=_WARN_DEPTH - depth)


def _check_references_paired(records: tuple[dict, dict, dict], path: str | Path) -> None:
    """Every node with a reference record has a vibration record."""
    vibrations, references, others = records
    for node in sorted(references):
        if node not in vibrations:
            raise DataError(
                f"scan '{path}': node {node} has a reference record but no vibration record "
                f"(velocity or displacement){describe_others({node: others.get(node, [])})}"
            )


def _located_rows(records: tuple[dict, dict, dict], geometry: dict[int, tuple],
                  path: str | Path, label: str, what: str) -> list[Row]:
    """(node, response direction, vibration, reference) of every vibration record of a 3-D
    scan, ordered by node then direction (see :func:`forcecal.io.uff.read_scan_uff`)."""
    vibrations, references, _ = records
    rows = []
    _check_references_paired(records, path)
    for node in sorted(vibrations):
        if node not in geometry:
            raise DataError(f"scan '{path}': node {node} has {what} but no coordinates "
                            "(dataset 2411 or 15)")
        refs = references.get(node, [])
        if not refs:
            raise DataError(f"scan '{path}': node {node} has a vibration record but no "
                            f"reference record (id line 2 containing '{label}')")
        seen: set[int] = set()
        for vib in sorted(vibrations[node], key=lambda r: abs(_direction_code(r))):
            code = _direction_code(vib)
            if abs(code) not in (1, 2, 3):
                raise DataError(f"scan '{path}': node {node}: response direction {code} is not a "
                                "translation (X, Y, Z: 1, 2, 3 or their negatives)")
            if abs(code) in seen:
                raise DataError(f"scan '{path}': node {node} has two vibration records along "
                                f"axis {'XYZ'[abs(code) - 1]}; expected one per direction")
            seen.add(abs(code))
            ref = refs[0] if len(refs) == 1 else next(
                (r for r in refs if _direction_code(r) == code), None)
            if ref is None:
                raise DataError(f"scan '{path}': node {node} has {len(refs)} reference records, "
                                f"none with the response direction {code} of its vibration "
                                "record")
            rows.append((node, code, vib, ref))
    check_no_missing_points(geometry, set(vibrations), path, what)
    return rows


def _direction_code(record: dict) -> int:
    """A record's response direction: 1, 2, 3 = +X, +Y, +Z, negative for minus (default +Z)."""
    try:
        return int(record.get("rsp_dir", PLUS_Z))
    except (TypeError, ValueError):
        return 0


def _axis_vector(code: int) -> np.ndarray:
    """Unit vector of a response direction code (1, 2, 3 or negative)."""
    e = np.zeros(3)
    e[abs(code) - 1] = np.sign(code)
    return e


def scan_quantity(rows: Sequence[Row], path: str | Path) -> str:
    """'velocity' or 'displacement', common to the vibration records of all rows."""
    node0, _, first_record, _ = rows[0]
    first = vibration_quantity(first_record)
    for node, _, record, _ in rows:
        quantity = vibration_quantity(record)
        if quantity != first:
            raise DataError(
                f"scan '{path}': node {node} records {quantity} but node {node0} records "
                f"{first}; a scan holds one quantity"
            )
    return str(first)


def vibration_quantity(record: dict) -> str | None:
    """'velocity'/'displacement' from the ordinate type (11/8), else from id line 2; or None."""
    ordinate = record.get("ordinate_spec_data_type")
    if ordinate in QUANTITY_OF_ORDINATE:
        return QUANTITY_OF_ORDINATE[ordinate]
    text = str(record.get("id2", "")).lower()
    return next((q for q in ("velocity", "displacement") if q in text), None)


def describe_others(others: dict[int, list[dict]]) -> str:
    """'; found: 'Vib  Acceleration' (ordinate type 12), ...' or ''."""
    found = [
        f"'{str(r.get('id2', '')).strip()}' (ordinate type {r.get('ordinate_spec_data_type')})"
        for records in others.values()
        for r in records
    ]
    if not found:
        return ""
    more = f" and {len(found) - 3} more" if len(found) > 3 else ""
    return f"; found: {', '.join(found[:3])}{more}"


def scan_points(geometry: dict[int, tuple], nodes: list[int]) -> np.ndarray:
    """(n_points, n_dim) [m]: x only for a line scan, (x, y) when any y is non-zero."""
    xyz = np.array([geometry[n] for n in nodes], dtype=float)
    return xyz[:, :2] if np.any(xyz[:, 1] != 0.0) else xyz[:, :1]


def record_values(record: dict, node: int, kind: str, path: str | Path, factor: float,
                  complex_values: bool) -> np.ndarray:
    """A record's ordinate values in SI (divided by the length factor to its power).

    Parameters
    ----------
    record : dict
        The dataset 58.
    node : int
        Its node, for messages.
    kind : str
        "time record", "vibration spectrum", ..., for messages.
    path : str or Path
        The file, for messages.
    factor : float
        The file's length unit factor (file value / factor = metres).
    complex_values : bool
        Whether the values must be complex (a spectrum) or real (a time record).

    Returns
    -------
    (n_values,) float or complex array
    """
    data = np.asarray(record.get("data"))
    if np.iscomplexobj(data) != complex_values:
        found = "complex values" if np.iscomplexobj(data) else "real values, no phase"
        raise DataError(f"scan '{path}': node {node}: {kind} holds {found}")
    data = data.astype(complex if complex_values else float)
    if not np.all(np.isfinite(data)):
        bad = int(np.count_nonzero(~np.isfinite(data)))
        what = "lines" if complex_values else "samples"
        raise DataError(f"scan '{path}': node {node}: record has {bad} NaN or infinite {what}")
    exponent = int(record.get("ordinate_len_unit_exp", 0) or 0)
    return data / factor**exponent if exponent and factor != 1.0 else data
