"""Universal Files written for tests: datasets through pyuff, and the function type of records
pyuff will not write (a spectrum, 12) set afterwards."""

from __future__ import annotations

import gc
import warnings
from pathlib import Path

import pyuff


def write_uff(path: Path, sets: list[dict]) -> Path:
    """The datasets ``sets`` (prepared by pyuff) written to ``path``, replacing it."""
    with warnings.catch_warnings():  # pyuff may leave a reopened handle to the collector
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
        gc.collect()
    return path


def retype(path: Path, func_type: int) -> Path:
    """Set the function type (record 6, field 1) of every ASCII dataset 58 of a file: pyuff
    writes no spectrum (12), so spectra are written as FRFs (4) and retyped."""
    lines = path.read_text(encoding="ascii").split("\n")
    for k, line in enumerate(lines[:-1]):
        if line.strip() == "-1" and lines[k + 1].strip() == "58":
            lines[k + 7] = f"{func_type:5d}" + lines[k + 7][5:]
    path.write_text("\n".join(lines), encoding="ascii")
    return path
