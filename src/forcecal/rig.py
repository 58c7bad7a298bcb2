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

from .errors import RigError
from .schema.channels import Fail, channel_map
from .schema.rig_file import check_rig_document
from .schema.toml_text import duplicated_key
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


def _acquisition(fail: Fail, acq: Any) -> dict[str, Any]:
    """The validated ``[acquisition]`` keys as :class:`Rig` fields, with the checks that join
    two keys (a band's ends in order; ``drive = "any"`` and ``scan_averages`` need a band)."""
    band = None
    if acq.band is not None:
        lo, hi = acq.band
        if not lo < hi:
            raise fail("acquisition.band", f"= [{lo!r}, {hi!r}] Hz is not a band "
                       "(0 <= low < high)")
        band = (float(lo), float(hi))
    if acq.drive == "any" and band is None:
        raise fail("acquisition.drive", "= 'any' needs 'acquisition.band', the band a "
                   "broadband scan covered")
    if acq.scan_averages is not None and band is None:
        raise fail("acquisition.scan_averages", "serves a broadband scan's FRFs; give "
                   "'acquisition.band' too")
    return {"frequency": acq.frequency, "run_group": acq.group, "temperature": acq.temperature,
            "mains": acq.mains, "band": band, "drive": acq.drive,
            "scan_averages": acq.scan_averages}


DRIVES = ("steady", "any")
"""What ``acquisition.drive`` may say."""


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
    flux: str | None = None
    """The run files' channel of the flux through this pole (``forces[].flux``); None: the
    actuator's (``actuator.flux``), when the rig gives one."""
    core: str | None = None
    """The magnetic circuit of this pole (``forces[].core``): poles of one core carry one flux
    and pull alike (:attr:`Rig.cores`)."""


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
class Weight:
    """The ``[weight]`` table: the gauges were zeroed without the structure, so a tare reads its
    weight (:mod:`forcecal.forces.weight` checks it against the rig's masses).

    Attributes
    ----------
    gravity : float [m/s^2]
        Along -w (on a body along -z).
    gauge_zero : float [N]
        Type-B standard uncertainty of each gauge's zero.
    """

    gravity: float
    gauge_zero: float


