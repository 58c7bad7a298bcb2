"""Reading an SLDV scan exported as spectra: per point the complex spectrum (dataset 58, function
type 12) of the vibration and of the reference, paired by node as time records are
(:mod:`._uff_pairs`), over one common set of evenly spaced lines in Hz.

The amplitude convention is not a field of dataset 58. It is taken as "rms" when the vibration
records' id lines or ordinate labels say ``RMS`` (as a word: ``m/s RMS``, ``Vib  Velocity RMS``)
and as "peak" otherwise; every vibration record must agree. The reference spectra are taken in
the same convention: their scale cancels in the phase referencing and in the normalization to
the mean drive (only the reported drive amplitude in A depends on it).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..records import ScanSpectra
from ..signals.checks import SCAN_FLOORS, SCAN_LIMITS
from ._uff_pairs import Row, record_values, scan_quantity, scan_rows, split_records
from ._uff_sets import SPECTRUM, TIME_ABSCISSA, length_factor, set_type

__all__: list[str] = []

_LABELS = ("id1", "id2", "id3", "id4", "id5", "ordinate_axis_lab", "ordinate_axis_units_lab")
"""The text fields of a record searched for its amplitude convention."""
_RMS = re.compile(r"(?<![a-z])rms(?![a-z])", re.IGNORECASE)


def spectra_from_sets(sets: Sequence[dict], geometry: dict[int, tuple], path: str | Path,
                      label: str, locations: bool) -> ScanSpectra:
    """The ScanSpectra of a file's spectra (see :func:`forcecal.io.uff.read_scan_uff`).

    Parameters
    ----------
    sets : sequence of dict
        Every dataset of the file, as pyuff reads them.
    geometry : dict
        node -> (x, y, z) [m].
    path : str or Path
        The file, for messages and ``source``.
    label : str
        Text in id line 2 of every reference spectrum.
    locations : bool
        A 3-D body's rows, as for time records.

    Returns
    -------
    ScanSpectra
        ``response`` [m/s] or [m] and ``reference`` [A] per line, in the file's amplitude
        convention; ``frequencies`` [Hz].

    Raises
    ------
    InputError
        No reference or no vibration spectra.
    DataError
        Spectra that do not pair up, or disagree in lines, quantity or amplitude convention;
        real (magnitude) values; non-finite or implausible values; lines over time or below
        0 Hz.
    """
    spectra = [s for s in sets if set_type(s) == 58 and s.get("func_type") == SPECTRUM]
    rows, points = scan_rows(split_records(spectra, path, label), geometry, path, label,
                             locations, "spectra")
    factor = length_factor(sets, path)
    quantity = scan_quantity(rows, path)
    frequencies = common_lines(rows, path)
    response = np.array([record_values(v, n, "vibration spectrum", path, factor, True)
                         for n, _, v, _ in rows])
    reference = np.array([record_values(r, n, "reference spectrum", path, 1.0, True)
                          for n, _, _, r in rows])
    scan = ScanSpectra(points=points, frequencies=frequencies, response=response,
                       reference=reference, quantity=quantity,
                       amplitude=_amplitude_convention(rows, path), source=str(path))
    _check_plausible(scan)
    return scan


def common_lines(rows: list[Row], path: str | Path,
                 kinds: tuple[str, str] = ("vibration spectrum", "reference spectrum")
                 ) -> np.ndarray:
    """(n_lines,) [Hz] the lines shared by both records of every row (named ``kinds`` in
    messages)."""
    node0, _, first, _ = rows[0]
    start0, step0 = _lines_of(first, node0, kinds[0], path)
    n0 = np.atleast_1d(first.get("data", [])).size
    for node, _, vibration, reference in rows:
        for kind, record in zip(kinds, (vibration, reference), strict=True):
            n = np.atleast_1d(record.get("data", [])).size
            if n != n0:
                raise DataError(f"scan '{path}': node {node}: {kind} has {n} lines, expected "
                                f"{n0} (as node {node0})")
            start, step = _lines_of(record, node, kind, path)
            if abs(step - step0) > 1e-6 * step0 or abs(start - start0) > 1e-6 * step0:
                raise DataError(f"scan '{path}': node {node}: {kind} has lines from {start:.6g} "
                                f"Hz every {step:.6g} Hz, expected from {start0:.6g} Hz every "
                                f"{step0:.6g} Hz (as node {node0})")
    if n0 < 2:
        raise DataError(f"scan '{path}': the records hold {n0} lines; at least 2 needed")
    return start0 + step0 * np.arange(n0)


def _lines_of(record: dict, node: int, kind: str, path: str | Path) -> tuple[float, float]:
    """First line and line spacing [Hz] of one spectrum."""
    where = f"scan '{path}': node {node}: {kind}"
    if record.get("abscissa_spec_data_type") == TIME_ABSCISSA:
        raise DataError(f"{where} is given over time (abscissa data type 17); its abscissa "
                        "must be frequency in Hz")
    if record.get("abscissa_spacing", 1) == 1:
        start = float(record.get("abscissa_min", 0.0))
        step = float(record.get("abscissa_inc", 0.0))
    else:
        x = np.asarray(record.get("x", []), dtype=float)
        diffs = np.diff(x)
        start = float(x[0]) if x.size else 0.0
        step = float(np.mean(diffs)) if diffs.size else 0.0
        if diffs.size and np.max(np.abs(diffs - step)) > 1e-6 * abs(step):
            raise DataError(f"{where}: lines are not evenly spaced")
    if not (np.isfinite(step) and step > 0):
        raise DataError(f"{where}: line spacing {step} Hz is not positive")
    if not (np.isfinite(start) and start >= -1e-6 * step):
        raise DataError(f"{where}: first line at {start:.6g} Hz; expected a one-sided "
                        "spectrum (lines from 0 Hz up)")
    return max(start, 0.0), step


def _amplitude_convention(rows: list[Row], path: str | Path) -> str:
    """'rms' when the vibration spectra are labelled RMS, else 'peak' (see the module)."""
    labelled = {node: bool(_RMS.search(" ".join(str(vib.get(k, "")) for k in _LABELS)))
                for node, _, vib, _ in rows}
    if len(set(labelled.values())) > 1:
        rms = next(n for n, v in labelled.items() if v)
        other = next(n for n, v in labelled.items() if not v)
        raise DataError(f"scan '{path}': the vibration spectrum of node {rms} is labelled RMS "
                        f"but that of node {other} is not; a scan holds one amplitude "
                        "convention")
    return "rms" if any(labelled.values()) else "peak"


def _check_plausible(scan: ScanSpectra) -> None:
    """DataError when a spectrum's lines exceed a plausible amplitude or none holds a signal
    (the limits of :data:`forcecal.signals.checks.SCAN_LIMITS` and ``SCAN_FLOORS``)."""
    where = f"scan '{scan.source}'"
    scale = np.sqrt(2.0) if scan.amplitude == "rms" else 1.0
    for key, lines in (("response", scan.response), ("reference", scan.reference)):
        kind = "reference" if key == "reference" else scan.quantity
        limit, unit = SCAN_LIMITS[kind]
        peak = scale * np.max(np.abs(lines), axis=1)
        k = int(np.argmax(peak))
        if peak[k] > limit:
            raise DataError(f"{where}: {key} spectrum of point {k + 1} (x = "
                            f"{scan.points[k, 0]:.4g} m) reaches {peak[k]:.4g} {unit} on a line; "
                            f"a {kind} beyond {limit:g} {unit} is not plausible (a wrong unit or "
                            "a damaged file?)")
        if not peak.max() > SCAN_FLOORS[key]:
            raise DataError(f"{where}: every {key} spectrum stays within {peak.max():.3g} (at "
                            f"most {SCAN_FLOORS[key]:g} in SI units); no signal was recorded (a "
                            "wrong unit?)")
