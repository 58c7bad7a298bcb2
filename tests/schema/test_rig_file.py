"""The rig file's schema: every documented key, misspelt or in the wrong case, in every table
and every array entry, is refused naming the file, the key and the nearest valid key; the
guide's table and the shipped JSON Schema are the schema's own."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import jsonschema
import pytest

from forcecal.cli import main
from forcecal.errors import RigError
from forcecal.rig import load_rig, parse_rig
from forcecal.schema.rig_file import (
    SCHEMA_FILE,
    key_table,
    rig_json_schema,
    rig_json_schema_text,
)

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide.md"

POINT = {"name": "", "x": 0.0}
BEAM = {
    "name": "beam with every optional key",
    "structure": {"kind": "beam", "length": 0.6, "mass_per_length": 3.768,
                  "masses": [{"x": 0.3, "mass": 0.25}]},
    "gauges": [{"name": "R1", "x": 0.0, "scale": -1.0}, {"name": "R2", "x": 0.6}],
    "forces": [{"name": "F1", "x": 0.25, "gap": 1e-3, "core": "U"},
               {"name": "F2", "x": 0.35, "gap": 1e-3, "flux": "phi2"}],
    "sensors": [{"name": "s1", "x": 0.1, "scale": 1e-3}, {"name": "s2", "x": 0.5}],
    "actuator": {"current": "i", "current_scale": 0.1, "flux": "phi", "flux_scale": 1e-3,
                 "turns": 200, "pole_area": 4e-4},
    "acquisition": {"frequency": 60.0, "group": "runs", "band": [10.0, 200.0],
                    "scan_averages": 8, "drive": "any", "mains": 50.0, "temperature": 22.5},
    "channels": {"s1": "cDAQ1Mod1/ai0", "s2": {"node": 12, "direction": "+Z"},
                 "time": "Sample Time"},
    "uncertainty": {"gauge_scale": 0.005, "probe_scale": 0.01, "current_scale": 0.002,
                    "position": 5e-4, "mass": 0.01, "gap": 1e-5},
    "weight": {"gravity": 9.81, "gauge_zero": 0.05},
}
PLATE = {
    "structure": {"kind": "plate", "mass_per_area": 7.85,
                  "outline": [[0.0, 0.0], [0.4, 0.0], [0.4, 0.3], [0.0, 0.3]],
                  "masses": [{"x": 0.2, "y": 0.1, "mass": 0.1}]},
    "gauges": [{"name": "R1", "x": 0.02, "y": 0.02}, {"name": "R2", "x": 0.38, "y": 0.02},
               {"name": "R3", "x": 0.2, "y": 0.28}],
    "forces": [{"name": "F1", "x": 0.2, "y": 0.15}],
    "sensors": [{"name": "s1", "x": 0.1, "y": 0.1}],
}
BODY = {
    "structure": {"kind": "body", "density": 7800.0,
                  "blocks": [{"min": [0.0, 0.0, 0.0], "max": [0.2, 0.1, 0.05]}],
                  "masses": [{"x": 0.1, "y": 0.05, "z": 0.05, "mass": 0.2}]},
    "gauges": [{"name": f"R{k + 1}", "x": x, "y": y, "z": z, "direction": d}
               for k, (x, y, z, d) in enumerate([
                   (0.0, 0.0, 0.0, [0, 0, 1]), (0.2, 0.0, 0.0, [0, 0, 1]),
                   (0.0, 0.1, 0.0, [0, 0, 1]), (0.0, 0.0, 0.025, [1, 0, 0]),
                   (0.0, 0.1, 0.025, [1, 0, 0]), (0.1, 0.0, 0.025, [0, 1, 0])])],
    "forces": [{"name": "F1", "x": 0.1, "y": 0.05, "z": 0.05, "direction": [0, 0, -1]}],
    "sensors": [{"name": "s1", "x": 0.15, "y": 0.05, "z": 0.05, "direction": [0, 0, 1]}],
}
DOCS = {"beam": BEAM, "plate": PLATE, "body": BODY}


def _key_paths(obj, path=()):
    """Every key of a document with its path: (path of its table, key)."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield path, k
            yield from _key_paths(v, (*path, k))
    elif isinstance(obj, list):
        for k, v in enumerate(obj):
            yield from _key_paths(v, (*path, k))


