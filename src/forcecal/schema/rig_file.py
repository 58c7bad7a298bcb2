"""The rig file's schema (INTERFACES.md section 1): every table, key, type, unit, bound and
default, in one place.

:func:`check_rig_document` validates a parsed TOML document against :class:`RigFile`; what the
schema cannot say (a point on the structure, statics, names unique, a key that needs another)
:mod:`forcecal.rig` checks next. :func:`rig_json_schema` is the JSON Schema an editor validates
a rig against as it is typed (shipped as ``rig.schema.json``, written by ``forcecal schema``);
:func:`key_table` is the guide's table of keys, generated from the same classes.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Discriminator, Field, Tag, field_validator
from pydantic.fields import FieldInfo
from pydantic.json_schema import GenerateJsonSchema, JsonSchemaValue

from ..errors import RigError
from .channels import check_channel_names
from .keys import Keys, Number, field_unit, is_array, nearest_key, submodels, validate

__all__ = [
    "SCHEMA_FILE",
    "check_rig_document",
    "key_table",
    "rig_json_schema_text",
]

COORDINATE = 1e4
"""[m] largest magnitude of a coordinate: no laboratory rig reaches 10 km."""
SCALE = 1e9
"""Largest magnitude of a channel's scale (per raw unit)."""

Text = Annotated[str, Field(min_length=1, pattern=r"\S")]
Coordinate = Annotated[float, Number(ge=-COORDINATE, le=COORDINATE)]
Vector3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Vertex = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]


def _coordinate(axis: str) -> Any:
    return Number(unit="m", ge=-COORDINATE, le=COORDINATE, default=None,
                  description=f"{axis} of the point (required where the structure has that "
                              "axis)")


def _nonzero(value: float) -> float:
    if value == 0.0:
        raise ValueError("must not be zero")
    return value


class _Point(Keys):
    name: Text
    """its name, unique across gauges, forces and sensors (`time` and `total` are reserved);
    a gauge's and a sensor's is the run files' column (or mapped in `[channels]`)"""
    x: float = Number(unit="m", ge=-COORDINATE, le=COORDINATE)
    """its position along the beam (x of a point on a plate or a body); on the structure"""
    y: float | None = _coordinate("y")
    z: float | None = _coordinate("z")
    direction: Vector3 | None = Field(None, json_schema_extra={"unit": "1"})
    """body only, and required there: `[dx, dy, dz]`, the measured or applied direction
    (beams and plates act along +w); two gauges of a body may share a point if their
    directions differ"""


class Gauge(_Point):
    noun: ClassVar[str] = "gauge"
    scale: float = Number(ge=-SCALE, le=SCALE, default=1.0)
    """raw value × scale = N acting on the structure in +w (default 1; not 0)"""

    _scale_nonzero = field_validator("scale")(_nonzero)


class ForcePoint(_Point):
    noun: ClassVar[str] = "force"
    gap: float | None = Number(unit="m", ge=1e-7, le=0.1, default=None)
    """the static air gap at that pole with the structure at w = 0"""
    flux: Text | None = None
    """optional: the run files' column of the flux through this pole, where the poles do not
    all carry `actuator.flux` (magnets on their own cores); with `actuator.pole_area` each
    force is checked against Maxwell's stress Φ² / (2 μ0 A)"""
    core: Text | None = None
    """optional: the magnetic circuit this pole belongs to; poles that name one core (a
    U-core's two poles in series on one coil) carry one flux and pull alike, and their forces
    are checked against each other; poles that name one flux channel share a core without it"""


class Sensor(_Point):
    noun: ClassVar[str] = "sensor"
    scale: float = Number(ge=-SCALE, le=SCALE, default=1.0)
    """raw value × scale = m of displacement in +w (default 1; not 0): a probe in mm needs
    `scale = 0.001`"""

    _scale_nonzero = field_validator("scale")(_nonzero)


class LumpedMass(Keys):
    noun: ClassVar[str] = "lumped mass"
    x: float = Number(unit="m", ge=-COORDINATE, le=COORDINATE)
    """its position (with `y`, `z` where the structure has them)"""
    y: float | None = _coordinate("y")
    z: float | None = _coordinate("z")
    mass: float = Number(unit="kg", ge=1e-12, le=1e7)
    """its mass"""


class Beam(Keys):
    noun: ClassVar[str] = "beam"
    kind: Literal["beam"] = "beam"
    """`"beam"` (default): along x from 0 to `length`, on 2 gauges; `"plate"`: in the x-y
    plane, on 3 gauges, every point with `y`; `"body"`: 3-D, on 6 gauges, every point with
    `y`, `z` and `direction`"""
    length: float = Number(unit="m", ge=1e-6, le=COORDINATE)
    """beam: its length"""
    mass_per_length: float = Number(unit="kg/m", ge=1e-9, le=1e6)
    """beam: its distributed mass ρA"""
    masses: list[LumpedMass] = Field(default_factory=list)
    """lumped masses `[{ x = 0.3, mass = 0.25 }]`: armature, probe targets, gauge caps"""


