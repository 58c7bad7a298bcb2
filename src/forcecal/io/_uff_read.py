"""Reading an SLDV scan from a Universal File: time records paired by node, sampling and
values checked (see :mod:`forcecal.io.uff` for the layout).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..records import Scan
from ._uff_sets import (
    PLUS_Z,
    QUANTITY_OF_ORDINATE,
    RATE_DIGITS,
    TIME_RESPONSE,
    geometry_of,
    length_factor,
    read_sets,
    set_type,
    type_list,
)

__all__ = ["MIN_MEASURED_SHARE", "read_scan_uff"]

MIN_MEASURED_SHARE = 0.5
"""Fewest of the geometry's nodes, as a share, that a scan must measure (else it was cut)."""


def read_scan_uff(path: str | Path, reference_label: str = "Ref",
                  locations: bool = False) -> Scan:
    """Read an SLDV scan from a Universal File (ASCII or binary).

    Parameters
    ----------
    path : str or Path
        The ``.uff``/``.unv`` file.
    reference_label : str
        Text that id line 2 of every reference record contains (``Ref1  Current``).
    locations : bool
        For a 3-D body: a node may carry up to three vibration records, one per response
        direction (X, Y, Z, or their negatives: a 3-D SLDV's components), and every record
        becomes a row located by (x, y, z, dx, dy, dz). The node's reference record serves all
        of its directions when it has one; otherwise each direction has its own, paired by
        response direction.

    Returns
    -------
    Scan
        ``points`` (n_points, n_dim) [m] ordered by node number, n_dim = 2 when any y
        coordinate is non-zero, else 1 (z, the measuring direction, is not a scan coordinate);
        with ``locations``, (n_records, 6) ordered by node then direction;
        ``response`` (n_points, n_samples) [m/s] or [m]; ``reference`` (n_points, n_samples)
        [A]; ``fs`` [Hz] = 1 / abscissa increment.

    Raises
    ------
    InputError
        The file is missing, is not a Universal File, or lacks node coordinates, time records
        or reference records.
    DataError
        A scan point lacks one of its two records, or the records disagree in length,
        sampling or quantity.
    """
    sets = read_sets(path, "scan")
    geometry = geometry_of(sets, path, "scan")
    records = _split_time_records(sets, path, reference_label)
    vibrations, references, _ = records
    if locations:
        rows = _located_rows(records, geometry, path, reference_label)
        points = np.array([[*geometry[n], *_axis_vector(code)] for n, code, _, _ in rows])
    else:
        nodes = _paired_nodes(records, geometry, path, reference_label)
        rows = [(n, PLUS_Z, vibrations[n][0], references[n][0]) for n in nodes]
        points = _scan_points(geometry, nodes)
    factor = length_factor(sets, path)
    quantity = _scan_quantity([(n, v) for n, _, v, _ in rows], path)
    step, n_samples = _common_sampling(rows, path)
    response = np.array([_values(v, n, path, factor) for n, _, v, _ in rows])
    reference = np.array([_values(r, n, path, 1.0) for n, _, _, r in rows])
    return Scan(
        points=points,
        response=response.reshape(len(rows), n_samples),
        reference=reference.reshape(len(rows), n_samples),
        fs=_rate_from_increment(step),
        quantity=quantity,
        source=str(path),
    )


def _split_time_records(sets: Sequence[dict], path: str | Path, label: str) -> tuple[dict, ...]:
    """Time records (dataset 58, function type 1) by response node.

    Returns three dicts node -> list of records: vibrations (velocity or displacement),
    references (id line 2 contains ``label``) and the others, which are ignored.
    """
    records = [s for s in sets if set_type(s) == 58]
    if not records:
        raise InputError(
            f"scan '{path}': no time records (dataset 58); found datasets {type_list(sets)}"
        )
    times = [r for r in records if r.get("func_type") == TIME_RESPONSE]
    if not times:
        raise InputError(
            f"scan '{path}': none of the {len(records)} dataset-58 records is a time record "
            "(function type 1)"
        )
    vibrations: dict[int, list[dict]] = {}
    references: dict[int, list[dict]] = {}
    others: dict[int, list[dict]] = {}
    for record in times:
        if label in str(record.get("id2", "")):
            target = references
        else:
            target = vibrations if _vibration_quantity(record) else others
        target.setdefault(int(record.get("rsp_node", 0)), []).append(record)
    if not references:
        raise InputError(
            f"scan '{path}': no reference records (no record whose id line 2 contains '{label}')"
        )
    if not vibrations:
        raise InputError(
            f"scan '{path}': no vibration records (velocity, ordinate type 11, or displacement, "
            f"8){_describe_others(others)}"
        )
    return vibrations, references, others


