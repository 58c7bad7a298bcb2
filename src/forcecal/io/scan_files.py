"""Scan files in any accepted form: Universal File, HDF5 or NPZ (INTERFACES.md section 2).

HDF5 and NPZ hold the same content under the same names: ``x`` (n_points,) or (n_points, 2)
[m], ``response`` (n_points, n_samples) [m/s] or [m], ``reference`` (n_points, n_samples) [A],
scalar ``fs`` [Hz] and the string ``quantity`` ("velocity" or "displacement"). A scan of a 3-D
body gives ``x`` as (n_records, 3) and ``direction`` (n_records, 3), the measuring direction of
every record (default +z); a point measured along three axes is three records.

A Universal File may instead hold the scan as spectra (dataset 58, function type 12), read as a
:class:`~forcecal.records.ScanSpectra`, or a broadband scan as FRFs (4) with their coherence
(6), read as a :class:`~forcecal.records.ScanFRF` (see :mod:`forcecal.io.uff`).
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TypedDict

import h5py
import numpy as np

from .._atomic import atomic_path
from ..errors import DataError, InputError
from ..records import Scan, ScanFRF, ScanSpectra
from ..signals.checks import check_scan_values
from .uff import read_scan_uff

__all__ = ["read_scan"]

SCAN_SUFFIXES = (".uff", ".unv", ".h5", ".hdf5", ".npz")
_KEYS = ("x", "response", "reference", "fs", "quantity")
_OPTIONAL = ("direction",)


def read_scan(path: str | Path, reference_label: str = "Ref", locations: bool = False
              ) -> Scan | ScanSpectra | ScanFRF:
    """Read a scan, choosing the reader from the file suffix.

    Parameters
    ----------
    path : str or Path
        ``.uff``/``.unv`` (Universal File), ``.h5``/``.hdf5`` or ``.npz``.
    reference_label : str
        For a Universal File: text in id line 2 of the reference records.
    locations : bool
        For a 3-D body: every record's point comes with its measuring direction, (n, 6).

    Returns
    -------
    Scan, ScanSpectra or ScanFRF
        The records in SI units, ``source`` = ``str(path)``; a ScanSpectra for a Universal File
        of spectra (function type 12), a ScanFRF for one of FRFs with their coherence (4, 6).

    Raises
    ------
    InputError
        An unknown suffix, a missing or unreadable file, or a missing or malformed array; a
        Universal File of FRFs without coherence, or of time records and spectra together.
    DataError
        Records that do not pair up or disagree (see :func:`forcecal.io.uff.read_scan_uff`).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    scan: Scan | ScanSpectra | ScanFRF | None = None
    if suffix in (".uff", ".unv"):
        scan = read_scan_uff(path, reference_label=reference_label, locations=locations)
    elif suffix in (".h5", ".hdf5"):
        scan = read_scan_hdf5(path, locations)
    elif suffix == ".npz":
        scan = read_scan_npz(path, locations)
    if isinstance(scan, Scan):  # spectra are checked as they are read
        check_scan_values(scan)
    if scan is not None:
        return scan
    raise InputError(
        f"scan '{path}': unknown file type '{path.suffix}'; accepted: {', '.join(SCAN_SUFFIXES)}"
    )


def read_scan_npz(path: str | Path, locations: bool = False) -> Scan:
    """Read a scan from an ``.npz`` archive (arrays named as in the module docstring).

    Parameters
    ----------
    path : str or Path
        The ``.npz`` archive.
    locations : bool
        For a 3-D body: ``x`` (n, 3) and ``direction`` give every record's point and measuring
        direction, (n, 6).

    Returns
    -------
    Scan
        The records, ``source`` = ``str(path)``.

    Raises
    ------
    InputError
        A missing or unreadable archive, or a missing or malformed array.
    """
    path = _existing(path)
    with open(path, "rb") as fh:  # closed whatever np.load makes of it
        try:
            loaded = np.load(fh, allow_pickle=False)
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise InputError(f"scan '{path}': not a readable NPZ archive ({_first_line(exc)})"
                             ) from exc
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise InputError(f"scan '{path}': a single array (.npy content), not an NPZ archive")
        try:
            with loaded:
                content = {key: loaded[key] for key in loaded.files if key in _KEYS + _OPTIONAL}
        except Exception as exc:  # zipfile and numpy raise assorted errors on damage
            raise InputError(f"scan '{path}': not a readable NPZ archive ({_first_line(exc)})"
                             ) from exc
    return _scan_from(content, path, locations)


def read_scan_hdf5(path: str | Path, locations: bool = False) -> Scan:
    """Read a scan from an HDF5 file (root datasets named as in the module docstring).

    Parameters
    ----------
    path : str or Path
        The ``.h5``/``.hdf5`` file.
    locations : bool
        For a 3-D body: ``x`` (n, 3) and ``direction`` give every record's point and measuring
        direction, (n, 6).

    Returns
    -------
    Scan
        The records, ``source`` = ``str(path)``.

    Raises
    ------
    InputError
        A missing or unreadable file, or a missing or malformed dataset.
    """
    path = _existing(path)
    try:
        with h5py.File(path, "r") as h5:
            content = {
                key: h5[key][()] for key in _KEYS + _OPTIONAL
                if key in h5 and isinstance(h5[key], h5py.Dataset)
            }
    except Exception as exc:  # h5py raises OSError, KeyError, RuntimeError... on damage
        raise InputError(f"scan '{path}': not a readable HDF5 file ({_first_line(exc)})") from exc
    return _scan_from(content, path, locations)