class Plate(Keys):
    noun: ClassVar[str] = "plate"
    kind: Literal["plate"]
    """`"plate"`"""
    mass_per_area: float = Number(unit="kg/m^2", ge=1e-9, le=1e6)
    """plate: its distributed mass ρh"""
    outline: list[Vertex] = Field(min_length=3, json_schema_extra={"unit": "m"})
    """plate: its outline, a polygon of at least 3 `[x, y]` vertices"""
    masses: list[LumpedMass] = Field(default_factory=list)
    """lumped masses `[{ x = 0.3, mass = 0.25 }]`: armature, probe targets, gauge caps"""


class Block(Keys):
    noun: ClassVar[str] = "block"
    min: Vector3 = Field(json_schema_extra={"unit": "m"})
    """the block's lowest corner [x, y, z]"""
    max: Vector3 = Field(json_schema_extra={"unit": "m"})
    """the block's highest corner [x, y, z]"""


class Body(Keys):
    noun: ClassVar[str] = "body"
    kind: Literal["body"]
    """`"body"`"""
    density: float = Number(unit="kg/m^3", ge=1e-6, le=1e6)
    """body: the material's density"""
    blocks: list[Block] = Field(min_length=1)
    """body: axis-aligned boxes `{min = [x, y, z], max = [x, y, z]}` that do not overlap"""
    masses: list[LumpedMass] = Field(default_factory=list)
    """lumped masses `[{ x = 0.3, mass = 0.25 }]`: armature, probe targets, gauge caps"""


def kind(table: Any) -> str | None:
    """The ``structure.kind`` of a table: ``"beam"`` when absent, the kind a misspelt key
    (``knid = "plate"``) names."""
    if not isinstance(table, dict):
        return None
    if "kind" not in table:             # a misspelt kind still names the kind meant
        meant = [v for k, v in table.items() if nearest_key(k, ["kind"]) == "kind"
                 and isinstance(v, str) and v in STRUCTURE_KEYS]
        return meant[0] if meant else "beam"
    value = table["kind"]
    return value if isinstance(value, str) else repr(value)


StructureKeys = Annotated[Annotated[Beam, Tag("beam")] | Annotated[Plate, Tag("plate")]
                          | Annotated[Body, Tag("body")], Discriminator(kind)]
STRUCTURE_KEYS: dict[str, type[Keys]] = {"beam": Beam, "plate": Plate, "body": Body}
"""The declared keys of each ``structure.kind``."""


class Actuator(Keys):
    noun: ClassVar[str] = "actuator"
    current: Text = "i"
    """the run files' column of the coil current (default `"i"`)"""
    current_scale: float = Number(unit="A", ge=-SCALE, le=SCALE, default=1.0)
    """raw value × current_scale = A (default 1)"""
    flux: Text | None = None
    """optional: the run files' column of the flux through one pole"""
    flux_scale: float = Number(unit="Wb", ge=-SCALE, le=SCALE, default=1.0)
    """raw value × flux_scale = Wb (default 1)"""
    turns: float | None = Number(ge=1.0, le=1e7, default=None)
    """optional: the coil's turns N; with `pole_area` the ideal K = μ0 N² A / 4 is reported
    beside the fitted one"""
    pole_area: float | None = Number(unit="m^2", ge=1e-10, le=10.0, default=None)
    """optional: one pole face's area A"""


