"""Reading a broadband SLDV scan exported as FRFs: per point one frequency response function
(dataset 58, function type 4) of the vibration (velocity, ordinate type 11, or displacement, 8)
to the reference, and its ordinary coherence (function type 6), paired by response node over one
common set of evenly spaced lines [Hz].

An FRF's phase is relative to the reference at each line, so a steady drive's harmonics cannot be
read from it (:data:`forcecal.records.FRF_PHASE`); a broadband scan can, its noise stated by the
coherence and the number of averages the rig gives (:func:`forcecal.model.frf.scan_response`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..records import ScanFRF
from ..signals.checks import FRF_LIMITS
from ._uff_pairs import (
    Row,
    check_no_missing_points,
    record_values,
    scan_points,
    scan_quantity,
    vibration_quantity,
)
from ._uff_sets import PLUS_Z, length_factor, set_type
from ._uff_spectra import common_lines

__all__: list[str] = []

FRF = 4  # dataset 58 function type "frequency response function"
COHERENCE = 6  # dataset 58 function type "coherence"


def frfs_from_sets(sets: Sequence[dict], geometry: dict[int, tuple], path: str | Path,
                   locations: bool) -> ScanFRF:
    """The ScanFRF of a file's FRFs and coherences (see :func:`forcecal.io.uff.read_scan_uff`).

    Parameters
    ----------
    sets, geometry, path
        The file's datasets, its node coordinates and its path, as for
        :func:`._uff_spectra.spectra_from_sets`.
    locations : bool
        A 3-D body's scan: refused (a body's shapes are not built over a band).

    Returns
    -------
    ScanFRF
        ``values`` [m/s per A] or [m per A], ``coherence`` [1], ``frequencies`` [Hz].

    Raises
    ------
    InputError
        A body's scan, or no FRF of a vibration.
    DataError
        A node with no, or more than one, FRF or coherence; records that disagree in lines or
        quantity; a coherence outside 0-1; FRFs of real values; non-finite or implausible
        values (:data:`forcecal.signals.checks.FRF_LIMITS`).
    """
    if locations:
        raise InputError(f"scan '{path}': a body's scan is read from its time records or "
                         "spectra, not from FRFs (its shapes are not built over a band)")
    frfs = _by_node([s for s in sets if _is(s, FRF)])
    cohs = _by_node([s for s in sets if _is(s, COHERENCE)])
    # an export of every channel against the reference also holds the reference's coherence
    # with itself, 1 on every line: it is not the vibration's
    cohs = {n: [r for r in rs if not _all_one(r)] or rs for n, rs in cohs.items()}
    vibrations = {n: [r for r in rs if vibration_quantity(r)] for n, rs in frfs.items()}
    vibrations = {n: rs for n, rs in vibrations.items() if rs}
    if not vibrations:
        raise InputError(f"scan '{path}': none of its FRFs is of a vibration (velocity, "
                         "ordinate type 11, or displacement, 8)")
    for node in sorted(set(vibrations) | set(cohs)):
        for kind, by_node in (("FRF of a vibration", vibrations), ("coherence", cohs)):
            n = len(by_node.get(node, []))
            if n != 1:
                raise DataError(f"scan '{path}': node {node} has {n} {kind} records; "
                                "expected one FRF and its coherence per point")
        if node not in geometry:
            raise DataError(f"scan '{path}': node {node} has FRFs but no coordinates "
                            "(dataset 2411 or 15)")
    nodes = sorted(vibrations)
    check_no_missing_points(geometry, set(nodes), path, "FRFs", depth=2)
    rows: list[Row] = [(n, PLUS_Z, vibrations[n][0], cohs[n][0]) for n in nodes]
    frequencies = common_lines(rows, path, ("FRF", "coherence"))
    factor = length_factor(sets, path)
    values = np.array([record_values(v, n, "FRF", path, factor, True) for n, _, v, _ in rows])
    coherence = np.array([record_values(_real(c), n, "coherence", path, 1.0, False)
                          for n, _, _, c in rows])
    for (node, *_), coh in zip(rows, coherence, strict=True):
        if coh.min() < 0.0 or coh.max() > 1.0 + 1e-6:
            bad = coh.min() if coh.min() < 0.0 else coh.max()
            raise DataError(f"scan '{path}': node {node}: coherence reaches {bad:.4g} on a "
                            "line; a coherence lies within 0-1")
    quantity = scan_quantity(rows, path)
    limit, unit = FRF_LIMITS[quantity]
    peak = np.max(np.abs(values), axis=1)
    if peak.max() > limit:
        node = rows[int(np.argmax(peak))][0]
        raise DataError(f"scan '{path}': node {node}: FRF reaches {peak.max():.4g} {unit} on a "
                        f"line; a {quantity} FRF beyond {limit:g} {unit} is not plausible (a "
                        "wrong unit or a damaged file?)")
    if not peak.max() > 0:
        raise DataError(f"scan '{path}': every FRF is zero; no signal was recorded")
    return ScanFRF(points=scan_points(geometry, nodes), frequencies=frequencies, values=values,
                   coherence=coherence, quantity=quantity, source=str(path))


def _is(record: dict, function_type: int) -> bool:
    """A dataset 58 of that function type."""
    try:
        return set_type(record) == 58 and int(record.get("func_type", -1)) == function_type
    except (TypeError, ValueError):
        return False


def _real(record: dict) -> dict:
    """A coherence record written as complex numbers with no imaginary part, made real."""
    data = np.asarray(record.get("data", []))
    if np.iscomplexobj(data) and np.all(np.abs(np.imag(data)) <= 1e-12):
        return {**record, "data": np.real(data)}
    return record


def _all_one(record: dict) -> bool:
    """A coherence record that is 1 on every line (the reference's with itself)."""
    try:
        data = np.asarray(record.get("data"), dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(data.size) and bool(np.all(np.abs(data - 1.0) <= 1e-9))


def _by_node(records: list[dict]) -> dict[int, list[dict]]:
    """Records by response node."""
    out: dict[int, list[dict]] = {}
    for record in records:
        out.setdefault(int(record.get("rsp_node", 0)), []).append(record)
    return out
