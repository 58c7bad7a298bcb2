"""Typed access to a parsed TOML table, with messages that name the file and the key."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

from .errors import RigError

__all__ = ["TableReader", "channel_map", "check_numbers", "node_channel"]

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


# --------------------------------------------------------------------------------------------
# the channel map ([channels])

_AXES = ("X", "Y", "Z", "RX", "RY", "RZ")
_NODE_TEXT = re.compile(r"node\s*(\d+)(?:\s+([+-]?)\s*(R?[XYZ]))?", re.IGNORECASE)
_CHANNEL_FORMS = ('a channel name of the run files ("cDAQ1Mod1/ai0"), "node 12 +Z" or '
                  '{ node = 12, direction = "+Z" }')


def node_channel(node: int, direction: int = 0) -> str:
    """The name of a UFF record by its response node and direction: ``"node 12 +Z"``.

    Parameters
    ----------
    node : int
        The response node.
    direction : int
        The UFF direction code: 1 to 6 = +X, +Y, +Z, +RX, +RY, +RZ, negative for the opposite
        sense; 0 (scalar, or not given) gives ``"node 12"``.

    Returns
    -------
    str
    """
    if not direction or abs(direction) > len(_AXES):
        return f"node {node}"
    return f"node {node} {'+' if direction > 0 else '-'}{_AXES[abs(direction) - 1]}"


def parse_node_channel(text: str) -> tuple[int, int] | None:
    """``(node, direction code)`` of a text ``"node 12 +Z"`` (any case; ``Z`` means ``+Z``;
    direction 0 when not given), or None when ``text`` is not of that form."""
    match = _NODE_TEXT.fullmatch(text.strip())
    if match is None:
        return None
    node, sign, axis = match.groups()
    code = _AXES.index(axis.upper()) + 1 if axis else 0
    return int(node), -code if sign == "-" else code


def _channel_ref(r: TableReader, value: object, key: str) -> str:
    """One ``[channels]`` value as a channel name of the run files (a node made canonical)."""
    if isinstance(value, dict):
        node, direction = value.get("node"), value.get("direction", 0)
        extra = sorted(set(value) - {"node", "direction"})
        if extra:
            raise r.fail(f"{key}.{extra[0]}", "is not a key of a node channel (node, direction)")
        if isinstance(node, bool) or not isinstance(node, int) or node < 0:
            raise r.fail(f"{key}.node", f"must be a node number (a whole number >= 0), found "
                         f"{node!r}")
        if isinstance(direction, str):
            parsed = parse_node_channel(f"node {node} {direction}")
            direction = parsed[1] if parsed else None
        if isinstance(direction, bool) or not isinstance(direction, int) \
                or abs(direction) > len(_AXES):
            raise r.fail(f"{key}.direction", "must be one of +X, +Y, +Z, +RX, +RY, +RZ or their "
                         "negatives (or the UFF code, 1 to 6, negative for minus), found "
                         f"{value.get('direction')!r}")
        return node_channel(node, direction)
    if not isinstance(value, str) or not value.strip():
        raise r.fail(key, f"must be {_CHANNEL_FORMS}; found {value!r}")
    parsed = parse_node_channel(value)
    if parsed is not None:
        return node_channel(*parsed)
    if re.match(r"(?i)node\s*\d", value.strip()):
        raise r.fail(key, f"= {value!r} is not 'node N' followed by a direction such as +Z")
    return value.strip()


def channel_map(r: TableReader, table: dict[str, Any],
                names: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """The ``[channels]`` table: (rig channel, channel of the run files) pairs.

    Parameters
    ----------
    r : TableReader
        The rig file's reader, for the messages.
    table : dict
        The parsed ``[channels]`` table (empty when the rig has none).
    names : sequence of str
        The rig's channels (gauges, sensors, ``actuator.current``, ``actuator.flux``) and
        ``time``, the run files' time column.

    Returns
    -------
    tuple of (str, str)
        In the table's order; a node given as text or as an inline table is written
        ``"node 12 +Z"`` (see :func:`node_channel`).

    Raises
    ------
    RigError
        A key that is not a channel of the rig, a value of another form, or two keys naming
        one channel of the files.
    """
    pairs: list[tuple[str, str]] = []
    taken: dict[str, str] = {}
    for name, value in table.items():
        key = f"channels.{name}"
        if name not in names:
            raise r.fail(key, f"is not a channel of the rig; expected one of {', '.join(names)} "
                         "(the gauges, sensors, actuator.current, actuator.flux and the "
                         "run files' time column)")
        ref = _channel_ref(r, value, key)
        if ref in taken:
            raise r.fail(key, f"= {ref!r} is also the channel of '{taken[ref]}'")
        taken[ref] = key
        pairs.append((name, ref))
    return tuple(pairs)