class Acquisition(Keys):
    noun: ClassVar[str] = "acquisition"
    frequency: float | None = Number(unit="Hz", ge=1e-3, le=1e6, default=None)
    """the nominal drive frequency of a steady drive; the exact one is refined from the data.
    A scan or run whose current sweeps instead (a sweep, a chirp, a stepped sine) is refused
    with the band it covers and the keys to declare (`band`, and `drive = "any"` for runs
    under that drive)"""
    group: Text | None = None
    """the TDMS group, or the HDF5 group's path, the runs are read from when their files have
    several (`--group` overrides it)"""
    band: Annotated[list[Annotated[float, Number(ge=0.0, le=1e6)]],
                    Field(min_length=2, max_length=2)] | None = Field(
        None, json_schema_extra={"unit": "Hz"})
    """optional: `[low, high]`, the band a broadband scan's drive covered (a swept, chirped or
    random current); `scan` then builds a broadband model (the span of the operating shapes
    over the band, [method](method.md) section 10), which serves steady runs at any
    fundamental in the band and runs under any drive"""
    scan_averages: int | None = Field(None, ge=1, le=1_000_000)
    """optional: the number of averages behind a broadband scan's FRFs exported with their
    coherence ([runs](runs.md) section 8); their noise follows from it and the coherence. A
    whole number, 2 or more; needs `band`"""

    @field_validator("scan_averages")
    @classmethod
    def _more_than_one(cls, n: int | None) -> int | None:
        if n == 1:
            raise ValueError("= 1: the coherence of one average is 1 on every line and states "
                             "no noise; FRFs need 2 or more averages")
        return n

    drive: Literal["steady", "any"] = "steady"
    """`"steady"` (default: periodic runs, the harmonic path) or `"any"` (swept, multi-tone
    or random runs: `reconstruct` gives the forces sample by sample; needs `band`)"""
    mains: float | None = Number(unit="Hz", ge=10.0, le=1000.0, default=None,
                                 hint="not a mains frequency (50 or 60)")
    """optional: the mains frequency (50 or 60); `reconstruct` then notes every drive
    harmonic within 3 lines of one of the mains' first 10 harmonics, and with a tare record
    (`--tare`) counts the hum it reads there in that harmonic's uncertainty"""
    temperature: float | None = Number(
        unit="°C", ge=-100.0, le=200.0, default=None,
        hint="not an ambient temperature between -100 and 200 °C (23.0 for 23 °C; not in kelvin)")
    """optional: the ambient temperature of the measurements, stated in the calibration
    certificate's conditions (−100 to 200 °C; not in kelvin)"""


class Uncertainty(Keys):
    noun: ClassVar[str] = "uncertainty"
    gauge_scale: float = Number(unit="1", ge=0.0, le=0.5, default=0.005)
    """type-B relative standard uncertainty of every gauge's sensitivity"""
    probe_scale: float = Number(unit="1", ge=0.0, le=0.5, default=0.01)
    """type-B relative standard uncertainty of every probe's sensitivity"""
    current_scale: float = Number(unit="1", ge=0.0, le=0.5, default=0.002)
    """type-B relative standard uncertainty of the current sensor's sensitivity"""
    position: float = Number(unit="m", ge=0.0, le=0.1, default=0.5e-3)
    """type-B standard uncertainty of every gauge's, force point's and probe's position along
    each axis"""
    mass: float = Number(unit="1", ge=0.0, le=0.5, default=0.01)
    """type-B relative standard uncertainty of the distributed mass and of each lumped mass"""
    gap: float = Number(unit="m", ge=0.0, le=1e-3, default=10e-6)
    """type-B standard uncertainty of each static air gap"""


class Weight(Keys):
    noun: ClassVar[str] = "weight"
    gravity: float = Number(unit="m/s^2", ge=-100.0, le=100.0, default=9.81,
                            hint="not a gravitational acceleration (9.81 m/s^2)")
    """the gravitational acceleration, acting along -w (on a body along -z); negative where
    the structure's +w points down (default 9.81)"""
    gauge_zero: float = Number(unit="N", ge=0.0, le=1e6)
    """type-B standard uncertainty of each gauge's zero (its reading without the structure)"""

    @field_validator("gravity")
    @classmethod
    def _acting(cls, g: float) -> float:
        if g == 0.0:
            raise ValueError("= 0.0 m/s^2: a weight check needs gravity acting (9.81 along -w, "
                             "-9.81 where +w points down)")
        return g


class RigFile(Keys):
    """The rig file."""

    noun: ClassVar[str] = "rig"
    name: Text | None = None
    """a label for reports (default: the file's name)"""
    structure: StructureKeys
    """the structure: its kind, geometry and mass"""
    gauges: list[Gauge]
    """the force gauges, holding the structure statically determinately: exactly 2 for a
    beam, 3 for a plate, 6 for a body"""
    forces: list[ForcePoint]
    """where the unknown forces act (the actuator's poles); at least one, at most one per
    gauge"""
    sensors: list[Sensor]
    """the displacement probes; at least one"""
    actuator: Actuator = Field(default_factory=Actuator)
    """the electromagnet's channels"""
    acquisition: Acquisition = Field(default_factory=Acquisition)
    """how the scan and the runs were driven and recorded"""
    channels: dict[str, Any] = Field(default_factory=dict, json_schema_extra={
        "additionalProperties": {"anyOf": [
            {"type": "string", "minLength": 1},
            {"type": "object", "additionalProperties": False, "required": ["node"],
             "properties": {"node": {"type": "integer", "minimum": 0},
                            "direction": {"anyOf": [{"type": "string"},
                                                    {"type": "integer"}]}}}]}})
    """the run files' name of a gauge, sensor, current or flux channel: `s1 = "cDAQ1Mod1/ai0"`,
    a UFF record `s1 = "node 12 +Z"` or `{ node = 12, direction = "+Z" }`
    ([runs](runs.md)); `time = "Sample Time"` names the time column where it is not `time`,
    `t`, `Zeit`, `X_Value` or `Timestamp`"""
    uncertainty: Uncertainty | None = None
    """type-B standard uncertainties (GUM); without the table the defaults apply and every
    estimate says so in a note"""
    weight: Weight | None = None
    """optional: the gauges were zeroed without the structure on them, so that a zero-current
    record (a tare) reads its weight; every tare is then checked against the rig's masses"""