def _listed(names: Sequence[str], most: int = 6) -> str:
    """Names joined by commas, the first ``most`` of them and a count of the rest."""
    more = len(names) - most
    return ", ".join(names[:most]) + (f", ... ({more} more)" if more > 0 else "")


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
    weight: Weight | None = None
    """``[weight]``: gravity and the gauges' zero where the gauges read the structure's weight;
    None when the rig does not say so."""

    def __repr__(self) -> str:
        """One line: the name, the structure, the gauges, forces and sensors, the drive."""
        drive = (f"{self.drive} drive" + (f" at {self.frequency:g} Hz" if self.frequency else "")
                 + (f", band {self.band[0]:g}-{self.band[1]:g} Hz" if self.band else ""))
        points = "; ".join(f"{len(names)} {what} ({_listed(names)})" for what, names in (
            ("gauges", self.gauge_names), ("forces", self.force_names),
            ("sensors", self.sensor_names)))
        return (f"Rig('{self.name}' from '{self.source}': {type(self.structure).__name__}; "
                f"{points}; {drive})")

    @property
    def flux_channels(self) -> list[str]:
        """The run files' flux channels: ``actuator.flux`` and every ``forces[].flux``, once
        each, in that order."""
        names = [self.actuator.flux, *(f.flux for f in self.forces)]
        return list(dict.fromkeys(n for n in names if n is not None))

    @property
    def cores(self) -> dict[str, list[int]]:
        """The poles of each core with two or more, by the core's name: the forces that name
        one ``forces[].core``, or else one flux channel (``forces[].flux``, else
        ``actuator.flux``: a flux channel is one circuit's). Poles of one core carry one flux
        and pull alike."""
        out: dict[str, list[int]] = {}
        for k, f in enumerate(self.forces):
            name = f.core or f.flux or self.actuator.flux
            if name is not None:
                out.setdefault(name, []).append(k)
        return {name: poles for name, poles in out.items() if len(poles) > 1}

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
        text = path.read_text(encoding="utf-8")
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        twice = duplicated_key(text, str(exc))
        if twice is not None:
            where = str(exc)[str(exc).rfind("(at ") + 4:].rstrip(")")
            raise RigError(f"rig '{path}': key '{twice}' is written twice ({where}); a key is "
                           "given once per table") from None
        raise RigError(f"rig '{path}': not a valid TOML file ({exc})") from None
    except UnicodeDecodeError as exc:
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
    """Validate a rig given as a parsed TOML document (see :func:`load_rig`): first against
    its schema (:mod:`forcecal.schema.rig_file`: keys, types, units' bounds, unknown keys
    refused), then what joins keys (points on the structure, statics, unique names).

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
    keys = check_rig_document(doc, source)

    def fail(key: str, what: str) -> RigError:
        return RigError(f"rig '{source}': key '{key}' {what}")

    structure = _structure(fail, keys.structure)
    gauges = tuple(Gauge(**g, scale=k.scale)
                   for k, g in zip(keys.gauges, _points(fail, keys.gauges, "gauges", structure),
                                   strict=True))
    forces = tuple(ForcePoint(**f, gap=k.gap, flux=k.flux, core=k.core)
                   for k, f in zip(keys.forces, _points(fail, keys.forces, "forces", structure),
                                   strict=True))
    sensors = tuple(Sensor(**p, scale=k.scale)
                    for k, p in zip(keys.sensors,
                                    _points(fail, keys.sensors, "sensors", structure),
                                    strict=True))
    actuator = Actuator(**keys.actuator.model_dump())
    acq = _acquisition(fail, keys.acquisition)
    _check_names(fail, gauges, forces, sensors, actuator)
    _check_statics(fail, structure, gauges, forces, sensors)
    names = [g.name for g in gauges] + [s.name for s in sensors] + [actuator.current]
    names += [n for n in [actuator.flux, *(f.flux for f in forces)]
              if n is not None and n not in names]
    names += ["time"]                   # the run files' time column
    channels = channel_map(fail, keys.channels, names)
    type_b = (TypeB(**keys.uncertainty.model_dump(), declared=True)
              if keys.uncertainty is not None else TypeB())
    weight = None if keys.weight is None else Weight(**keys.weight.model_dump())
    return Rig(name=keys.name or Path(source).stem, structure=structure, gauges=gauges,
               forces=forces, sensors=sensors, actuator=actuator, source=source,
               channel_map=channels, type_b=type_b, weight=weight, **acq)


def _structure(fail: Fail, st: Any) -> Structure:
    """The validated ``[structure]`` table: its kind picks the class, which builds itself."""
    cls = KINDS[st.kind]
    masses = tuple(LumpedMass(x=m.x, y=_coordinate(fail, m, "y", f"structure.masses[{k}]",
                                                   cls.axes),
                              z=_coordinate(fail, m, "z", f"structure.masses[{k}]", cls.axes),
                              mass=m.mass) for k, m in enumerate(st.masses))
    structure = cls.from_keys(st, masses, fail)
    for k, lm in enumerate(masses):
        if not structure.contains(lm.x, lm.y, lm.z):
            raise fail(f"structure.masses[{k}].x", f"= {lm.x} lies off the structure")
    return structure


def _coordinate(fail: Fail, item: Any, axis: str, path: str, axes: tuple[str, ...]) -> float:
    """Coordinate ``axis`` of a point: required when the structure has that axis, else 0."""
    value = getattr(item, axis)
    if value is None and axis in axes:
        raise fail(f"{path}.{axis}", "is missing")
    return 0.0 if value is None else float(value)


def _direction(fail: Fail, item: Any, path: str,
               directed: bool) -> tuple[float, float, float]:
    """A point's unit ``direction`` (required where the structure's points carry one; beams
    and plates act along +w)."""
    if item.direction is None:
        if directed:
            raise fail(f"{path}.direction", "is missing: on a body every gauge, force and "
                       "sensor needs its direction [dx, dy, dz]")
        return UP
    if not directed:
        raise fail(f"{path}.direction", "applies to a 3-D body only (beams and plates act "
                   "along +w)")
    v = item.direction
    norm = math.sqrt(sum(c * c for c in v))
    if norm == 0.0:
        raise fail(f"{path}.direction", "must not be zero")
    return (v[0] / norm, v[1] / norm, v[2] / norm)


def _points(fail: Fail, items: Sequence[Any], key: str,
            structure: Structure) -> list[dict[str, Any]]:
    """The entries of ``[[key]]``: name, position and direction, each on the structure."""
    out = []
    for k, item in enumerate(items):
        path = f"{key}[{k}]"
        entry: dict[str, Any] = dict(
            name=item.name, x=item.x,
            y=_coordinate(fail, item, "y", path, structure.axes),
            z=_coordinate(fail, item, "z", path, structure.axes),
            direction=_direction(fail, item, path, structure.directed))
        if not structure.contains(entry["x"], entry["y"], entry["z"]):
            raise fail(f"{path}.x", structure.outside(entry["x"], entry["y"], entry["z"]))
        out.append(entry)
    return out


def _groups(gauges: tuple[Gauge, ...], forces: tuple[ForcePoint, ...],
            sensors: tuple[Sensor, ...]) -> list[tuple[str, Sequence[Gauge | ForcePoint | Sensor]]]:
    """The rig's points by the key of their tables."""
    return [("gauges", gauges), ("forces", forces), ("sensors", sensors)]