def _dotted(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def _misspelt(key: str) -> list[str]:
    """A key misspelt (a letter doubled, then two letters swapped) and in another case."""
    doubled = key[:-1] + key[-1] * 2 if len(key) < 4 else key[:2] + key[2] + key[2:]
    swapped = key[:1] + key[2] + key[1] + key[3:] if len(key) >= 4 else doubled
    return list(dict.fromkeys([doubled, swapped, key.capitalize() if key.islower()
                               else key.lower()]))


def _renamed(doc, path, old, new):
    out = copy.deepcopy(doc)
    table = out
    for p in path:
        table = table[p]
    table[new] = table.pop(old)        # the misspelt key goes last, as if typed at the end
    return out


CASES = [(kind, path, key, wrong) for kind, doc in DOCS.items()
         for path, key in _key_paths(doc) for wrong in _misspelt(key) if wrong != key]


@pytest.mark.parametrize("kind", list(DOCS))
def test_every_document_is_valid(kind):
    parse_rig(copy.deepcopy(DOCS[kind]), source=f"{kind}.toml")


def test_every_key_misspelt_is_refused_naming_the_nearest():
    """Every key in every table and array entry, misspelt and in the wrong case (achieved:
    every case refused with its key and the original suggested)."""
    failures = []
    for kind, path, key, wrong in CASES:
        source = f"{kind}.toml"
        bad = _renamed(DOCS[kind], path, key, wrong)
        try:
            parse_rig(bad, source=source)
        except RigError as exc:
            said = str(exc)
            dotted = _dotted((*path, wrong))
            if not (said.startswith(f"rig '{source}': key '{dotted}' ")
                    and f"did you mean '{key}'?" in said):
                failures.append(f"{dotted}: {said}")
        else:
            failures.append(f"{_dotted((*path, wrong))}: accepted")
    assert not failures, "\n".join(failures[:10])
    assert len(CASES) > 150


def _pattern(path, key) -> str:
    """A key's row in the guide's table: arrays as ``[]``, a channel as ``<rig channel>``."""
    if path[:1] == ("channels",):
        return "channels.<rig channel>"
    return re.sub(r"\[\d+\]", "[]", _dotted((*path, key)))


def test_the_cases_cover_every_documented_key():
    documented = {re.sub(r"\[\]$", "", m) for m in
                  re.findall(r"^\| `([^`]+)` \|", key_table(), flags=re.MULTILINE)}
    covered = {re.sub(r"\[\]$", "", _pattern(path, key)) for _, path, key, _ in CASES}
    assert documented <= covered, sorted(documented - covered)


@pytest.mark.parametrize(("edit", "key", "says"), [
    (lambda d: d["structure"].update(frequency=50.0), "structure.frequency",
     "is not a beam key; it belongs in [acquisition]"),
    (lambda d: d["gauges"][1].update(gap=1e-3), "gauges[1].gap",
     "is not a gauge key; it belongs in [[forces]]"),
    (lambda d: d.update(acquisiton={"mains": 50.0}), "acquisiton",
     "is not a rig key; did you mean 'acquisition'?"),
    (lambda d: d.update(extra={"value": 1}), "extra", "is not a rig key (expected one of name"),
    (lambda d: d["structure"].update(outline=[[0, 0], [1, 0], [0, 1]]), "structure.outline",
     "is not a beam key (it is a plate's)"),
    (lambda d: d["channels"].update(S1x="ai3"), "channels.S1x",
     "is not a channel of the rig; did you mean 's1'?"),
    (lambda d: d["channels"]["s2"].update(nod=3), "channels.s2.nod",
     "is not a key of a node channel; did you mean 'node'?"),
])
def test_moved_and_unknown_keys_point_to_their_place(edit, key, says):
    doc = copy.deepcopy(BEAM)
    edit(doc)
    with pytest.raises(RigError, match=re.escape(f"rig 'r.toml': key '{key}' {says}")):
        parse_rig(doc, source="r.toml")


def test_a_misspelt_key_on_the_command_line_exits_2_and_writes_nothing(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    rig.write_text('[structure]\nlength = 0.6\nmass_per_length = 3.7\n\n[[gauges]]\nname = "R1"'
                   '\nx = 0.0\nsacle = -1.0\n', encoding="utf-8")
    out = tmp_path / "model.json"
    assert main(["scan", "-q", str(rig), str(tmp_path / "scan.uff"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"forcecal: rig '{rig}': key 'gauges[0].sacle' is not a gauge key; "
                   "did you mean 'scale'?")
    assert not out.exists()


def test_the_guide_table_is_the_schema():
    text = GUIDE.read_text(encoding="utf-8")
    table = re.search(r"<!-- rig keys:[^\n]*-->\n(.*?)<!-- end of rig keys -->", text, re.S)
    assert table is not None, "docs/guide.md has lost its generated table of rig keys"
    assert table.group(1) == key_table(), "regenerate it: forcecal schema --keys"


def test_the_shipped_json_schema_is_the_schema_and_checks_a_rig(tmp_path, capsys):
    assert SCHEMA_FILE.read_text(encoding="utf-8") == rig_json_schema_text(), \
        "regenerate it: forcecal schema src/forcecal/schema/rig.schema.json"
    validator = jsonschema.Draft202012Validator(rig_json_schema())
    for doc in DOCS.values():
        assert not list(validator.iter_errors(doc))
    bad = _renamed(BEAM, ("gauges", 0), "scale", "sacle")
    assert any("sacle" in e.message for e in validator.iter_errors(bad))
    assert main(["schema", str(tmp_path / "rig.schema.json")]) == 0
    assert json.loads((tmp_path / "rig.schema.json").read_text()) == rig_json_schema()
    capsys.readouterr()
    assert main(["schema", "--keys"]) == 0
    assert capsys.readouterr().out == key_table()


@pytest.mark.parametrize(("text", "key", "line"), [
    ("[structure]\nlength = 0.6\nmass_per_length = 3.7\nlength = 0.6\n", "structure.length", 4),
    ('forces = [\n  { name = "F1", x = 0.2 },\n  { name = "F2", x = 0.3, x = 0.3 },\n]\n',
     "forces[1].x", 3),
    ('[[gauges]]\nname = "R1"\n\n[[gauges]]\nname = "R2"\nscale = 1.0\nscale = 1.0\n',
     "gauges[1].scale", 7),
    ('[channels]\ns2 = { node = 12, node = 13 }\n', "channels.s2.node", 2),
    ("[acquisition]\nmains = 50\n\n[acquisition]\n", "acquisition", 4),
])
def test_a_key_written_twice_is_named(tmp_path, text, key, line):
    """The TOML parser refuses a key written twice with a line and a column only."""
    path = tmp_path / "rig.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(RigError, match=re.escape(f"rig '{path}': key '{key}' is written twice "
                                                 f"(line {line}, column")):
        load_rig(path)


def test_a_key_moved_into_channels_is_named_there():
    doc = copy.deepcopy(BEAM)
    doc["channels"]["x"] = doc["forces"][1].pop("x")
    with pytest.raises(RigError, match=re.escape("key 'channels.x' is not a channel of the rig")):
        parse_rig(doc, source="r.toml")
