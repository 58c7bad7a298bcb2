"""Scan files in any accepted form: Universal File, HDF5 or NPZ (INTERFACES.md section 2).

HDF5 and NPZ hold the same content under the same names: ``x`` (n_points,) or (n_points, 2)
[m], ``response`` (n_points, n_samples) [m/s] or [m], ``reference`` (n_points, n_samples) [A],
scalar ``fs`` [Hz] and the string ``quantity`` ("velocity" or "displacement").
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from ..errors import InputError
from ..records import Scan
from .atomic import atomic_path
from .uff import read_scan_uff

__all__ = ["SCAN_SUFFIXES", "read_scan", "write_scan_hdf5", "write_scan_npz"]

SCAN_SUFFIXES = (".uff", ".unv", ".h5", ".hdf5", ".npz")
_KEYS = ("x", "response", "reference", "fs", "quantity")


def read_scan(path: str | Path, reference_label: str = "Ref") -> Scan:
    """Read a scan, choosing the reader from the file suffix.

    Parameters
    ----------
    path : str or Path
        ``.uff``/``.unv`` (Universal File), ``.h5``/``.hdf5`` or ``.npz``.
    reference_label : str
        For a Universal File: text in id line 2 of the reference records.

    Returns
    -------
    Scan
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in (".uff", ".unv"):
        return read_scan_uff(path, reference_label=reference_label)
    if suffix in (".h5", ".hdf5"):
        return read_scan_hdf5(path)
    if suffix == ".npz":
        return read_scan_npz(path)
    raise InputError(
        f"scan '{path}': unknown file type '{path.suffix}'; accepted: {', '.join(SCAN_SUFFIXES)}"
    )


def read_scan_npz(path: str | Path) -> Scan:
    """Read a scan from an ``.npz`` archive (arrays named as in the module docstring)."""
    path = _existing(path)
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"scan '{path}': not a readable NPZ archive ({_first_line(exc)})") from exc
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise InputError(f"scan '{path}': a single array (.npy content), not an NPZ archive")
    try:
        with loaded:
            content = {key: loaded[key] for key in loaded.files if key in _KEYS}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"scan '{path}': not a readable NPZ archive ({_first_line(exc)})") from exc
    return _scan_from(content, path)


def read_scan_hdf5(path: str | Path) -> Scan:
    """Read a scan from an HDF5 file (root datasets named as in the module docstring)."""
    path = _existing(path)
    try:
        with h5py.File(path, "r") as h5:
            content = {
                key: h5[key][()] for key in _KEYS if key in h5 and isinstance(h5[key], h5py.Dataset)
            }
    except OSError as exc:
        raise InputError(f"scan '{path}': not a readable HDF5 file ({_first_line(exc)})") from exc
    return _scan_from(content, path)


def write_scan_npz(scan: Scan, path: str | Path) -> Path:
    """Write a scan as an ``.npz`` archive, atomically; returns the path."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **_content_of(scan))
    return Path(path)


def write_scan_hdf5(scan: Scan, path: str | Path) -> Path:
    """Write a scan as an HDF5 file (one root dataset per key), atomically; returns the path."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as h5:
        for key, value in _content_of(scan).items():
            h5.create_dataset(key, data=str(value) if isinstance(value, str) else value)
    return Path(path)


def _content_of(scan: Scan) -> dict[str, np.ndarray]:
    x = scan.points[:, 0] if scan.points.shape[1] == 1 else scan.points
    return {
        "x": np.asarray(x, dtype=float),
        "response": scan.response,
        "reference": scan.reference,
        "fs": np.float64(scan.fs),
        "quantity": np.str_(scan.quantity),
    }


def _existing(path: str | Path) -> Path:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"scan '{path}': file does not exist")
    return path


def _scan_from(content: Mapping[str, np.ndarray], path: Path) -> Scan:
    """Build a Scan from the named arrays, naming the first missing or malformed one."""
    for key in _KEYS:
        if key not in content:
            raise InputError(f"scan '{path}': missing '{key}' (expected {', '.join(_KEYS)})")
    x = _float_array(content["x"], "x", path)
    if x.ndim not in (1, 2) or (x.ndim == 2 and x.shape[1] not in (1, 2)):
        raise InputError(f"scan '{path}': 'x' has shape {x.shape}; expected (n,) or (n, 2)")
    fs = _float_array(content["fs"], "fs", path)
    if fs.size != 1 or not np.isfinite(fs.item()) or fs.item() <= 0:
        raise InputError(f"scan '{path}': 'fs' must be one positive number (Hz), found {fs}")
    return Scan(
        points=x,
        response=_float_array(content["response"], "response", path),
        reference=_float_array(content["reference"], "reference", path),
        fs=float(fs.item()),
        quantity=_text(content["quantity"], path),
        source=str(path),
    )


def _float_array(value: np.ndarray, key: str, path: Path) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"scan '{path}': '{key}' is not numeric") from exc


def _text(value: object, path: Path) -> str:
    item = np.asarray(value).item() if np.asarray(value).size == 1 else value
    if isinstance(item, bytes):
        item = item.decode("utf-8", errors="replace")
    if not isinstance(item, str):
        raise InputError(f"scan '{path}': 'quantity' must be a string, found {item!r}")
    return item.strip()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