def check_rig_document(doc: Any, source: str) -> RigFile:
    """A parsed rig file checked against :class:`RigFile`.

    Parameters
    ----------
    doc : object
        What :func:`tomllib.loads` gave.
    source : str
        The file, quoted in every message.

    Returns
    -------
    RigFile

    Raises
    ------
    RigError
        ``rig 'FILE': key 'KEY' WHAT`` for the first fault; an unknown key with the nearest
        valid key.
    """
    _channels_first(doc, source)
    result: RigFile = validate(RigFile, doc, f"rig '{source}'", RigError)
    return result


def _channels_first(doc: Any, source: str) -> None:
    """A ``[channels]`` key that names no channel of the rig, refused before the schema's
    faults: a key moved there from another table leaves a key missing where it came from,
    and the move is the fault to name."""
    if not isinstance(doc, dict) or not all(isinstance(doc.get(k), t) for k, t in (
            ("channels", dict), ("gauges", list), ("sensors", list))):
        return
    act = doc.get("actuator", {})
    forces = doc.get("forces", [])
    tables = [*doc["gauges"], *doc["sensors"], *(forces if isinstance(forces, list) else [])]
    if not isinstance(act, dict) or not all(isinstance(t, dict) for t in tables):
        return                                          # the schema names the fault
    names: list[Any] = [t.get("name") for t in [*doc["gauges"], *doc["sensors"]]]
    names += [act.get("current", "i"), act.get("flux", "time"), "time"]
    names += [t.get("flux", "time") for t in tables]
    if all(isinstance(n, str) for n in names):
        check_channel_names(
            lambda key, what: RigError(f"rig '{source}': key '{key}' {what}"),
            doc["channels"], list(dict.fromkeys(names)))


# --------------------------------------------------------------------------------------------
# the JSON Schema and the guide's table

SCHEMA_FILE = Path(__file__).with_name("rig.schema.json")
"""The rig file's JSON Schema as shipped with the package (``forcecal schema`` writes it)."""


class _TomlSchema(GenerateJsonSchema):
    """JSON Schema for a TOML file: an optional key is absent, never null (TOML has none)."""

    def nullable_schema(self, schema: Any) -> JsonSchemaValue:
        return self.generate_inner(schema["schema"])

    def default_schema(self, schema: Any) -> JsonSchemaValue:
        out = super().default_schema(schema)
        if out.get("default", 0) is None:
            del out["default"]
        return out


def rig_json_schema() -> dict[str, Any]:
    """The rig file's JSON Schema (draft 2020-12), every key with its description and unit.

    Returns
    -------
    dict
    """
    schema = RigFile.model_json_schema(by_alias=True, schema_generator=_TomlSchema)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": "forcecal rig file", **{k: v for k, v in schema.items() if k != "title"}}


def rig_json_schema_text() -> str:
    """:func:`rig_json_schema` as the text shipped in ``rig.schema.json``."""
    return json.dumps(rig_json_schema(), indent=2, ensure_ascii=False) + "\n"


def _one_line(text: str | None) -> str:
    return " ".join((text or "").split()).replace("|", "\\|")


def key_table() -> str:
    """The guide's table of rig keys (Markdown), one row per key in the schema's order, from
    the fields' units and descriptions.

    Returns
    -------
    str
    """
    rows = ["| key | unit | meaning |", "|---|---|---|"]
    seen: set[str] = set()
    for key, info, is_table in _fields(RigFile, ""):
        if key not in seen and not is_table:
            seen.add(key)
            rows.append(f"| `{key}` | {field_unit(info)} | {_one_line(info.description)} |")
    return "\n".join(rows) + "\n"


def _fields(model: type[Keys], path: str) -> Iterator[tuple[str, FieldInfo, bool]]:
    """(dotted key, field, whether it is a table) of every key below ``model``, depth first
    in the declared order; an array of tables as ``key[]``, ``[channels]`` as
    ``channels.<rig channel>``."""
    for name, info in model.model_fields.items():
        key = f"{path}.{name}" if path else name
        subs = submodels(info)
        if key == "channels":
            yield "channels.<rig channel>", info, False
        elif not subs:
            yield key, info, False
        else:
            array = is_array(info)
            yield key + ("[]" if array else ""), info, not array
            for sub in subs:
                yield from _fields(sub, key + ("[]" if array else ""))
