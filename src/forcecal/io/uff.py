"""SLDV scans in the Universal File Format (UFF), read and written with pyuff.

A scan file holds the node coordinates (dataset 2411 or 15) and, for every scan point, two
dataset-58 time records (function type 1) whose response node is that point: the vibration
(velocity, ordinate type 11, or displacement, ordinate type 8) and the reference, the coil
current, recognised by its id line 2 (``Ref1  Current``). See INTERFACES.md section 2.

Precision of what pyuff writes: coordinates 17 significant digits (exact in float64); ASCII
record values ``%20.11e`` (12 significant digits, relative error at most 5e-12); binary
(58b) record values float64, exact; the abscissa increment ``%13.5e`` (6 significant digits) in
both forms, from which :func:`read_scan_uff` recovers the sampling rate exactly whenever it has
at most 6 significant digits.
"""

from __future__ import annotations

import gc
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyuff

from ..errors import DataError, InputError
from ..records import Scan
from .atomic import atomic_path

__all__ = ["read_scan_uff", "read_uff_geometry", "write_scan_uff"]

_TIME_RESPONSE = 1  # dataset 58 function type "time response"
_QUANTITY_OF_ORDINATE = {11: "velocity", 8: "displacement"}
_ORDINATE_OF_QUANTITY = {
    "velocity": (11, "m/s", "Velocity"),
    "displacement": (8, "m", "Displacement"),
}
_COORDINATE_SETS = (2411, 15)
_TIME_ABSCISSA = 17  # abscissa specific data type "time"
_GENERAL_ORDINATE = 0  # ordinate specific data type "general" (used for the current)
_PLUS_Z = 3
_RATE_DIGITS = 6  # significant digits of the abscissa increment as a UFF stores it (E13.5)


# --------------------------------------------------------------------------------------------
# reading


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
    sets = _read_sets(path, "scan")
    geometry = _geometry_of(sets, path, "scan")
    records = _split_time_records(sets, path, reference_label)
    vibrations, references, _ = records
    if locations:
        rows = _located_rows(records, geometry, path, reference_label)
        points = np.array([[*geometry[n], *_axis_vector(code)] for n, code, _, _ in rows])
    else:
        nodes = _paired_nodes(records, geometry, path, reference_label)
        rows = [(n, _PLUS_Z, vibrations[n][0], references[n][0]) for n in nodes]
        points = _scan_points(geometry, nodes)
    factor = _length_factor(sets, path)
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


def read_uff_geometry(path: str | Path) -> dict[int, tuple[float, float, float]]:
    """Node coordinates of a Universal File (datasets 2411 or 15), in metres.

    A units dataset 164 converts the file's length unit to metres (SI = value / factor).

    Returns
    -------
    dict
        node number -> (x, y, z) [m].
    """
    sets = _read_sets(path, "UFF")
    return _geometry_of(sets, path, "UFF")


