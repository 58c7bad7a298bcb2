"""The rig file: a valid file loads; every fault is a RigError naming the file and the key."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomli_w

from forcecal.errors import InputError, RigError
from forcecal.rig import Actuator, ForcePoint, Gauge, LumpedMass, Sensor, load_rig, rig_to_dict

VALID = """\
name = "reference beam rig"

[structure]
kind = "beam"
length = 0.6
mass_per_length = 3.768
masses = [{ x = 0.30, mass = 0.25 }]

[[gauges]]
name = "R1"
x = 0.0
scale = -1.0

[[gauges]]
name = "R2"
x = 0.6

[[forces]]
name = "F1"
x = 0.25
gap = 1.0e-3

[[forces]]
name = "F2"
x = 0.35
gap = 1.0e-3

[[sensors]]
name = "s1"
x = 0.10
scale = 1.0e-3

[[sensors]]
name = "s2"
x = 0.50

[actuator]
current = "i"
flux = "phi"
turns = 400
pole_area = 4.0e-4

[acquisition]
frequency = 20.0
"""


def write(tmp_path: Path, text: str, name: str = "rig.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def names(path: Path, key: str) -> str:
    """A pattern requiring the file and the key in the message."""
    return f"rig '{re.escape(str(path))}': key '{re.escape(key)}'"


def test_valid_rig_loads(tmp_path):
    path = write(tmp_path, VALID)
    rig = load_rig(path)
    assert rig.name == "reference beam rig" and rig.source == str(path)
    assert rig.structure.kind == "beam"
    assert rig.structure.length == 0.6 and rig.structure.mass_per_length == 3.768
    assert rig.structure.masses == (LumpedMass(x=0.3, mass=0.25),)
    assert rig.structure.total_mass == pytest.approx(0.6 * 3.768 + 0.25)
    assert rig.gauges == (Gauge("R1", 0.0, scale=-1.0), Gauge("R2", 0.6))
    assert rig.forces == (ForcePoint("F1", 0.25, gap=1e-3), ForcePoint("F2", 0.35, gap=1e-3))
    assert rig.sensors == (Sensor("s1", 0.1, scale=1e-3), Sensor("s2", 0.5))
    assert rig.actuator == Actuator(current="i", flux="phi", turns=400.0, pole_area=4e-4)
    assert rig.frequency == 20.0
    assert rig.gauge_names == ["R1", "R2"] and rig.force_names == ["F1", "F2"]


def test_valid_rig_round_trips_through_toml(tmp_path):
    rig = load_rig(write(tmp_path, VALID))
    again = load_rig(write(tmp_path, tomli_w.dumps(rig_to_dict(rig)), "again.toml"))
    assert again.gauges == rig.gauges and again.forces == rig.forces
    assert again.sensors == rig.sensors and again.structure == rig.structure
    assert again.actuator == rig.actuator and again.frequency == rig.frequency


def test_the_weight_table_reads_with_its_default_gravity_and_round_trips(tmp_path):
    rig = load_rig(write(tmp_path, VALID + "\n[weight]\ngauge_zero = 0.2\n"))
    assert (rig.weight.gravity, rig.weight.gauge_zero) == (9.81, 0.2)
    again = load_rig(write(tmp_path, tomli_w.dumps(rig_to_dict(rig)), "again.toml"))
    assert again.weight == rig.weight
    assert load_rig(write(tmp_path, VALID, "plain.toml")).weight is None


# Each case: (what to change in VALID, the key the message must name, what it must say).
FAULTS = {
    "missing key": (("length = 0.6\n", ""), "structure.length", "is missing"),
    "missing table": (("[structure]\nkind = \"beam\"\nlength = 0.6\nmass_per_length = 3.768\n"
                       "masses = [{ x = 0.30, mass = 0.25 }]\n", ""), "structure", "is missing"),
    "wrong type": (("length = 0.6", 'length = "long"'), "structure.length", "must be a number"),
    "not positive": (("mass_per_length = 3.768", "mass_per_length = -3.768"),
                     "structure.mass_per_length", "must be positive"),
    "name not text": (('name = "s2"', "name = 2"), "sensors[1].name",
                      "must be a non-empty string"),
    "gauge off the structure": (("x = 0.6\n\n[[forces]]", "x = 0.7\n\n[[forces]]"),
                                "gauges[1].x", "lies off the structure"),
    "mass off the structure": (("{ x = 0.30, mass", "{ x = -0.30, mass"),
                               "structure.masses[0].x", "lies off the structure"),
    "duplicate names": (('name = "s1"', 'name = "R1"'), "sensors[0].name", "is used twice"),
    "reserved name": (('name = "F2"', 'name = "total"'), "forces[1].name", "is used twice"),
    "two forces at one point": (("x = 0.35", "x = 0.25"), "forces[1].x", "at the same point"),
    "wrong gauge count": (('[[gauges]]\nname = "R2"\nx = 0.6\n',
                           '[[gauges]]\nname = "R2"\nx = 0.6\n\n'
                           '[[gauges]]\nname = "R3"\nx = 0.3\n'),
                          "gauges", "has 3 entries"),
    "unknown top-level key": (("[acquisition]", "[extra]\nvalue = 1\n\n[acquisition]"), "extra",
                              "is not a rig key"),
    "zero scale": (("scale = -1.0", "scale = 0.0"), "gauges[0].scale", "must not be zero"),
    "negative gap": (("gap = 1.0e-3\n\n[[forces]]", "gap = -1.0e-3\n\n[[forces]]"),
                     "forces[0].gap", "must be positive"),
    "no gauges": (('[[gauges]]\nname = "R1"\nx = 0.0\nscale = -1.0\n\n'
                           '[[gauges]]\nname = "R2"\nx = 0.6\n', ""), "gauges", "is missing"),
}


@pytest.mark.parametrize("case", list(FAULTS))
def test_fault_names_file_and_key(tmp_path, case):
    (old, new), key, says = FAULTS[case]
    assert old in VALID, case
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(RigError, match=names(path, key) + ".*" + re.escape(says)):
        load_rig(path)


def test_more_forces_than_gauges(tmp_path):
    text = VALID.replace("[[sensors]]", '[[forces]]\nname = "F3"\nx = 0.45\n\n[[sensors]]', 1)
    path = write(tmp_path, text)
    with pytest.raises(RigError, match=names(path, "forces") + ".*has 3 entries"):
        load_rig(path)


def test_not_toml(tmp_path):
    path = write(tmp_path, VALID + "\nthis is = = not toml\n")
    with pytest.raises(RigError, match=f"rig '{re.escape(str(path))}': not a valid TOML file"):
        load_rig(path)


def test_not_text(tmp_path):
    path = tmp_path / "rig.toml"
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(RigError, match=f"rig '{re.escape(str(path))}': not a valid TOML file"):
        load_rig(path)


def test_file_missing(tmp_path):
    path = tmp_path / "nowhere" / "rig.toml"
    with pytest.raises(RigError, match=f"rig '{re.escape(str(path))}': file not found"):
        load_rig(path)


def test_rig_error_is_an_input_error(tmp_path):
    path = write(tmp_path, VALID.replace("length = 0.6\n", "", 1))
    with pytest.raises(InputError):
        load_rig(path)
    with pytest.raises(ValueError, match=re.escape("structure.length")):
        load_rig(path)


@pytest.mark.parametrize(("old", "new", "key"), [
    ("length = 0.6", "length = 1e300", "structure.length"),
    ("length = 0.6", "length = 1e5", "structure.length"),            # 100 km: not a rig
    ("mass_per_length = 3.768", "mass_per_length = 1e300", "structure.mass_per_length"),
    ("scale = -1.0", "scale = 1e300", "gauges[0].scale"),
    ("length = 0.6", "length = " + "9" * 5000, "rig.toml"),           # beyond int's digits
    ("length = 0.6", "length = " + "9" * 40, "structure.length"),
])
def test_implausible_numbers_are_refused(tmp_path, old, new, key):
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(RigError, match=re.escape(key)):
        load_rig(path)


def test_deep_nesting_is_refused_in_one_line(tmp_path):
    path = write(tmp_path, VALID + "deep = " + "[" * 100_000 + "\n")
    with pytest.raises(RigError, match="not a valid TOML file"):
        load_rig(path)


def test_cores_group_the_poles_that_carry_one_flux(tmp_path):
    """Poles naming one core, or else one flux channel (the actuator's by default), are one
    core's; poles on their own flux channels, or without any, are alone."""
    shared = load_rig(write(tmp_path, VALID))
    assert shared.cores == {"phi": [0, 1]}
    declared = VALID.replace('gap = 1.0e-3\n', 'gap = 1.0e-3\ncore = "U"\n')
    declared = declared.replace('flux = "phi"\n', "")
    assert load_rig(write(tmp_path, declared, "core.toml")).cores == {"U": [0, 1]}
    own = VALID.replace('name = "F2"\n', 'name = "F2"\nflux = "phi2"\n')
    assert load_rig(write(tmp_path, own, "own.toml")).cores == {}
    assert load_rig(write(tmp_path, VALID.replace('flux = "phi"\n', ""), "none.toml")).cores == {}
    again = load_rig(write(tmp_path, tomli_w.dumps(rig_to_dict(load_rig(
        write(tmp_path, declared, "c2.toml")))), "again.toml"))
    assert again.cores == {"U": [0, 1]}