def _paired_nodes(
    records: tuple[dict, ...],
    geometry: dict[int, tuple],
    path: str | Path,
    label: str,
) -> list[int]:
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
                f"scan '{path}': node {node} has time records but no coordinates "
                "(dataset 2411 or 15)"
            )
    _check_no_missing_points(geometry, set(vibrations), path)
    return sorted(vibrations)


def _check_no_missing_points(geometry: dict[int, tuple], measured: set[int],
                             path: str | Path) -> None:
    """Nodes of the geometry without records: a scan cut short (an export interrupted, a file
    truncated) would otherwise give a model from its first points only.

    DataError when fewer than :data:`MIN_MEASURED_SHARE` of the geometry's nodes are measured;
    a warning naming the unmeasured nodes otherwise (a mesh may hold nodes never scanned).
    """
    missing = sorted(set(geometry) - measured)
    if not missing:
        return
    shown = ", ".join(str(n) for n in missing[:5]) + (
        f" and {len(missing) - 5} more" if len(missing) > 5 else "")
    text = (f"scan '{path}': the geometry lists {len(geometry)} nodes but only {len(measured)} "
            f"have time records; no records for node {shown}")
    if len(measured) < MIN_MEASURED_SHARE * len(geometry):
        raise DataError(f"{text} (a scan cut short?)")
    warnings.warn(f"{text}; the model uses the measured ones", stacklevel=4)


def _check_references_paired(records: tuple[dict, ...], path: str | Path) -> None:
    """Every node with a reference record has a vibration record."""
    vibrations, references, others = records
    for node in sorted(references):
        if node not in vibrations:
            raise DataError(
                f"scan '{path}': node {node} has a reference record but no vibration record "
                f"(velocity or displacement){_describe_others({node: others.get(node, [])})}"
            )


