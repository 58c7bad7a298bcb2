"""The rig: structure, force gauges, force points, sensors and actuator channels.

A rig is read from the TOML file described in INTERFACES.md section 1 and validated before any
computation: every message names the file and the key at fault. The parser is the one place
that looks at ``structure.kind``: it picks the structure's class from
:data:`forcecal.structures.KINDS`, and everything downstream asks that object.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ._toml import TableReader, channel_map, check_numbers
from .errors import RigError
from .structures import KINDS, UP, LumpedMass, Structure, locations

__all__ = [
    "Actuator",
    "ForcePoint",
    "Gauge",
    "LumpedMass",
    "Rig",
    "Sensor",
    "TypeB",
    "load_rig",
    "rig_to_dict",
]


# --- from rig_acquisition ---
def read_acquisition(r: TableReader, acq: dict[str, Any]) -> dict[str, Any]:
    """The ``[acquisition]`` keys as :class:`forcecal.rig.Rig` fields.

    Returns
    -------
    dict
        ``frequency``, ``run_group``, ``temperature``, ``mains``, ``band``, ``drive`` and
        ``scan_averages`` (None where a key is absent; ``drive`` "steady").

    Raises
    ------
    RigError
        A key out of its range or inconsistent with another, named.
    """
    keys: dict[str, Any] = {
        "frequency": r.number(acq, "frequency", "acquisition", required=False, positive=True),
        "run_group": r.text(acq, "group", "acquisition", required=False, default=None),
        "temperature": _temperature(r, acq),
        "mains": r.number(acq, "mains", "acquisition", required=False, positive=True)}
    mains = keys["mains"]
    if mains is not None and not 10.0 <= mains <= 1000.0:
        raise r.fail("acquisition.mains", f"= {mains!r} Hz is not a mains frequency (50 or 60)")
    keys["band"], keys["drive"] = _drive_band(r, acq)
    keys["scan_averages"] = _scan_averages(r, acq, keys["band"])
    return keys


DRIVES = ("steady", "any")
"""What ``acquisition.drive`` may say."""


def _drive_band(r: TableReader, acq: dict[str, Any]) -> tuple[tuple[float, float] | None, str]:
    """``acquisition.band`` [Hz] (None when absent) and ``acquisition.drive``."""
    drive = r.text(acq, "drive", "acquisition", required=False, default="steady")
    if drive not in DRIVES:
        raise r.fail("acquisition.drive", f"= {drive!r} is not one of {', '.join(DRIVES)}")
    band = None
    if "band" in acq:
        lo, hi = r.vector(acq, "band", "acquisition", 2, "a band (low, high) in Hz")
        if not 0.0 <= lo < hi:
            raise r.fail("acquisition.band", f"= [{lo!r}, {hi!r}] Hz is not a band "
                         "(0 <= low < high)")
        band = (float(lo), float(hi))
    if drive == "any" and band is None:
        raise r.fail("acquisition.drive", "= 'any' needs 'acquisition.band', the band a "
                     "broadband scan covered")
    return band, drive


def _scan_averages(r: TableReader, acq: dict[str, Any], band: tuple[float, float] | None
                   ) -> int | None:
    """``acquisition.scan_averages``: a whole number of averages, for a broadband scan."""
    n = r.number(acq, "scan_averages", "acquisition", required=False, positive=True)
    if n is None:
        return None
    if n != int(n) or n > 1e6:
        raise r.fail("acquisition.scan_averages", f"= {n!r} is not a number of averages (a "
                     "whole number, 2 to 1e6)")
    if n < 2:
        raise r.fail("acquisition.scan_averages", f"= {int(n)}: the coherence of one average is "
                     "1 on every line and states no noise; FRFs need 2 or more averages")
    if band is None:
        raise r.fail("acquisition.scan_averages", "serves a broadband scan's FRFs; give "
                     "'acquisition.band' too")
    return int(n)


_TEMPERATURE_RANGE_C = (-100.0, 200.0)
"""Ambient temperatures ``acquisition.temperature`` may give [°C]; beyond is probably kelvin."""


def _temperature(r: TableReader, acq: dict[str, Any]) -> float | None:
    """``acquisition.temperature`` [°C], or None when absent."""
    value = r.number(acq, "temperature", "acquisition", required=False)
    lo, hi = _TEMPERATURE_RANGE_C
    if value is not None and not lo <= value <= hi:
        raise r.fail("acquisition.temperature", f"= {value!r} °C is not an ambient temperature "
                     f"between {lo:g} and {hi:g} °C (23.0 for 23 °C; not in kelvin)")
    return value


# --- from rig ---
@dataclass(frozen=True)
class Gauge:
    """A force gauge; ``scale`` converts the raw channel to N acting on the structure in +w
    (on a body: along ``direction``, a unit vector)."""

    name: str
    x: float
    y: float = 0.0
    scale: float = 1.0
    z: float = 0.0
    direction: tuple[float, float, float] = UP


@dataclass(frozen=True)
class ForcePoint:
    """A point where an unknown external force acts (an actuator pole).

    ``gap`` is the static air gap [m] with the structure at w = 0, or None when unknown. On a
    body the force acts along ``direction`` (a unit vector, toward the magnet: motion along it
    closes the gap).
    """

    name: str
    x: float
    y: float = 0.0
    gap: float | None = None
    z: float = 0.0
    direction: tuple[float, float, float] = UP


@dataclass(frozen=True)
class Sensor:
    """A point displacement sensor; ``scale`` converts the raw channel to m in +w (on a body:
    along ``direction``)."""

    name: str
    x: float
    y: float = 0.0
    scale: float = 1.0
    z: float = 0.0
    direction: tuple[float, float, float] = UP


@dataclass(frozen=True)
class Actuator:
    """Channels and data of the electromagnet under calibration."""

    current: str = "i"
    flux: str | None = None
    turns: float | None = None
    pole_area: float | None = None
    current_scale: float = 1.0
    flux_scale: float = 1.0

    @property
    def ideal_k(self) -> float | None:
        """mu0 N^2 A / 4 [N m^2 / A^2], the ideal constant of f = K i^2 / s^2 for a U-core."""
        if self.turns is None or self.pole_area is None:
            return None
        return 4e-7 * math.pi * self.turns**2 * self.pole_area / 4.0


@dataclass(frozen=True)
class TypeB:
    """Type-B standard uncertainties of the rig (GUM), the ``[uncertainty]`` table.

    Relative ones are fractions (0.005 for 0.5 %). Without the table the defaults apply, and
    every output says so (:attr:`declared` is False).

    Attributes
    ----------
    gauge_scale : [1] relative, each gauge's sensitivity
    probe_scale : [1] relative, each displacement sensor's sensitivity
    current_scale : [1] relative, the current sensor's
    position : [m] each gauge's, force point's and sensor's position along every axis
    mass : [1] relative, the distributed mass and each lumped mass
    gap : [m] each static air gap
    declared : whether the rig file gives them
    """

    gauge_scale: float = 0.005
    probe_scale: float = 0.01
    current_scale: float = 0.002
    position: float = 0.5e-3
    mass: float = 0.01
    gap: float = 10e-6
    declared: bool = False

    KEYS: ClassVar[tuple[str, ...]] = ("gauge_scale", "probe_scale", "current_scale",
                                       "position", "mass", "gap")

    @classmethod
    def none(cls) -> TypeB:
        """Every type-B uncertainty zero, declared (ideal sensors and geometry)."""
        return cls(**dict.fromkeys(cls.KEYS, 0.0), declared=True)

    def describe(self) -> str:
        """One line: the values, and whether the rig declares them or they are defaults."""
        text = (f"gauge scale {self.gauge_scale:.3g}, probe scale {self.probe_scale:.3g}, "
                f"current scale {self.current_scale:.3g} (relative); positions "
                f"{self.position * 1e3:.3g} mm; masses {self.mass:.3g} (relative); gaps "
                f"{self.gap * 1e6:.3g} um")
        return ("type-B standard uncertainties declared by the rig: " if self.declared else
                "type-B standard uncertainties: the rig declares none ([uncertainty]); "
                "defaults used: ") + text


@dataclass(frozen=True)
class Rig:
    """A complete rig description (INTERFACES.md section 1)."""

    name: str
    structure: Structure
    gauges: tuple[Gauge, ...]
    forces: tuple[ForcePoint, ...]
    sensors: tuple[Sensor, ...]
    actuator: Actuator = field(default_factory=Actuator)
    frequency: float | None = None
    source: str = "<rig>"
    channel_map: tuple[tuple[str, str], ...] = ()
    """``[channels]``: (rig channel name, the file's channel) pairs; a UFF record is named
    ``"node 12 +Z"`` (see :func:`node_channel`); ``("time", NAME)`` names the run files' time
    column."""
    run_group: str | None = None
    """``acquisition.group``: the TDMS group, or the HDF5 group's path, the runs are read
    from."""
    type_b: TypeB = field(default_factory=TypeB)
    """``[uncertainty]``: the type-B standard uncertainties (defaults when not declared)."""
    temperature: float | None = None
    """``acquisition.temperature`` [°C]: the ambient temperature of the measurements, stated in
    the calibration certificate's conditions; None when the rig does not give it."""
    mains: float | None = None
    """``acquisition.mains`` [Hz]: the mains frequency (50 or 60); a drive harmonic on one of
    the mains' is then noted (:func:`forcecal.forces.diagnostics.mains_notes`)."""
    band: tuple[float, float] | None = None
    """``acquisition.band`` [Hz]: (low, high), the band a broadband scan's drive covered; when
    given, ``scan`` builds the shapes over that band (:mod:`forcecal.model.broadband`)."""
    scan_averages: int | None = None
    """``acquisition.scan_averages``: the averages behind every FRF of a broadband scan
    exported as FRFs (their noise follows from it and their coherence); None when not given."""
    drive: str = "steady"
    """``acquisition.drive``: "steady" (periodic at one fundamental, the harmonic path) or
    "any" (swept, multi-tone or random: forces sample by sample,
    :mod:`forcecal.forces.transient`)."""

    @property
    def gauge_names(self) -> list[str]:
        return [g.name for g in self.gauges]

    @property
    def force_names(self) -> list[str]:
        return [f.name for f in self.forces]

    @property
    def sensor_names(self) -> list[str]:
        return [s.name for s in self.sensors]

    @property
    def drive_frequency(self) -> float:
        """[Hz] the nominal drive frequency (``acquisition.frequency``), which every stage
        that refines a fundamental starts from.

        Raises
        ------
        RigError
            When the rig does not give it.
        """
        if self.frequency is None:
            raise RigError(f"rig '{self.source}': key 'acquisition.frequency' is missing "
                           "(the nominal drive frequency)")
        return self.frequency

    @property
    def gauge_points(self) -> np.ndarray:
        """Rig points of the gauges: (n_gauges, 2) (x, y) [m]; on a body (n_gauges, 6)
        locations (see :func:`forcecal.structures.locations`)."""
        return self.structure.rig_points(self.gauges)

    @property
    def force_points(self) -> np.ndarray:
        """Rig points of the force points, as :attr:`gauge_points`."""
        return self.structure.rig_points(self.forces)

    @property
    def sensor_points(self) -> np.ndarray:
        """Rig points of the sensors, as :attr:`gauge_points`."""
        return self.structure.rig_points(self.sensors)


# --------------------------------------------------------------------------------------------
# reading and validation

MAX_RIG_BYTES = 10_000_000
"""Largest rig file read (a rig of thousands of points is a few hundred kB)."""

_KNOWN_TOP = {"name", "structure", "gauges", "forces", "sensors", "actuator", "acquisition",
              "channels", "uncertainty"}


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig file.

    Parameters
    ----------
    path : str or Path
        The rig file (TOML).

    Returns
    -------
    Rig

    Raises
    ------
    RigError
        When the file is missing, is not TOML, or a key is missing or inconsistent; the message
        names the file and the key.
    """
    path = Path(path)
    if not path.is_file():
        raise RigError(f"rig '{path}': file not found")
    if path.stat().st_size > MAX_RIG_BYTES:
        raise RigError(f"rig '{path}': {path.stat().st_size} bytes; a rig file is at most "
                       f"{MAX_RIG_BYTES} bytes")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"rig '{path}': not a valid TOML file ({exc})") from None
    except RecursionError:
        raise RigError(f"rig '{path}': not a valid TOML file (nested too deeply)") from None
    except ValueError as exc:  # e.g. an integer beyond Python's digit limit
        raise RigError(f"rig '{path}': not a valid TOML file ({_first_line(exc)})") from None
    return parse_rig(doc, source=str(path))


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


def parse_rig(doc: dict[str, Any], source: str = "<rig>") -> Rig:
    """Validate a rig given as a parsed TOML document (see :func:`load_rig`).

    Parameters
    ----------
    doc : dict
        The parsed document.
    source : str
        The file's name, quoted in every message.

    Returns
    -------
    Rig
    """
    r = TableReader(source)
    if not isinstance(doc, dict):
        raise RigError(f"rig '{source}': expected a TOML document (a table of keys)")
    check_numbers(doc, source)
    unknown = set(doc) - _KNOWN_TOP
    if unknown:
        raise r.fail(sorted(unknown)[0], "is not a rig key (expected one of "
                     + ", ".join(sorted(_KNOWN_TOP)) + ")")
    name = r.text(doc, "name", "", required=False, default=Path(source).stem)
    structure = _structure(r, r.table(doc, "structure"))
    gauges = tuple(Gauge(**g) for g in _points(r, doc, "gauges", structure, ("scale",)))
    forces = tuple(ForcePoint(**f) for f in _points(r, doc, "forces", structure, ("gap",)))
    sensors = tuple(Sensor(**s) for s in _points(r, doc, "sensors", structure, ("scale",)))
    actuator = _actuator(r, r.table(doc, "actuator", required=False))
    acq = read_acquisition(r, r.table(doc, "acquisition", required=False))
    _check_names(r, gauges, forces, sensors, actuator)
    _check_statics(r, structure, gauges, forces, sensors)
    names = [g.name for g in gauges] + [s.name for s in sensors] + [actuator.current]
    names += [actuator.flux] if actuator.flux is not None else []
    names += ["time"]                   # the run files' time column
    channels = channel_map(r, r.table(doc, "channels", required=False), names)
    type_b = _type_b(r, r.table(doc, "uncertainty", required=False), "uncertainty" in doc)
    return Rig(name=name or Path(source).stem, structure=structure, gauges=gauges,
               forces=forces, sensors=sensors, actuator=actuator, source=source,
               channel_map=channels, type_b=type_b, **acq)


def _type_b(r: TableReader, table: dict[str, Any], declared: bool) -> TypeB:
    """The ``[uncertainty]`` table: type-B standard uncertainties, defaults for keys absent."""
    unknown = set(table) - set(TypeB.KEYS)
    if unknown:
        raise r.fail(f"uncertainty.{sorted(unknown)[0]}", "is not a type-B key (expected one of "
                     + ", ".join(TypeB.KEYS) + ")")
    limits = {"gauge_scale": 0.5, "probe_scale": 0.5, "current_scale": 0.5, "position": 0.1,
              "mass": 0.5, "gap": 1e-3}
    values: dict[str, float] = {}
    for key in TypeB.KEYS:
        v = r.number(table, key, "uncertainty", required=False)
        if v is None:
            continue
        if not 0.0 <= v <= limits[key]:
            raise r.fail(f"uncertainty.{key}", f"= {v!r} must lie in [0, {limits[key]:g}] "
                         + ("(a relative standard uncertainty: 0.005 for 0.5 %)"
                            if key not in ("position", "gap") else "(a standard uncertainty in m)"))
        values[key] = v
    return TypeB(**values, declared=declared)


def _structure(r: TableReader, st: dict[str, Any]) -> Structure:
    """The ``[structure]`` table: its kind picks the class, which reads its own keys."""
    kind = r.text(st, "kind", "structure", required=False, default="beam")
    cls = KINDS.get(kind or "")
    if cls is None:
        names = ", ".join(f"'{k}'" for k in KINDS)
        raise r.fail("structure.kind", f"must be one of {names}, found {kind!r}")
    masses_raw = st.get("masses", [])
    if not isinstance(masses_raw, list):
        raise r.fail("structure.masses", "must be an array of {x, mass} tables")
    masses = []
    for k, m in enumerate(masses_raw):
        key = f"structure.masses[{k}]"
        if not isinstance(m, dict):
            raise r.fail(key, "must be a table {x = ..., mass = ...}")
        masses.append(LumpedMass(
            x=r.required(m, "x", key),
            y=_coordinate(r, m, "y", key, cls.axes),
            z=_coordinate(r, m, "z", key, cls.axes),
            mass=r.required(m, "mass", key, positive=True),
        ))
    structure = cls.from_table(r, st, tuple(masses))
    for k, lm in enumerate(masses):
        if not structure.contains(lm.x, lm.y, lm.z):
            raise r.fail(f"structure.masses[{k}].x", f"= {lm.x} lies off the structure")
    return structure


def _optional(r: TableReader, table: dict[str, Any], key: str, path: str,
              default: float) -> float:
    """An optional number with its default."""
    value = r.number(table, key, path, required=False)
    return default if value is None else value


def _coordinate(r: TableReader, item: dict[str, Any], axis: str, path: str,
                axes: tuple[str, ...]) -> float:
    """Coordinate ``axis`` of a point: required when the structure has that axis, else 0."""
    return r.required(item, axis, path) if axis in axes else _optional(r, item, axis, path, 0.0)


def _direction(r: TableReader, item: dict[str, Any], path: str,
               directed: bool) -> tuple[float, float, float]:
    """A point's unit ``direction`` (required where the structure's points carry one; beams
    and plates act along +w)."""
    if "direction" not in item:
        if directed:
            raise r.fail(f"{path}.direction", "is missing: on a body every gauge, force and "
                         "sensor needs its direction [dx, dy, dz]")
        return UP
    if not directed:
        raise r.fail(f"{path}.direction", "applies to a 3-D body only (beams and plates act "
                     "along +w)")
    v = r.vector(item, "direction", path, 3, "[dx, dy, dz], three numbers")
    norm = math.sqrt(sum(c * c for c in v))
    if norm == 0.0:
        raise r.fail(f"{path}.direction", "must not be zero")
    return (v[0] / norm, v[1] / norm, v[2] / norm)


def _points(r: TableReader, doc: dict[str, Any], key: str, structure: Structure,
            extra: tuple[str, ...]) -> list[dict[str, Any]]:
    """The entries of ``[[key]]`` as keyword arguments of Gauge, ForcePoint or Sensor."""
    out = []
    for k, item in enumerate(r.array_of_tables(doc, key)):
        path = f"{key}[{k}]"
        entry: dict[str, Any] = dict(
            name=r.text(item, "name", path),
            x=r.required(item, "x", path),
            y=_coordinate(r, item, "y", path, structure.axes),
            z=_coordinate(r, item, "z", path, structure.axes),
            direction=_direction(r, item, path, structure.directed),
        )
        for e in extra:
            if e == "gap":
                entry[e] = r.number(item, "gap", path, required=False, positive=True)
            else:
                entry[e] = _optional(r, item, e, path, 1.0)
                if entry[e] == 0.0:
                    raise r.fail(f"{path}.{e}", "must not be zero")
        if not structure.contains(entry["x"], entry["y"], entry["z"]):
            raise r.fail(f"{path}.x", structure.outside(entry["x"], entry["y"], entry["z"]))
        out.append(entry)
    return out


def _actuator(r: TableReader, act: dict[str, Any]) -> Actuator:
    """The ``[actuator]`` table (every key optional)."""
    return Actuator(
        current=r.text(act, "current", "actuator", required=False, default="i") or "i",
        flux=r.text(act, "flux", "actuator", required=False, default=None),
        turns=r.number(act, "turns", "actuator", required=False, positive=True),
        pole_area=r.number(act, "pole_area", "actuator", required=False, positive=True),
        current_scale=_optional(r, act, "current_scale", "actuator", 1.0),
        flux_scale=_optional(r, act, "flux_scale", "actuator", 1.0),
    )


def _groups(gauges: tuple[Gauge, ...], forces: tuple[ForcePoint, ...],
            sensors: tuple[Sensor, ...]) -> list[tuple[str, Sequence[Gauge | ForcePoint | Sensor]]]:
    """The rig's points by the key of their tables."""
    return [("gauges", gauges), ("forces", forces), ("sensors", sensors)]


