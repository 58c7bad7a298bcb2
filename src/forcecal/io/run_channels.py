"""A run's channels under the rig's names: the ``[channels]`` map applied, and the units a
file states checked against the rig's scales.

The rig's ``[channels]`` table maps a rig channel (a gauge, a sensor, ``actuator.current``,
``actuator.flux``) to the file's channel: a DAQ name (``s1 = "cDAQ1Mod1/ai0"``), or for a
UFF run a record's node and direction (``s1 = "node 12 +Z"``) or ID line. Channels the map does
not name keep the file's names. Its key ``time`` names the time column, which the readers take
(:mod:`forcecal.io._time_column`).

Where the file states a channel's unit (``s1 [mm]`` in a CSV header or units row; a UFF
ordinate's label) and the unit is one of the rig's quantity for that channel (a length for a
sensor, a force for a gauge, a current, a flux), the rig's scale must convert it to SI, to
within a factor of :data:`SCALE_SLACK` (room for a calibration factor or a sign): a probe in
mm needs ``scale`` near 0.001 (or -0.001), not 1. Other units (V, mV/V, counts) are the
scale's business and are not checked.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import replace

from ..errors import DataError
from ..records import Run
from ..rig import Rig
from ._run_values import RunFile
from ._time_column import TIME_KEY

__all__: list[str] = []

SI_UNITS: dict[str, tuple[str, float]] = {
    "N": ("force", 1.0), "kN": ("force", 1e3), "mN": ("force", 1e-3),
    "m": ("length", 1.0), "mm": ("length", 1e-3), "um": ("length", 1e-6),
    "µm": ("length", 1e-6), "μm": ("length", 1e-6), "nm": ("length", 1e-9),
    "A": ("current", 1.0), "mA": ("current", 1e-3),
    "Wb": ("flux", 1.0), "mWb": ("flux", 1e-3), "uWb": ("flux", 1e-6), "µWb": ("flux", 1e-6),
}
"""Units a channel's stated unit is checked against: unit -> (quantity, factor to SI)."""

_SI_NAME = {"force": "N", "length": "m", "current": "A", "flux": "Wb"}
SCALE_SLACK = 2.0
"""How far a scale may lie from the stated unit's factor to SI (a unit mistake is a factor of
1000 or more)."""
_LISTED = 8  # channel names listed in a message


def apply_rig(loaded: RunFile, rig: Rig) -> Run:
    """The run with the rig's channel names, its stated units checked against the rig.

    Parameters
    ----------
    loaded : RunFile
        The run as its file names it, with the file's other names and units.
    rig : Rig
        The rig: its ``channel_map`` and its channels' scales.

    Returns
    -------
    Run
        Mapped channels under the rig's names, in the file's order; the others unchanged.

    Raises
    ------
    DataError
        A channel the map names that the file does not hold (naming the rig file, the key and
        the channel), or a stated unit the rig's scale does not convert.
    """
    run = loaded.run
    channels = run.channels
    sources: dict[str, str] = {}
    for name, ref in rig.channel_map:
        if name == TIME_KEY:                 # the time column: its reader took it
            continue
        source = ref if ref in channels else loaded.aliases.get(ref)
        if source is None:
            raise DataError(f"run '{run.source}': channel {ref!r} (rig '{rig.source}', key "
                            f"'channels.{name}') is not in the file; it holds "
                            f"{_listing(channels)}")
        sources[source] = name
    _check_units(run, loaded.units, sources, rig)
    if not sources:
        return run
    mapped = set(sources.values())
    renamed = {sources.get(n, n): v for n, v in channels.items()
               if n in sources or n not in mapped}
    return replace(run, channels=renamed)


def _listing(channels: Mapping[str, object]) -> str:
    names = list(channels)
    shown = ", ".join(repr(n) for n in names[:_LISTED])
    return shown + (f" and {len(names) - _LISTED} more" if len(names) > _LISTED else "")


def _rig_channels(rig: Rig) -> Iterator[tuple[str, str, float, str]]:
    """(name, quantity, scale, key of the scale) of every channel the rig reads."""
    for k, g in enumerate(rig.gauges):
        yield g.name, "force", g.scale, f"gauges[{k}].scale"
    for k, s in enumerate(rig.sensors):
        yield s.name, "length", s.scale, f"sensors[{k}].scale"
    act = rig.actuator
    yield act.current, "current", act.current_scale, "actuator.current_scale"
    for name in rig.flux_channels:
        yield name, "flux", act.flux_scale, "actuator.flux_scale"


def _check_units(run: Run, units: Mapping[str, str], sources: Mapping[str, str],
                 rig: Rig) -> None:
    """A stated unit of the rig's quantity must be what the rig's scale converts to SI."""
    if not units:
        return
    mapped = set(sources.values())
    unit_of = {sources.get(n, n): u for n, u in units.items() if n in sources or n not in mapped}
    file_name = {v: k for k, v in sources.items()}
    for name, quantity, scale, key in _rig_channels(rig):
        unit = unit_of.get(name, "")
        if unit not in SI_UNITS or SI_UNITS[unit][0] != quantity:
            continue
        factor = SI_UNITS[unit][1]
        if factor / SCALE_SLACK <= abs(scale) <= factor * SCALE_SLACK:
            continue
        column = file_name.get(name, name)
        shown = f"channel {column!r}" + (f" (rig channel {name!r})" if column != name else "")
        raise DataError(f"run '{run.source}': {shown} is in {unit}, but rig '{rig.source}' "
                        f"key '{key}' = {scale:g} reads it as {_SI_NAME[quantity]}; expected "
                        f"a scale near {factor:g} (or {-factor:g})")