def _located_rows(records: tuple[dict, ...], geometry: dict[int, tuple], path: str | Path,
                  label: str) -> list[tuple[int, int, dict, dict]]:
    """(node, response direction, vibration, reference) of every vibration record of a 3-D
    scan, ordered by node then direction (see :func:`read_scan_uff`)."""
    vibrations, references, _ = records
    rows = []
    _check_references_paired(records, path)
    for node in sorted(vibrations):
        if node not in geometry:
            raise DataError(f"scan '{path}': node {node} has time records but no coordinates "
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
    _check_no_missing_points(geometry, set(vibrations), path)
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


def _scan_quantity(vibrations: list[tuple[int, dict]], path: str | Path) -> str:
    """'velocity' or 'displacement', common to all vibration records."""
    node0, first_record = vibrations[0]
    first = _vibration_quantity(first_record)
    for node, record in vibrations:
        quantity = _vibration_quantity(record)
        if quantity != first:
            raise DataError(
                f"scan '{path}': node {node} records {quantity} but node {node0} records "
                f"{first}; a scan holds one quantity"
            )
    return str(first)


def _vibration_quantity(record: dict) -> str | None:
    """'velocity'/'displacement' from the ordinate type (11/8), else from id line 2; or None."""
    ordinate = record.get("ordinate_spec_data_type")
    if ordinate in QUANTITY_OF_ORDINATE:
        return QUANTITY_OF_ORDINATE[ordinate]
    text = str(record.get("id2", "")).lower()
    return next((q for q in ("velocity", "displacement") if q in text), None)


def _describe_others(others: dict[int, list[dict]]) -> str:
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


def _common_sampling(rows: list[tuple[int, int, dict, dict]], path: str | Path
                     ) -> tuple[float, int]:
    """Abscissa increment [s] and sample count shared by every record of the rows
    (node, direction, vibration, reference)."""
    node0, _, first, _ = rows[0]
    step0, n0 = _step_of(first, node0, path), len(np.atleast_1d(first.get("data", [])))
    for node, _, vibration, reference in rows:
        for kind, record in (("vibration", vibration), ("reference", reference)):
            n = len(np.atleast_1d(record.get("data", [])))
            if n != n0:
                raise DataError(
                    f"scan '{path}': node {node}: {kind} record has {n} samples, expected {n0} "
                    f"(as node {node0})"
                )
            step = _step_of(record, node, path)
            if abs(step - step0) > 1e-6 * step0:
                raise DataError(
                    f"scan '{path}': node {node}: {kind} record sampled every {step:.6g} s, "
                    f"expected {step0:.6g} s (as node {node0})"
                )
    if n0 < 2:
        raise DataError(f"scan '{path}': records hold {n0} samples; at least 2 needed")
    return step0, n0


def _step_of(record: dict, node: int, path: str | Path) -> float:
    """Sampling interval [s] of one time record."""
    if record.get("abscissa_spacing", 1) == 1:
        step = float(record.get("abscissa_inc", 0.0))
    else:
        x = np.asarray(record.get("x", []), dtype=float)
        diffs = np.diff(x)
        step = float(np.mean(diffs)) if diffs.size else 0.0
        if diffs.size and np.max(np.abs(diffs - step)) > 1e-6 * abs(step):
            raise DataError(f"scan '{path}': node {node}: record abscissa is not uniformly spaced")
    if not np.isfinite(step) or step <= 0:
        raise DataError(f"scan '{path}': node {node}: abscissa increment {step} is not positive")
    return step


def _values(record: dict, node: int, path: str | Path, factor: float) -> np.ndarray:
    """(n_samples,) real record values in SI (divided by the length factor to its power)."""
    data = np.asarray(record.get("data"))
    if np.iscomplexobj(data):
        raise DataError(f"scan '{path}': node {node}: time record holds complex values")
    data = data.astype(float)
    if not np.all(np.isfinite(data)):
        bad = int(np.count_nonzero(~np.isfinite(data)))
        raise DataError(f"scan '{path}': node {node}: record has {bad} NaN or infinite samples")
    exponent = int(record.get("ordinate_len_unit_exp", 0) or 0)
    return data / factor**exponent if exponent and factor != 1.0 else data


def _scan_points(geometry: dict[int, tuple], nodes: list[int]) -> np.ndarray:
    """(n_points, n_dim) [m]: x only for a line scan, (x, y) when any y is non-zero."""
    xyz = np.array([geometry[n] for n in nodes], dtype=float)
    return xyz[:, :2] if np.any(xyz[:, 1] != 0.0) else xyz[:, :1]


def _rate_from_increment(step: float) -> float:
    """Sampling rate [Hz] from an abscissa increment given to limited decimal digits.

    A UFF stores the increment with 6 significant digits, so 1/step is off by up to 5e-6 in
    relative terms. Returns the number with the fewest significant digits whose reciprocal,
    written with as many digits as the file gave (at least 6), is the increment in the file;
    for a rate such as 5120 Hz that is the rate that was written.
    """
    digits = max(RATE_DIGITS, _significant_digits(step))
    written = f"{step:.{digits - 1}e}"
    raw = 1.0 / step
    for n in range(1, 16):
        candidate = float(f"{raw:.{n - 1}e}")
        if f"{1.0 / candidate:.{digits - 1}e}" == written:
            return candidate
    return raw


def _significant_digits(value: float) -> int:
    """Significant digits of the shortest repr of ``value``."""
    mantissa = repr(float(value)).lower().split("e")[0].replace("-", "").replace(".", "")
    return max(1, len(mantissa.strip("0")))