def _check_names(r: TableReader, gauges: tuple[Gauge, ...], forces: tuple[ForcePoint, ...],
                 sensors: tuple[Sensor, ...], actuator: Actuator) -> None:
    """Names unique across every channel kind, and none reserved for an output column."""
    seen: dict[str, str] = {}
    for key, items in _groups(gauges, forces, sensors):
        for k, item in enumerate(items):
            if item.name in seen or item.name in ("time", "total"):
                other = seen.get(item.name, "a reserved column name")
                raise r.fail(f"{key}[{k}].name", f"= '{item.name}' is used twice (also {other})")
            seen[item.name] = f"{key}[{k}]"
    if actuator.current in seen:
        raise r.fail("actuator.current", f"= '{actuator.current}' is also {seen[actuator.current]}")


def _check_statics(r: TableReader, structure: Structure, gauges: tuple[Gauge, ...],
                   forces: tuple[ForcePoint, ...], sensors: tuple[Sensor, ...]) -> None:
    """Gauge count, at least one sensor and one force, no two points at one place."""
    needed = structure.n_rigid
    if len(gauges) != needed:
        raise r.fail("gauges", f"has {len(gauges)} entries; a {structure.kind} on statically "
                     f"determinate gauges needs exactly {needed}")
    if not sensors:
        raise r.fail("sensors", "is empty: each harmonic's shape needs at least one "
                     "displacement sensor (no more shapes than sensors)")
    if not forces:
        raise r.fail("forces", "is empty: name at least one force point")
    if len(forces) > len(gauges):
        raise r.fail("forces", f"has {len(forces)} entries; at most {len(gauges)} forces "
                     "(one per gauge) can be determined")
    directed = structure.directed
    for key, items in _groups(gauges, forces, sensors):
        pts = locations(items)          # on a body, one point may carry two directions
        for a in range(len(items)):
            for b in range(a):
                if np.linalg.norm(pts[a, :3] - pts[b, :3]) < 1e-6 and (
                        not directed or np.linalg.norm(pts[a, 3:] - pts[b, 3:]) < 1e-6):
                    raise r.fail(f"{key}[{a}].x", f"puts '{items[a].name}' at the same point as "
                                 f"'{items[b].name}'" + (" in the same direction" if directed
                                                         else ""))


