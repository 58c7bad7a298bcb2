"""The rig: structure, force gauges, force points, sensors and actuator channels.

A rig is read from the TOML file described in INTERFACES.md section 1 and validated before any
computation: every message names the file and the key at fault.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import RigError

__all__ = [
    "Actuator",
    "ForcePoint",
    "Gauge",
    "LumpedMass",
    "Rig",
    "Sensor",
    "Structure",
    "inside_polygon",
    "load_rig",
    "locations",
    "parse_rig",
    "rig_to_dict",
]


UP = (0.0, 0.0, 1.0)
"""The measuring direction of beams and plates: +w, out of their plane."""


@dataclass(frozen=True)
class LumpedMass:
    """A point mass rigidly attached to the structure [kg] at (x, y, z) [m]."""

    x: float
    mass: float
    y: float = 0.0
    z: float = 0.0


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


def inside_polygon(polygon: np.ndarray, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Which points lie inside a simple polygon or within ``tol`` of its edges.

    Parameters
    ----------
    polygon : (n_vertices, 2) [m]; points : (n_points, 2) [m]

    Returns
    -------
    (n_points,) bool
    """
    v = np.asarray(polygon, dtype=float)
    p = np.atleast_2d(np.asarray(points, dtype=float))
    a, b = v, np.roll(v, -1, axis=0)                                 # edges a -> b
    px, py = p[:, 0:1], p[:, 1:2]
    # even-odd rule: edges that straddle the point's height, crossed to its right
    straddle = (a[:, 1] > py) != (b[:, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = np.count_nonzero(straddle & (px < x_cross), axis=1) % 2 == 1
    # distance to every edge, so that points on the outline count
    d = b - a
    length2 = np.maximum(np.sum(d**2, axis=1), 1e-300)
    u = np.clip(((px - a[:, 0]) * d[:, 0] + (py - a[:, 1]) * d[:, 1]) / length2, 0.0, 1.0)
    dist = np.hypot(px - (a[:, 0] + u * d[:, 0]), py - (a[:, 1] + u * d[:, 1]))
    return inside | np.any(dist <= tol, axis=1)


@dataclass(frozen=True)
class Structure:
    """The elastic body: its kind, extent and mass distribution.

    For a beam, ``length`` [m] and ``mass_per_length`` [kg/m] along x in [0, length].
    For a plate, ``outline`` (n_vertices, 2) [m] and ``mass_per_area`` [kg/m^2].
    For a 3-D body, ``blocks`` (axis-aligned boxes ((x0, y0, z0), (x1, y1, z1)) [m] that do not
    overlap) and ``density`` [kg/m^3].
    """

    kind: str
    length: float | None = None
    mass_per_length: float | None = None
    mass_per_area: float | None = None
    outline: tuple[tuple[float, float], ...] | None = None
    masses: tuple[LumpedMass, ...] = ()
    density: float | None = None
    blocks: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...] = ()

    @property
    def dim(self) -> int:
        return {"beam": 1, "plate": 2}.get(self.kind, 3)

    def contains(self, x: float, y: float = 0.0, z: float = 0.0, tol: float = 1e-9) -> bool:
        """Whether (x, y[, z]) lies on the structure (within ``tol`` [m])."""
        if self.kind == "beam":
            return -tol <= x <= self.length + tol
        if self.kind == "body":
            p = np.array([x, y, z])
            return any(bool(np.all((np.asarray(lo) - tol <= p) & (p <= np.asarray(hi) + tol)))
                       for lo, hi in self.blocks)
        return bool(inside_polygon(np.asarray(self.outline), np.array([[x, y]]), tol)[0])

    @property
    def total_mass(self) -> float:
        """Distributed plus lumped mass [kg]."""
        if self.kind == "beam":
            distributed = self.mass_per_length * self.length
        elif self.kind == "body":
            distributed = self.density * sum(float(np.prod(np.subtract(hi, lo)))
                                             for lo, hi in self.blocks)
        else:
            v = np.asarray(self.outline)
            x, y = v[:, 0], v[:, 1]
            area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
            distributed = self.mass_per_area * area
        return distributed + sum(m.mass for m in self.masses)


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
    def is_body(self) -> bool:
        """Whether the structure is a 3-D body (its points are located with a direction)."""
        return self.structure.kind == "body"

    def _coords(self, items) -> np.ndarray:
        if self.is_body:
            return locations(items)
        return np.array([[p.x, p.y] for p in items], dtype=float).reshape(-1, 2)

    @property
    def gauge_points(self) -> np.ndarray:
        """(n_gauges, 2) (x, y) [m]; on a body (n_gauges, 6) locations (see :func:`locations`)."""
        return self._coords(self.gauges)

    @property
    def force_points(self) -> np.ndarray:
        """(n_forces, 2) (x, y) [m]; on a body (n_forces, 6) locations."""
        return self._coords(self.forces)

    @property
    def sensor_points(self) -> np.ndarray:
        """(n_sensors, 2) (x, y) [m]; on a body (n_sensors, 6) locations."""
        return self._coords(self.sensors)


def locations(items) -> np.ndarray:
    """Locations of points on a 3-D body: rows (x, y, z, dx, dy, dz), a point [m] and the unit
    direction in which a force acts or a displacement is measured there.

    Every scalar quantity on a body (a gauge's reaction, a pole's force, a probe's or a scan
    record's displacement) is the component of a vector along its direction, so a location is
    what a shape or a relaxation shape is evaluated at.
    """
    return np.array([[p.x, p.y, p.z, *p.direction] for p in items], dtype=float).reshape(-1, 6)


# --------------------------------------------------------------------------------------------
# reading and validation


class _Reader:
    """Typed access to a TOML table with messages that name the file and the key."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, what: str) -> RigError:
        return RigError(f"rig '{self.source}': key '{key}' {what}")

    def number(self, table: dict, key: str, path: str, *, required=True, positive=False,
               default=None) -> float | None:
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

    def text(self, table: dict, key: str, path: str, *, required=True, default=None):
        full = f"{path}.{key}" if path else key
        if key not in table:
            if required:
                raise self.fail(full, "is missing")
            return default
        value = table[key]
        if not isinstance(value, str) or not value.strip():
            raise self.fail(full, f"must be a non-empty string, found {value!r}")
        return value

    def table(self, doc: dict, key: str, *, required=True) -> dict:
        if key not in doc:
            if required:
                raise self.fail(key, "is missing (a [" + key + "] table)")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, "must be a table")
        return value

    def array_of_tables(self, doc: dict, key: str) -> list[dict]:
        if key not in doc:
            raise self.fail(key, f"is missing (at least one [[{key}]] table)")
        value = doc[key]
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, f"must be an array of tables [[{key}]]")
        return value


_KNOWN_TOP = {"name", "structure", "gauges", "forces", "sensors", "actuator", "acquisition"}


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig file.

    Raises
    ------
    RigError
        When the file is missing, is not TOML, or a key is missing or inconsistent; the message
        names the file and the key.
    """
    path = Path(path)
    if not path.is_file():
        raise RigError(f"rig '{path}': file not found")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"rig '{path}': not a valid TOML file ({exc})") from None
    return parse_rig(doc, source=str(path))


