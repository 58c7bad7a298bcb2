"""Reading an SLDV scan from a Universal File: the records' kind decided (time records, spectra
read by :mod:`._uff_spectra`, or FRFs with their coherence read by :mod:`._uff_frf`; FRFs
without coherence refused), time records paired by node, sampling and values checked (see
:mod:`forcecal.io.uff` for the layout).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..records import FRF_PHASE, Scan, ScanFRF, ScanSpectra
from ._uff_frf import COHERENCE, FRF, frfs_from_sets
from ._uff_pairs import Row, record_values, scan_quantity, scan_rows, split_records
from ._uff_sets import (
    RATE_DIGITS,
    SPECTRUM,
    TIME_RESPONSE,
    geometry_of,
    length_factor,
    read_sets,
    set_type,
    type_list,
)
from ._uff_spectra import spectra_from_sets

__all__: list[str] = []

_KINDS = {2: "auto spectra", 3: "cross spectra", 4: "frequency response functions",
          5: "transmissibilities", 6: "coherences", 9: "power spectral densities",
          10: "energy spectral densities"}
"""Names of the dataset-58 function types a scan cannot be read from, for messages."""
_RELATIVE_PHASE = (3, 4, 5)
"""Function types whose phase at a line is relative to the reference at that same line."""


def read_scan_uff(path: str | Path, reference_label: str = "Ref",
                  locations: bool = False) -> Scan | ScanSpectra | ScanFRF:
    """Read an SLDV scan from a Universal File (ASCII or binary).

    The scan records are dataset-58 time records (function type 1), or the complex spectra
    (function type 12) of a frequency-domain export of the same content, read by
    :func:`forcecal.io._uff_spectra.spectra_from_sets`, or a broadband scan's FRFs (4) with
    their coherence (6), read by :func:`forcecal.io._uff_frf.frfs_from_sets` (a steady drive's
    model refuses them). A file holding time records and spectra is refused, and so is a file
    of FRFs without coherence, cross spectra or auto spectra: their phases are relative to the
    reference at each line (or absent), so the harmonics' phases relative to the drive's
    fundamental cannot be recovered from them, and an FRF alone states no noise.

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
    Scan, ScanSpectra or ScanFRF
        A Scan from time records: ``points`` (n_points, n_dim) [m] ordered by node number,
        n_dim = 2 when any y coordinate is non-zero, else 1 (z, the measuring direction, is not
        a scan coordinate); with ``locations``, (n_records, 6) ordered by node then direction;
        ``response`` (n_points, n_samples) [m/s] or [m]; ``reference`` (n_points, n_samples)
        [A]; ``fs`` [Hz] = 1 / abscissa increment. A ScanSpectra from spectra, a ScanFRF from
        FRFs and coherences, with the same points.

    Raises
    ------
    InputError
        The file is missing, is not a Universal File, or lacks node coordinates, time records
        (or spectra) or reference records; it holds FRFs without coherence, or time records
        and spectra.
    DataError
        A scan point lacks one of its two records, or the records disagree in length,
        sampling or quantity.
    """
    sets = read_sets(path, "scan")
    geometry = geometry_of(sets, path, "scan")
    function_type = _record_kind(sets, path)
    if function_type == SPECTRUM:
        return spectra_from_sets(sets, geometry, path, reference_label, locations)
    if function_type == FRF:
        return frfs_from_sets(sets, geometry, path, locations)
    return _time_scan(sets, geometry, path, reference_label, locations)


def _time_scan(sets: Sequence[dict], geometry: dict[int, tuple], path: str | Path, label: str,
               locations: bool) -> Scan:
    """The Scan of a file's time records (see :func:`read_scan_uff`)."""
    times = [s for s in sets if set_type(s) == 58 and s.get("func_type") == TIME_RESPONSE]
    rows, points = scan_rows(split_records(times, path, label), geometry, path, label,
                             locations, "time records")
    factor = length_factor(sets, path)
    quantity = scan_quantity(rows, path)
    step, n_samples = _common_sampling(rows, path)
    response = np.array([record_values(v, n, "time record", path, factor, False)
                         for n, _, v, _ in rows])
    reference = np.array([record_values(r, n, "time record", path, 1.0, False)
                          for n, _, _, r in rows])
    return Scan(
        points=points,
        response=response.reshape(len(rows), n_samples),
        reference=reference.reshape(len(rows), n_samples),
        fs=_rate_from_increment(step),
        quantity=quantity,
        source=str(path),
    )


def _record_kind(sets: Sequence[dict], path: str | Path) -> int:
    """The function type the scan is read from: TIME_RESPONSE, SPECTRUM or FRF (with
    coherences).

    Raises InputError, in one line, for a file without dataset 58, with both time records and
    spectra, or with none of the three (saying why FRFs alone, cross and auto spectra cannot
    serve).
    """
    records = [s for s in sets if set_type(s) == 58]
    if not records:
        raise InputError(
            f"scan '{path}': no time records (dataset 58); found datasets {type_list(sets)}"
        )
    types = Counter(_function_type(r) for r in records)
    if types[TIME_RESPONSE] and types[SPECTRUM]:
        raise InputError(
            f"scan '{path}': holds {types[TIME_RESPONSE]} time records (function type 1) and "
            f"{types[SPECTRUM]} spectra (function type 12); a scan is read from one kind: "
            "export the time records or the spectra, not both, into one file")
    if types[TIME_RESPONSE]:
        return TIME_RESPONSE
    if types[SPECTRUM]:
        return SPECTRUM
    if types[FRF] and types[COHERENCE]:
        return FRF
    found = ", ".join(f"{n} {_KINDS.get(t, 'records')} (function type {t})"
                      for t, n in sorted(types.items()))
    text = (f"scan '{path}': none of the {len(records)} dataset-58 records is a time record "
            f"(function type 1) or a spectrum (function type 12); found {found}")
    export = ("export the time records or the complex spectra of the response and of the "
              "reference")
    if any(t in _RELATIVE_PHASE for t in types):
        raise InputError(
            f"{text}, {FRF_PHASE}; {export} (a broadband scan may also be read from its FRFs "
            "with their coherence, function type 6, which states their noise)")
    if any(t in _KINDS for t in types):
        raise InputError(f"{text}, which hold no phase; {export}")
    raise InputError(f"{text}; {export}")


def _function_type(record: dict) -> int:
    """A dataset 58's function type (-1 when pyuff gave none)."""
    try:
        return int(record.get("func_type", -1))
    except (TypeError, ValueError):
        return -1


def _common_sampling(rows: list[Row], path: str | Path) -> tuple[float, int]:
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
