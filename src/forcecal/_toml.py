"""Typed access to a parsed TOML table, with messages that name the file and the key."""

from __future__ import annotations

import math
from typing import Any

from .errors import RigError

__all__ = ["TableReader"]


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
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(full, f"must be finite, found {value!r}")
        if positive and value <= 0:
            raise self.fail(full, f"must be positive, found {value!r}")
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
                           and math.isfinite(c) for c in v)):
            found = f"; found {v!r}" if quote else ""
            raise self.fail(f"{path}.{key}", f"must be {what}{found}")
        return tuple(float(c) for c in v)