KINDS = ("beam", "plate", "body")
"""Structure kinds: a beam in plane bending, a plate in out-of-plane bending, a 3-D body."""
RIGID_MODES = {"beam": 2, "plate": 3, "body": 6}
"""Rigid-body modes of each kind, and so the number of statically determinate gauges."""


def _blocks(r: _Reader, st: dict) -> tuple:
    """A body's ``structure.blocks``: axis-aligned boxes {min = [x, y, z], max = [x, y, z]}."""
    raw = st.get("blocks")
    if not isinstance(raw, list) or not raw:
        raise r.fail("structure.blocks", "must list at least one block "
                     "{min = [x, y, z], max = [x, y, z]} (m)")
    out = []
    for k, blk in enumerate(raw):
        key = f"structure.blocks[{k}]"
        corners = []
        for end in ("min", "max"):
            v = blk.get(end) if isinstance(blk, dict) else None
            if (not isinstance(v, list) or len(v) != 3
                    or not all(isinstance(c, int | float) and not isinstance(c, bool)
                               and math.isfinite(c) for c in v)):
                raise r.fail(f"{key}.{end}", "must be a corner [x, y, z] of three numbers (m)")
            corners.append(tuple(float(c) for c in v))
        lo, hi = corners
        if not all(a < b for a, b in zip(lo, hi, strict=True)):
            raise r.fail(f"{key}.max", f"= {list(hi)} must exceed min = {list(lo)} in x, y and z")
        for j, (lo2, hi2) in enumerate(out):
            if all(max(a, c) < min(b, d) - 1e-12 for a, b, c, d in zip(lo, hi, lo2, hi2,
                                                                     strict=True)):
                raise r.fail(key, f"overlaps structure.blocks[{j}] (its mass would count twice)")
        out.append((lo, hi))
    return tuple(out)