def write_scan_npz(scan: Scan, path: str | Path) -> Path:
    """Write a scan as an ``.npz`` archive, atomically.

    Parameters
    ----------
    scan : Scan
        The scan (a body's located records are written as ``x`` and ``direction``).
    path : str or Path
        The ``.npz`` archive, replaced atomically.

    Returns
    -------
    Path
        ``path``.
    """
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **_content_of(scan))
    return Path(path)


def write_scan_hdf5(scan: Scan, path: str | Path) -> Path:
    """Write a scan as an HDF5 file (one root dataset per key), atomically.

    Parameters
    ----------
    scan : Scan
        The scan (a body's located records are written as ``x`` and ``direction``).
    path : str or Path
        The ``.h5`` file, replaced atomically.

    Returns
    -------
    Path
        ``path``.
    """
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as h5:
        for key, value in _content_of(scan).items():
            h5.create_dataset(key, data=str(value) if isinstance(value, str) else value)
    return Path(path)


class _Direction(TypedDict, total=False):
    direction: np.ndarray


class _ScanContent(_Direction):
    """The named arrays of a scan file, in file order (see the module docstring)."""

    x: np.ndarray
    response: np.ndarray
    reference: np.ndarray
    fs: np.float64
    quantity: np.str_


def _content_of(scan: Scan) -> _ScanContent:
    """The arrays a scan file holds: a body's located points become ``x`` and ``direction``."""
    x = scan.points[:, 0] if scan.points.shape[1] == 1 else scan.points
    located = scan.points.shape[1] == 6
    direction: _Direction = {"direction": np.asarray(x[:, 3:], dtype=float)} if located else {}
    return {
        "x": np.asarray(x[:, :3] if located else x, dtype=float),
        **direction,
        "response": scan.response,
        "reference": scan.reference,
        "fs": np.float64(scan.fs),
        "quantity": np.str_(scan.quantity),
    }


def _existing(path: str | Path) -> Path:
    """``path`` as a Path; InputError when there is no such file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"scan '{path}': file does not exist")
    return path


def _scan_from(content: Mapping[str, np.ndarray], path: Path, locations: bool = False) -> Scan:
    """Build a Scan from the named arrays, naming the first missing or malformed one."""
    for key in _KEYS:
        if key not in content:
            raise InputError(f"scan '{path}': missing '{key}' (expected {', '.join(_KEYS)})")
    x = _float_array(content["x"], "x", path)
    top = 3 if locations else 2
    if x.ndim not in (1, 2) or (x.ndim == 2 and not 1 <= x.shape[1] <= top):
        raise InputError(f"scan '{path}': 'x' has shape {x.shape}; expected (n,) or (n, "
                         f"{'2 or 3' if locations else 2})" + ("" if locations else
                         " (a scan with z and directions is for a body rig)"))
    if locations:
        x = _located(x, content.get("direction"), path)
    fs = _float_array(content["fs"], "fs", path)
    if fs.size != 1 or not np.isfinite(fs.item()) or fs.item() <= 0:
        raise InputError(f"scan '{path}': 'fs' must be one positive number (Hz), found {fs}")
    response = _float_array(content["response"], "response", path)
    reference = _float_array(content["reference"], "reference", path)
    for key, arr in (("response", response), ("reference", reference)):
        if arr.ndim != 2 or arr.shape[0] != len(x) or arr.shape[1] < 2:
            raise DataError(f"scan '{path}': '{key}' has shape {arr.shape}; expected "
                            f"({len(x)}, n_samples), one record per point of 'x'")
    return Scan(
        points=x,
        response=response,
        reference=reference,
        fs=float(fs.item()),
        quantity=_text(content["quantity"], path),
        source=str(path),
    )


def _located(x: np.ndarray, direction: np.ndarray | None, path: Path) -> np.ndarray:
    """(n, 6) rows (x, y, z, dx, dy, dz): coordinates padded with zeros, unit directions."""
    xyz = np.zeros((len(x), 3))
    xyz[:, :(1 if x.ndim == 1 else x.shape[1])] = x.reshape(len(x), -1)
    if direction is None:
        d = np.tile([0.0, 0.0, 1.0], (len(x), 1))
    else:
        d = _float_array(direction, "direction", path)
        if d.shape != (len(x), 3):
            raise InputError(f"scan '{path}': 'direction' has shape {d.shape}; expected "
                             f"({len(x)}, 3), one unit vector per record")
        norm = np.linalg.norm(d, axis=1)
        if not np.all(np.isfinite(norm)) or np.any(norm == 0):
            k = int(np.argmin(np.isfinite(norm) & (norm > 0)))
            raise InputError(f"scan '{path}': 'direction' of record {k + 1} is zero or not "
                             "finite")
        d = d / norm[:, None]
    return np.column_stack([xyz, d])


def _float_array(value: np.ndarray, key: str, path: Path) -> np.ndarray:
    """The named array as floats; InputError naming the key when it is not numeric."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"scan '{path}': '{key}' is not numeric") from exc


def _text(value: object, path: Path) -> str:
    """The ``quantity`` string, stripped; InputError when it is not a string."""
    item = np.asarray(value).item() if np.asarray(value).size == 1 else value
    if isinstance(item, bytes):
        item = item.decode("utf-8", errors="replace")
    if not isinstance(item, str):
        raise InputError(f"scan '{path}': 'quantity' must be a string, found {item!r}")
    return item.strip()


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when it has none)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