def _read_sets(path: str | Path, what: str) -> list[dict]:
    """All datasets of a Universal File as pyuff dictionaries; one-line errors otherwise."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what} '{path}': file does not exist")
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exception on anything malformed
        raise InputError(
            f"{what} '{path}': not a readable Universal File (pyuff: {_first_line(exc)})"
        ) from exc
    if isinstance(sets, dict):  # pyuff returns a lone dataset unwrapped
        sets = [sets]
    sets = [s for s in sets if isinstance(s, dict) and _set_type(s) > 0]  # 0: garbage block
    if not sets:
        raise InputError(f"{what} '{path}': not a Universal File (no dataset found)")
    return sets


def _geometry_of(
    sets: Sequence[dict], path: str | Path, what: str
) -> dict[int, tuple[float, float, float]]:
    """node -> (x, y, z) [m] from every dataset 2411 and 15 (a later one overrides)."""
    factor = _length_factor(sets, path)
    geometry: dict[int, tuple[float, float, float]] = {}
    for dataset in sets:
        if _set_type(dataset) in _COORDINATE_SETS:
            geometry.update(_nodes_of(dataset, path, factor))
    if not geometry:
        raise InputError(
            f"{what} '{path}': no node coordinates (dataset 2411 or 15); "
            f"found datasets {_type_list(sets)}"
        )
    return geometry


def _nodes_of(dataset: dict, path: str | Path, factor: float) -> dict[int, tuple]:
    """Coordinates of one node dataset, converted to metres."""
    try:
        nums = np.asarray(dataset["node_nums"], dtype=float)
        xyz = np.array([dataset[k] for k in ("x", "y", "z")], dtype=float) / factor
    except (KeyError, ValueError) as exc:
        raise InputError(
            f"UFF '{path}': dataset {_set_type(dataset)} (nodes) is malformed"
        ) from exc
    if xyz.shape != (3, nums.size) or not np.all(np.isfinite(xyz)):
        raise InputError(f"UFF '{path}': dataset {_set_type(dataset)} (nodes) is malformed")
    return {
        int(n): (float(x), float(y), float(z)) for n, (x, y, z) in zip(nums, xyz.T, strict=True)
    }


def _length_factor(sets: Sequence[dict], path: str | Path) -> float:
    """Length unit factor of the first dataset 164 (file value / factor = metres), else 1."""
    for dataset in sets:
        if _set_type(dataset) == 164:
            factor = float(dataset.get("length", 1.0))
            if not np.isfinite(factor) or factor <= 0:
                raise InputError(
                    f"UFF '{path}': dataset 164 gives length unit factor {factor}; "
                    "expected a positive number"
                )
            return factor
    return 1.0


def _split_time_records(sets: Sequence[dict], path: str | Path, label: str) -> tuple[dict, ...]:
    """Time records (dataset 58, function type 1) by response node.

    Returns three dicts node -> list of records: vibrations (velocity or displacement),
    references (id line 2 contains ``label``) and the others, which are ignored.
    """
    records = [s for s in sets if _set_type(s) == 58]
    if not records:
        raise InputError(
            f"scan '{path}': no time records (dataset 58); found datasets {_type_list(sets)}"
        )
    times = [r for r in records if r.get("func_type") == _TIME_RESPONSE]
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
    return sorted(vibrations)


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
    return rows


def _direction_code(record: dict) -> int:
    """A record's response direction: 1, 2, 3 = +X, +Y, +Z, negative for minus (default +Z)."""
    try:
        return int(record.get("rsp_dir", _PLUS_Z))
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
    if ordinate in _QUANTITY_OF_ORDINATE:
        return _QUANTITY_OF_ORDINATE[ordinate]
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
    digits = max(_RATE_DIGITS, _significant_digits(step))
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


# --------------------------------------------------------------------------------------------
# writing


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
    path : str or Path
    binary : bool
        Write dataset 58b (float64 values) instead of ASCII 58 (12 significant digits).
    node_offset : int
        Node number of the first point; points are numbered consecutively.

    Returns
    -------
    Path
        The written file.
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


def _located_sets(scan: Scan, node_offset: int, binary: bool, path) -> list[dict]:
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
                                           code if not shared else _PLUS_Z))
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
                   direction: int = _PLUS_Z) -> dict:
    ordinate, unit, word = _ORDINATE_OF_QUANTITY[quantity]
    return _time_set(node, values, fs, binary, ("Vib", f"Vib  {word}"), (ordinate, 1, word, unit),
                     direction)


def _reference_set(node: int, values: np.ndarray, fs: float, binary: bool,
                   direction: int = _PLUS_Z) -> dict:
    ordinate = (_GENERAL_ORDINATE, 0, "Current", "A")
    return _time_set(node, values, fs, binary, ("Ref1", "Ref1  Current"), ordinate, direction)


def _time_set(
    node: int,
    values: np.ndarray,
    fs: float,
    binary: bool,
    ids: tuple[str, str],
    ordinate: tuple[int, int, str, str],
    direction: int = _PLUS_Z,
) -> dict:
    """One dataset 58 (binary: 58b) time record with an even abscissa."""
    data = np.asarray(values, dtype=float)
    spec_type, length_exp, axis_label, unit = ordinate
    dataset = pyuff.prepare_58(
        binary=1 if binary else 0,
        id1=ids[0],
        id2=ids[1],
        func_type=_TIME_RESPONSE,
        rsp_node=node,
        rsp_dir=direction,
        ref_node=0,
        ref_dir=0,
        abscissa_spacing=1,
        abscissa_inc=float(1.0 / fs),
        abscissa_spec_data_type=_TIME_ABSCISSA,
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


# --------------------------------------------------------------------------------------------
# small helpers


def _set_type(dataset: dict) -> int:
    try:
        return int(dataset.get("type", -1))
    except (TypeError, ValueError):
        return -1


def _type_list(sets: Sequence[dict]) -> str:
    types = sorted({_set_type(s) for s in sets})
    return ", ".join(str(t) for t in types) if types else "none"


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