def _direction(r: _Reader, item: dict, path: str, body: bool) -> tuple[float, float, float]:
    """A point's unit ``direction`` (required on a body; beams and plates act along +w)."""
    if "direction" not in item:
        if body:
            raise r.fail(f"{path}.direction", "is missing: on a body every gauge, force and "
                         "sensor needs its direction [dx, dy, dz]")
        return UP
    if not body:
        raise r.fail(f"{path}.direction", "applies to a 3-D body only (beams and plates act "
                     "along +w)")
    v = item["direction"]
    if (not isinstance(v, list) or len(v) != 3
            or not all(isinstance(c, int | float) and not isinstance(c, bool)
                       and math.isfinite(c) for c in v)):
        raise r.fail(f"{path}.direction", f"must be [dx, dy, dz], three numbers; found {v!r}")
    norm = math.sqrt(sum(c * c for c in v))
    if norm == 0.0:
        raise r.fail(f"{path}.direction", "must not be zero")
    return tuple(float(c) / norm for c in v)


def parse_rig(doc: dict[str, Any], source: str = "<rig>") -> Rig:
    """Validate a rig given as a parsed TOML document (see :func:`load_rig`)."""
    r = _Reader(source)
    unknown = set(doc) - _KNOWN_TOP
    if unknown:
        raise r.fail(sorted(unknown)[0], "is not a rig key (expected one of "
                     + ", ".join(sorted(_KNOWN_TOP)) + ")")
    name = r.text(doc, "name", "", required=False, default=Path(source).stem)

    st = r.table(doc, "structure")
    kind = r.text(st, "kind", "structure", required=False, default="beam")
    if kind not in KINDS:
        raise r.fail("structure.kind", f"must be 'beam', 'plate' or 'body', found {kind!r}")
    body = kind == "body"
    masses_raw = st.get("masses", [])
    if not isinstance(masses_raw, list):
        raise r.fail("structure.masses", "must be an array of {x, mass} tables")
    if kind == "beam":
        length = r.number(st, "length", "structure", positive=True)
        mpl = r.number(st, "mass_per_length", "structure", positive=True)
        structure_kw = dict(length=length, mass_per_length=mpl)
    elif kind == "plate":
        mpa = r.number(st, "mass_per_area", "structure", positive=True)
        outline = st.get("outline")
        if (not isinstance(outline, list) or len(outline) < 3
                or not all(isinstance(v, list) and len(v) == 2 for v in outline)):
            raise r.fail("structure.outline", "must list at least 3 [x, y] vertices")
        structure_kw = dict(mass_per_area=mpa,
                            outline=tuple((float(a), float(b)) for a, b in outline))
    else:
        structure_kw = dict(density=r.number(st, "density", "structure", positive=True),
                            blocks=_blocks(r, st))
    masses = []
    for k, m in enumerate(masses_raw):
        key = f"structure.masses[{k}]"
        if not isinstance(m, dict):
            raise r.fail(key, "must be a table {x = ..., mass = ...}")
        masses.append(LumpedMass(
            x=r.number(m, "x", key),
            y=r.number(m, "y", key, required=kind != "beam", default=0.0),
            z=r.number(m, "z", key, required=body, default=0.0),
            mass=r.number(m, "mass", key, positive=True),
        ))
    structure = Structure(kind=kind, masses=tuple(masses), **structure_kw)
    for k, m in enumerate(masses):
        if not structure.contains(m.x, m.y, m.z):
            raise r.fail(f"structure.masses[{k}].x", f"= {m.x} lies off the structure")

    def points(key: str, extra: tuple[str, ...]) -> list[dict]:
        items = r.array_of_tables(doc, key)
        out = []
        for k, item in enumerate(items):
            path = f"{key}[{k}]"
            entry = dict(
                name=r.text(item, "name", path),
                x=r.number(item, "x", path),
                y=r.number(item, "y", path, required=kind != "beam", default=0.0),
                z=r.number(item, "z", path, required=body, default=0.0),
                direction=_direction(r, item, path, body),
            )
            for e in extra:
                if e == "gap":
                    entry[e] = r.number(item, "gap", path, required=False, positive=True)
                else:
                    entry[e] = r.number(item, e, path, required=False, default=1.0)
                    if entry[e] == 0.0:
                        raise r.fail(f"{path}.{e}", "must not be zero")
            if not structure.contains(entry["x"], entry["y"], entry["z"]):
                where = {"beam": f"x = {entry['x']} lies off the structure "
                                 f"(0 <= x <= {structure.length})",
                         "plate": f"(x, y) = ({entry['x']}, {entry['y']}) lies outside the "
                                  "outline",
                         "body": f"(x, y, z) = ({entry['x']}, {entry['y']}, {entry['z']}) lies "
                                 "in none of the structure's blocks"}[kind]
                raise r.fail(f"{path}.x", where)
            out.append(entry)
        return out

    gauges = tuple(Gauge(**g) for g in points("gauges", ("scale",)))
    forces = tuple(ForcePoint(**f) for f in points("forces", ("gap",)))
    sensors = tuple(Sensor(**s) for s in points("sensors", ("scale",)))

    act = r.table(doc, "actuator", required=False)
    actuator = Actuator(
        current=r.text(act, "current", "actuator", required=False, default="i"),
        flux=r.text(act, "flux", "actuator", required=False, default=None),
        turns=r.number(act, "turns", "actuator", required=False, positive=True),
        pole_area=r.number(act, "pole_area", "actuator", required=False, positive=True),
        current_scale=r.number(act, "current_scale", "actuator", required=False, default=1.0),
        flux_scale=r.number(act, "flux_scale", "actuator", required=False, default=1.0),
    )
    acq = r.table(doc, "acquisition", required=False)
    frequency = r.number(acq, "frequency", "acquisition", required=False, positive=True)

    # names: unique across every channel kind
    seen: dict[str, str] = {}
    for key, items in (("gauges", gauges), ("forces", forces), ("sensors", sensors)):
        for k, item in enumerate(items):
            if item.name in seen or item.name in ("time", "total"):
                other = seen.get(item.name, "a reserved column name")
                raise r.fail(f"{key}[{k}].name", f"= '{item.name}' is used twice (also {other})")
            seen[item.name] = f"{key}[{k}]"
    if actuator.current in seen:
        raise r.fail("actuator.current", f"= '{actuator.current}' is also {seen[actuator.current]}")

    # statics: gauge count, distinct points
    needed = RIGID_MODES[kind]
    if len(gauges) != needed:
        raise r.fail("gauges", f"has {len(gauges)} entries; a {kind} on statically determinate "
                     f"gauges needs exactly {needed}")
    if not sensors:
        raise r.fail("sensors", "is empty: each harmonic's shape needs at least one "
                     "displacement sensor (no more shapes than sensors)")
    if not forces:
        raise r.fail("forces", "is empty: name at least one force point")
    if len(forces) > len(gauges):
        raise r.fail("forces", f"has {len(forces)} entries; at most {len(gauges)} forces "
                     "(one per gauge) can be determined")
    for key, items in (("gauges", gauges), ("forces", forces), ("sensors", sensors)):
        pts = locations(items)          # on a body, one point may carry two directions
        for a in range(len(items)):
            for b in range(a):
                if np.linalg.norm(pts[a, :3] - pts[b, :3]) < 1e-6 and (
                        not body or np.linalg.norm(pts[a, 3:] - pts[b, 3:]) < 1e-6):
                    raise r.fail(f"{key}[{a}].x", f"puts '{items[a].name}' at the same point as "
                                 f"'{items[b].name}'" + (" in the same direction" if body else ""))
    return Rig(name=name, structure=structure, gauges=gauges, forces=forces, sensors=sensors,
               actuator=actuator, frequency=frequency, source=source)