def rig_to_dict(rig: Rig) -> dict[str, Any]:
    """The rig as a TOML-ready document (inverse of :func:`parse_rig`).

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    dict
    """
    st = rig.structure
    structure = st.to_dict()
    if st.masses:
        structure["masses"] = [{**{a: getattr(m, a) for a in st.axes}, "mass": m.mass}
                               for m in st.masses]

    def point(p: Gauge | ForcePoint | Sensor, extra: tuple[str, ...]) -> dict[str, Any]:
        d: dict[str, Any] = {"name": p.name, **{a: getattr(p, a) for a in st.axes}}
        if st.directed:
            d["direction"] = list(p.direction)
        for e in extra:
            v = getattr(p, e)
            if v is not None and not (e == "scale" and v == 1.0):
                d[e] = v
        return d

    doc: dict[str, Any] = {
        "name": rig.name,
        "structure": structure,
        "gauges": [point(g, ("scale",)) for g in rig.gauges],
        "forces": [point(f, ("gap",)) for f in rig.forces],
        "sensors": [point(s, ("scale",)) for s in rig.sensors],
    }
    act: dict[str, Any] = {"current": rig.actuator.current}
    for key in ("flux", "turns", "pole_area"):
        v = getattr(rig.actuator, key)
        if v is not None:
            act[key] = v
    doc["actuator"] = act
    acquisition: dict[str, Any] = {}
    if rig.frequency is not None:
        acquisition["frequency"] = rig.frequency
    if rig.run_group is not None:
        acquisition["group"] = rig.run_group
    if rig.temperature is not None:
        acquisition["temperature"] = rig.temperature
    if rig.mains is not None:
        acquisition["mains"] = rig.mains
    if rig.band is not None:
        acquisition["band"] = list(rig.band)
    if rig.scan_averages is not None:
        acquisition["scan_averages"] = rig.scan_averages
    if rig.drive != "steady":
        acquisition["drive"] = rig.drive
    if acquisition:
        doc["acquisition"] = acquisition
    if rig.channel_map:
        doc["channels"] = dict(rig.channel_map)
    if rig.type_b.declared:
        doc["uncertainty"] = {k: getattr(rig.type_b, k) for k in TypeB.KEYS}
    return doc
