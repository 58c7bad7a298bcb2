"""Where a result comes from: forcecal's version, when, the command line, and the SHA-256 of
every input file, written into every JSON document and report forcecal produces, so that a
result can be traced to its data and a certificate names exactly what it certifies."""

from __future__ import annotations

import hashlib
import shlex
import sys
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

from ._version import __version__

__all__ = ["file_digest", "provenance"]

_CHUNK = 1 << 20


def file_digest(path: str | Path) -> str:
    """The SHA-256 of a file's bytes (read in 1 MiB chunks), hexadecimal.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    str
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


def provenance(inputs: Sequence[str | Path], argv: Sequence[str] | None = None) -> dict:
    """The provenance of a result.

    Parameters
    ----------
    inputs : sequence of str or Path
        The input files (those that do not exist as files, a MODEL.json's scans moved away
        for instance, are listed without a digest).
    argv : sequence of str, optional
        The command line (default: this process's).

    Returns
    -------
    dict
        ``forcecal_version``, ``created_utc`` (ISO 8601, seconds), ``command`` (the command
        line, shell-quoted), ``python``, and ``inputs``: ``[{"path", "bytes", "sha256"}]``.
    """
    args = list(sys.argv if argv is None else argv)
    if args:
        args[0] = Path(args[0]).name
    files = []
    for p in inputs:
        path = Path(p)
        entry: dict[str, str | int] = {"path": str(path)}
        if path.is_file():
            entry.update(bytes=path.stat().st_size, sha256=file_digest(path))
        files.append(entry)
    return {
        "forcecal_version": __version__,
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": " ".join(shlex.quote(a) for a in args),
        "python": sys.version.split()[0],
        "inputs": files,
    }