def rig_to_dict(rig: Rig) -> dict[str, Any]:
    """The rig as a TOML-ready document (inverse of :func:`parse_rig`)."""
    st = rig.structure
    axes = ("x", "y", "z")[:st.dim]
    structure: dict[str, Any] = {"kind": st.kind}
    if st.kind == "plate":
        structure["mass_per_area"] = st.mass_per_area
        structure["outline"] = [list(v) for v in st.outline]
    elif st.kind == "body":
        structure["density"] = st.density
        structure["blocks"] = [{"min": list(lo), "max": list(hi)} for lo, hi in st.blocks]
    else:
        structure["length"] = st.length
        structure["mass_per_length"] = st.mass_per_length
    if st.masses:
        structure["masses"] = [{**{a: getattr(m, a) for a in axes}, "mass": m.mass}
                               for m in st.masses]

    def point(p, extra):
        d = {"name": p.name, **{a: getattr(p, a) for a in axes}}
        if st.kind == "body":
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
    act = {"current": rig.actuator.current}
    for key in ("flux", "turns", "pole_area"):
        v = getattr(rig.actuator, key)
        if v is not None:
            act[key] = v
    doc["actuator"] = act
    if rig.frequency is not None:
        doc["acquisition"] = {"frequency": rig.frequency}
    return doc
