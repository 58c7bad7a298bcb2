"""Typed access to a parsed TOML table, with messages that name the file and the key."""

from __future__ import annotations

import math
from typing import Any

from .errors import RigError

__all__ = ["KEY_LIMITS", "MAX_DEPTH", "MAX_NUMBER", "TableReader", "check_numbers"]

MAX_NUMBER = 1e12
"""Largest magnitude of any number in a rig file: no key of a laboratory rig comes near it."""

MAX_DEPTH = 32
"""Deepest nesting of tables and arrays in a rig file (a rig needs four levels)."""

KEY_LIMITS: dict[str, tuple[float, float, str]] = {
    # key: (smallest positive value, largest magnitude, unit)
    "x": (0.0, 1e4, "m"), "y": (0.0, 1e4, "m"), "z": (0.0, 1e4, "m"),
    "length": (1e-6, 1e4, "m"),
    "mass_per_length": (1e-9, 1e6, "kg/m"),       # a hair to a 1.5 m solid steel bar
    "mass_per_area": (1e-9, 1e6, "kg/m^2"),
    "density": (1e-6, 1e6, "kg/m^3"),             # osmium is 22,600 kg/m^3
    "mass": (1e-12, 1e7, "kg"),
    "gap": (1e-7, 0.1, "m"),                     # an air gap: 0.1 um to 10 cm
    "scale": (0.0, 1e9, "per raw unit"),
    "current_scale": (0.0, 1e9, "A per raw unit"),
    "flux_scale": (0.0, 1e9, "Wb per raw unit"),
    "frequency": (1e-3, 1e6, "Hz"),
    "turns": (1.0, 1e7, ""),
    "pole_area": (1e-10, 10.0, "m^2"),
}
"""Physical bounds of the rig's numbers, by key: a value beyond is a unit mistake (mm for m)
or a damaged file. The smallest positive value applies to keys that must be positive."""


def check_numbers(doc: object, source: str, path: str = "", depth: int = 0) -> None:
    """Refuse a rig document nested deeper than :data:`MAX_DEPTH` or holding a number beyond
    :data:`MAX_NUMBER` (a 5000-digit integer, 1e300), naming the key.

    Raises
    ------
    RigError
    """
    if depth > MAX_DEPTH:
        raise RigError(f"rig '{source}': key '{path}' is nested more than {MAX_DEPTH} levels deep")
    if isinstance(doc, dict):
        for k, v in doc.items():
            check_numbers(v, source, f"{path}.{k}" if path else str(k), depth + 1)
    elif isinstance(doc, list):
        for k, v in enumerate(doc):
            check_numbers(v, source, f"{path}[{k}]", depth + 1)
    elif isinstance(doc, int | float) and not isinstance(doc, bool):
        big = (abs(doc) > MAX_NUMBER) if isinstance(doc, float) else (
            doc.bit_length() > 60 or abs(doc) > MAX_NUMBER)
        if big:
            shown = (repr(doc) if isinstance(doc, float)
                     else f"an integer of {doc.bit_length()} bits")
            raise RigError(f"rig '{source}': key '{path}' is {shown}; no number of a rig "
                           f"exceeds {MAX_NUMBER:g} in magnitude")


class TableReader:
    """Reads keys of a rig file's tables; every failure is a :class:`RigError` that names the
    file and the dotted key.

    Parameters
    ----------
    source : str
        The file's name, quoted in every message.
    """

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, what: str) -> RigError:
        """The error for ``key``: ``rig 'FILE': key 'KEY' WHAT``."""
        return RigError(f"rig '{self.source}': key '{key}' {what}")

    def number(self, table: dict[str, Any], key: str, path: str, *, required: bool = True,
               positive: bool = False, default: float | None = None) -> float | None:
        """A finite number (optionally positive); ``default`` when absent and not required."""
        full = f"{path}.{key}" if path else key
        if key not in table:
            if required:
                raise self.fail(full, "is missing")
            return default
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(full, f"must be a number, found {value!r}")
        try:
            value = float(value)
        except OverflowError:
            raise self.fail(full, "is too large a number") from None
        if not math.isfinite(value):
            raise self.fail(full, f"must be finite, found {value!r}")
        if positive and value <= 0:
            raise self.fail(full, f"must be positive, found {value!r}")
        lo, hi, unit = KEY_LIMITS.get(key, (0.0, MAX_NUMBER, ""))
        unit = f" {unit}" if unit else ""
        if abs(value) > hi:
            raise self.fail(full, f"= {value!r}{unit} is implausibly large (at most {hi:g}{unit}; "
                            "a unit mistake?)")
        if positive and value < lo:
            raise self.fail(full, f"= {value!r}{unit} is implausibly small (at least {lo:g}{unit}; "
                            "a unit mistake?)")
        return value

    def required(self, table: dict[str, Any], key: str, path: str, *,
                 positive: bool = False) -> float:
        """A number that must be present (see :meth:`number`)."""
        value = self.number(table, key, path, positive=positive)
        assert value is not None                      # required: number() raised otherwise
        return value

    def text(self, table: dict[str, Any], key: str, path: str, *, required: bool = True,
             default: str | None = None) -> str | None:
        """A non-empty string; ``default`` when absent and not required."""
        full = f"{path}.{key}" if path else key
        if key not in table:
            if required:
                raise self.fail(full, "is missing")
            return default
        value = table[key]
        if not isinstance(value, str) or not value.strip():
            raise self.fail(full, f"must be a non-empty string, found {value!r}")
        return value

    def table(self, doc: dict[str, Any], key: str, *, required: bool = True) -> dict[str, Any]:
        """A sub-table (``{}`` when absent and not required)."""
        if key not in doc:
            if required:
                raise self.fail(key, "is missing (a [" + key + "] table)")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, "must be a table")
        return value

    def array_of_tables(self, doc: dict[str, Any], key: str) -> list[dict[str, Any]]:
        """A non-missing array of tables ``[[key]]``."""
        if key not in doc:
            raise self.fail(key, f"is missing (at least one [[{key}]] table)")
        value = doc[key]
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, f"must be an array of tables [[{key}]]")
        return value

    def vector(self, table: dict[str, Any], key: str, path: str, length: int, what: str,
               *, quote: bool = True) -> tuple[float, ...]:
        """A list of ``length`` finite numbers, e.g. a corner [x, y, z]; the message says it
        ``must be WHAT`` (and quotes what was found unless ``quote`` is false)."""
        v = table.get(key)
        if (not isinstance(v, list) or len(v) != length
                or not all(isinstance(c, int | float) and not isinstance(c, bool)
                           and abs(c) <= MAX_NUMBER and math.isfinite(c) for c in v)):
            found = f"; found {v!r}" if quote else ""
            raise self.fail(f"{path}.{key}", f"must be {what}{found}")
        return tuple(float(c) for c in v)
