"""The rig file's ``[channels]`` table: the run files' names of the rig's channels, and the
``"node 12 +Z"`` names of UFF records."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

from .keys import nearest_key

__all__ = ["channel_map", "node_channel"]

Fail = Callable[[str, str], Exception]
"""``fail(key, what)``: the error naming the file and ``key``."""

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


def _channel_ref(fail: Fail, value: object, key: str) -> str:
    """One ``[channels]`` value as a channel name of the run files (a node made canonical)."""
    if isinstance(value, dict):
        node, direction = value.get("node"), value.get("direction", 0)
        extra = sorted(set(value) - {"node", "direction"})
        if extra:
            near = nearest_key(extra[0], ["node", "direction"])
            raise fail(f"{key}.{extra[0]}", "is not a key of a node channel" + (
                f"; did you mean '{near}'?" if near else " (node, direction)"))
        if isinstance(node, bool) or not isinstance(node, int) or node < 0:
            raise fail(f"{key}.node", f"must be a node number (a whole number >= 0), found "
                         f"{node!r}")
        if isinstance(direction, str):
            parsed = parse_node_channel(f"node {node} {direction}")
            direction = parsed[1] if parsed else None
        if isinstance(direction, bool) or not isinstance(direction, int) \
                or abs(direction) > len(_AXES):
            raise fail(f"{key}.direction", "must be one of +X, +Y, +Z, +RX, +RY, +RZ or their "
                         "negatives (or the UFF code, 1 to 6, negative for minus), found "
                         f"{value.get('direction')!r}")
        return node_channel(node, direction)
    if not isinstance(value, str) or not value.strip():
        raise fail(key, f"must be {_CHANNEL_FORMS}; found {value!r}")
    parsed = parse_node_channel(value)
    if parsed is not None:
        return node_channel(*parsed)
    if re.match(r"(?i)node\s*\d", value.strip()):
        raise fail(key, f"= {value!r} is not 'node N' followed by a direction such as +Z")
    return value.strip()


def channel_map(fail: Fail, table: dict[str, Any],
                names: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """The ``[channels]`` table: (rig channel, channel of the run files) pairs.

    Parameters
    ----------
    fail : callable
        ``fail(key, what)``: the rig file's error naming ``key``.
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
    check_channel_names(fail, table, names)
    pairs: list[tuple[str, str]] = []
    taken: dict[str, str] = {}
    for name, value in table.items():
        key = f"channels.{name}"
        ref = _channel_ref(fail, value, key)
        if ref in taken:
            raise fail(key, f"= {ref!r} is also the channel of '{taken[ref]}'")
        taken[ref] = key
        pairs.append((name, ref))
    return tuple(pairs)


def check_channel_names(fail: Fail, table: dict[str, Any], names: Sequence[str]) -> None:
    """Every key of ``[channels]`` one of the rig's channels ``names``; else the error for the
    first other, with the nearest name.

    Raises
    ------
    Exception
        ``fail(key, what)``.
    """
    for name in table:
        if name not in names:
            near = nearest_key(name, list(names))
            raise fail(f"channels.{name}", "is not a channel of the rig; " + (
                f"did you mean '{near}'?" if near else
                f"expected one of {', '.join(names)} (the gauges, sensors, actuator.current, "
                "actuator.flux and the run files' time column)"))