def _check_names(fail: Fail, gauges: tuple[Gauge, ...], forces: tuple[ForcePoint, ...],
                 sensors: tuple[Sensor, ...], actuator: Actuator) -> None:
    """Names unique across every channel kind, and none reserved for an output column."""
    seen: dict[str, str] = {}
    for key, items in _groups(gauges, forces, sensors):
        for k, item in enumerate(items):
            if item.name in seen or item.name in ("time", "total"):
                other = seen.get(item.name, "a reserved column name")
                raise fail(f"{key}[{k}].name", f"= '{item.name}' is used twice (also {other})")
            seen[item.name] = f"{key}[{k}]"
    if actuator.current in seen:
        raise fail("actuator.current", f"= '{actuator.current}' is also {seen[actuator.current]}")


def _check_statics(fail: Fail, structure: Structure, gauges: tuple[Gauge, ...],
                   forces: tuple[ForcePoint, ...], sensors: tuple[Sensor, ...]) -> None:
    """Gauge count, at least one sensor and one force, no two points at one place."""
    needed = structure.n_rigid
    if len(gauges) != needed:
        raise fail("gauges", f"has {len(gauges)} entries; a {structure.kind} on statically "
                     f"determinate gauges needs exactly {needed}")
    if not sensors:
        raise fail("sensors", "is empty: each harmonic's shape needs at least one "
                     "displacement sensor (no more shapes than sensors)")
    if not forces:
        raise fail("forces", "is empty: name at least one force point")
    if len(forces) > len(gauges):
        raise fail("forces", f"has {len(forces)} entries; at most {len(gauges)} forces "
                     "(one per gauge) can be determined")
    directed = structure.directed
    for key, items in _groups(gauges, forces, sensors):
        pts = locations(items)          # on a body, one point may carry two directions
        for a in range(len(items)):
            for b in range(a):
                if np.linalg.norm(pts[a, :3] - pts[b, :3]) < 1e-6 and (
                        not directed or np.linalg.norm(pts[a, 3:] - pts[b, 3:]) < 1e-6):
                    raise fail(f"{key}[{a}].x", f"puts '{items[a].name}' at the same point as "
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
        "forces": [point(f, ("gap", "flux", "core")) for f in rig.forces],
        "sensors": [point(s, ("scale",)) for s in rig.sensors],
    }
    act: dict[str, Any] = {"current": rig.actuator.current}
    for key in ("flux", "turns", "pole_area", "current_scale", "flux_scale"):
        v = getattr(rig.actuator, key)
        if v is not None and not (key.endswith("_scale") and v == 1.0):
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
    if rig.weight is not None:
        doc["weight"] = {"gravity": rig.weight.gravity, "gauge_zero": rig.weight.gauge_zero}
    return doc
