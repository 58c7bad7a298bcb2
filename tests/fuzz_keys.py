"""Key mutations (issue 33): a key misspelt, in the wrong case, moved to another table, an
unknown table, a key written twice, in the rig file (TOML), a spatial model and a calibration
(JSON), at any depth: the top level, every table, every entry of an array of tables.

Nothing a user writes may be silently ignored, so for these input kinds the only right outcome
is a refusal (exit 2, one line, nothing written) that names the file and the mutated key's
dotted path in quotes (``'gauges[1].sacle'``; for an unknown table its own path,
``'acquisiton'``, or a key below it). Exit 0 is *silent*; a refusal that does not name the
key is *unclean* (:func:`names_key`, applied by :func:`fuzz_inputs.run_case`).

A mutation must make a key that the file's schema does not have: each draw is checked against
the keys the harness knows of that table (:data:`RIG`, :data:`MODEL`, :data:`BROADBAND`,
:data:`CALIBRATION`) and every key the document holds in a table of the same pattern
(``gauges[]``); one that lands on a valid key (``x`` replaced by ``y``) is drawn again.

Duplicated keys: TOML forbids a key written twice in a table (tomllib refuses the file). JSON
(RFC 8259) only says that names SHOULD be unique, and ``json.loads`` keeps the last value,
dropping the first without a word. Here a duplicate is wrong in both: forcecal never writes
one, so it is a hand edit, and which of two values was meant cannot be told (parsers differ:
first wins, last wins). The right outcome is a refusal naming the key. The copy carries the
same value, so that no check of a value can refuse the file for another reason.
"""

from __future__ import annotations

import copy
import json
import random
import re
import string
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import tomli_w
from fuzz_mutations import write_file

if TYPE_CHECKING:
    from fuzz_inputs import Case, Lab

KEY_KINDS = ("rig-keys", "model-keys", "cal-keys")
"""Input kinds of key mutations: refused naming the key is the only right outcome."""
FAMILIES = ("misspelt", "case", "moved", "unknown-table", "duplicated")
"""Seed ``s`` of a key kind draws family ``FAMILIES[s % 5]``: five seeds cover them all."""

SENTINEL = "__fuzz_duplicate_key__"
EXTRA_TABLES = ("extra", "options", "settings", "meta", "user", "comment")

KeyPath = tuple[str | int, ...]
"""A key's place in a document: ("gauges", 1, "scale")."""


@dataclass(frozen=True)
class Schema:
    """What the harness knows of a file's keys: per table pattern (``""`` the top level,
    ``gauges[]`` every gauge) its documented keys; and the patterns whose keys are data (a
    harmonic number, an uncertainty source), never mutated, their values walked."""

    known: dict[str, frozenset[str]]
    maps: frozenset[str] = frozenset()

    def pattern(self, path: KeyPath) -> str:
        out = ""
        for p in path:
            if out in self.maps:
                out += ".*"
            elif isinstance(p, int):
                out += "[]"
            else:
                out += f".{p}" if out else p
        return out


def _fs(*names: str) -> frozenset[str]:
    return frozenset(names)


_POINT = ("name", "x", "y", "z", "direction")
RIG = Schema({
    "": _fs("name", "structure", "gauges", "forces", "sensors", "actuator", "acquisition",
            "channels", "uncertainty"),
    "structure": _fs("kind", "length", "mass_per_length", "masses", "outline", "mass_per_area",
                     "blocks", "density"),
    "structure.masses[]": _fs("x", "y", "z", "mass"),
    "structure.blocks[]": _fs("min", "max"),
    "gauges[]": _fs(*_POINT, "scale"),
    "forces[]": _fs(*_POINT, "gap"),
    "sensors[]": _fs(*_POINT, "scale"),
    "actuator": _fs("current", "flux", "turns", "pole_area", "current_scale", "flux_scale"),
    "acquisition": _fs("frequency", "group", "temperature", "mains", "band", "drive",
                       "scan_averages"),
    "channels": _fs("time"),   # and every rig channel: rig_schema
    "uncertainty": _fs("gauge_scale", "probe_scale", "current_scale", "position", "mass", "gap"),
})
_SHAPE = ("order", "criterion", "domain", "family", "basis", "coefficients_re",
          "coefficients_im", "residual_std", "coefficient_covariance", "orders", "score",
          "basis_order", "columns", "components")
_PROVENANCE = {"provenance": _fs("forcecal_version", "created_utc", "command", "python",
                                 "inputs"),
               "provenance.inputs[]": _fs("path", "bytes", "sha256")}
MODEL = Schema({
    "": _fs("format", "source", "f0_hz", "n_points", "gauges", "harmonics", "snr", "dropped",
            "one_shape_serves_all", "similarity_mac", "couplings_re", "couplings_im", "shapes",
            "notes", "set_aside", "rig", "provenance", "scans", "span"),
    "shapes[]": _fs(*_SHAPE),
    "shapes[].components[]": _fs("axis", *_SHAPE),
    "span[]": _fs("harmonic", "shapes", "scans", "couplings_re", "couplings_im"),
    "rig": _fs("sha256", "keys"),
    **_PROVENANCE,
}, maps=_fs("dropped", "rig.keys"))
BROADBAND = Schema({"shapes[]": _fs(*_SHAPE), "coordinates": _fs("re", "im"),
                    "ratios": _fs("re", "im"), **_PROVENANCE}, maps=_fs("rig"))
CALIBRATION = Schema({
    "": _fs("format", "version", "law", "formula", "param_names", "param_units", "params",
            "stderr", "covariance", "n_poles", "current_range", "gap_range", "flux_range",
            "candidates", "chosen", "k_total", "reactions_only", "repeatability",
            "uncertainty", "campaign", "runs", "provenance"),
    **_PROVENANCE,
}, maps=_fs("uncertainty.budget", "uncertainty.k_total.budget"))


def rig_schema(doc: dict[str, Any]) -> Schema:
    """:data:`RIG` with the rig's channels (its gauges', sensors', current's and flux's names)
    as the keys of ``[channels]``."""
    act = doc.get("actuator", {})
    names = [p.get("name") for k in ("gauges", "sensors") for p in doc.get(k, [])]
    names += [act.get("current", "i"), act.get("flux")]
    known = dict(RIG.known)
    known["channels"] = known["channels"] | {n for n in names if isinstance(n, str)}
    return Schema(known, RIG.maps)


# --------------------------------------------------------------------------------------------
# paths


def dotted(path: KeyPath) -> str:
    """``("gauges", 1, "scale")`` -> ``gauges[1].scale``, as messages name a key."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def names_key(line: str, path: str) -> bool:
    """Whether a refusal names ``path`` in quotes (or a key below it: ``'acquisiton.mains'``),
    not merely a key that ends in it (``'acquisition.frequency'`` is not ``'frequency'``)."""
    return re.search("['\"`]" + re.escape(path) + r"(?=['\"`.\[])", line) is not None


def _get(doc: Any, path: KeyPath) -> Any:
    for p in path:
        doc = doc[p]
    return doc


def _tables(doc: Any, schema: Schema, path: KeyPath = ()) -> list[KeyPath]:
    """Every table of ``doc`` whose keys are keys (not a map's data), top level first."""
    out: list[KeyPath] = []
    if isinstance(doc, dict):
        if schema.pattern(path) not in schema.maps:
            out.append(path)
        for k, v in doc.items():
            out += _tables(v, schema, (*path, k))
    elif isinstance(doc, list):
        for k, v in enumerate(doc):
            if isinstance(v, dict | list):
                out += _tables(v, schema, (*path, k))
    return out


def _replace_items(table: dict[str, Any], items: list[tuple[str, Any]]) -> None:
    table.clear()
    table.update(items)


def _rename(table: dict[str, Any], old: str, new: str) -> None:
    """Key ``old`` renamed ``new`` where it stands."""
    _replace_items(table, [(new if k == old else k, v) for k, v in table.items()])


def _insert_after(table: dict[str, Any], after: str, key: str, value: Any) -> None:
    items = list(table.items())
    i = [k for k, _ in items].index(after) + 1
    _replace_items(table, [*items[:i], (key, value), *items[i:]])


# --------------------------------------------------------------------------------------------
# the families


def misspell(word: str, rng: random.Random) -> tuple[str, str]:
    """``word`` with one letter dropped, doubled, swapped with the next or replaced."""
    i = rng.randrange(len(word))
    how = rng.choice(["dropped", "doubled", "swapped", "replaced"])
    if how == "swapped" and len(word) >= 2:
        i = min(i, len(word) - 2)
        return word[:i] + word[i + 1] + word[i] + word[i + 2:], "two letters swapped"
    if how == "dropped":
        return word[:i] + word[i + 1:], "a letter dropped"
    if how == "doubled":
        return word[:i] + word[i] + word[i:], "a letter doubled"
    letter = rng.choice([c for c in string.ascii_lowercase if c != word[i].lower()])
    return word[:i] + letter + word[i + 1:], "a letter replaced"


@dataclass
class _Draw:
    """One document, its tables and their valid keys, and the generator drawing from them."""

    doc: Any
    schema: Schema
    rng: random.Random
    tables: list[KeyPath] = field(default_factory=list)
    valid: dict[str, set[str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.tables = [t for t in _tables(self.doc, self.schema) if _get(self.doc, t)]
        for t in _tables(self.doc, self.schema):
            pat = self.schema.pattern(t)
            self.valid.setdefault(pat, set(self.schema.known.get(pat, ()))).update(
                _get(self.doc, t))

    def is_new(self, table: KeyPath, key: str) -> bool:
        """Whether ``key`` is a key no table of ``table``'s pattern may hold."""
        return bool(key) and key not in self.valid.get(self.schema.pattern(table), set())

    def key(self) -> tuple[KeyPath, str]:
        """A table (each as likely, whatever its depth) and one of its keys."""
        table = self.rng.choice(self.tables)
        return table, self.rng.choice(list(_get(self.doc, table)))


Found = tuple[KeyPath, str, KeyPath | None]
"""A mutation made: the mutated key's path, what was done, the key to write twice (or None)."""


def _misspelt(w: _Draw, doc: Any) -> Found | None:
    table, key = w.key()
    new, how = misspell(key, w.rng)
    if not w.is_new(table, new):
        return None
    _rename(_get(doc, table), key, new)
    return (*table, new), f"{dotted((*table, key))} misspelt {new!r} ({how})", None


def _case(w: _Draw, doc: Any) -> Found | None:
    table, key = w.key()
    new = key.upper() if w.rng.random() < 0.3 else key[:1].swapcase() + key[1:]
    if new == key or not w.is_new(table, new):
        return None
    _rename(_get(doc, table), key, new)
    return (*table, new), f"{dotted((*table, key))} written {new!r}", None


def _moved(w: _Draw, doc: Any) -> Found | None:
    table, key = w.key()
    dest = w.rng.choice(_tables(w.doc, w.schema))
    if dest == table or dest[:len(table) + 1] == (*table, key) or not w.is_new(dest, key):
        return None
    _get(doc, dest)[key] = _get(doc, table).pop(key)
    where = dotted(dest) or "the top level"
    return (*dest, key), f"{dotted((*table, key))} moved into {where}", None


def _unknown_table(w: _Draw, doc: Any) -> Found | None:
    if w.rng.random() < 0.5:  # a table's (or an array of tables') name misspelt
        pairs = [(t, k) for t in w.tables for k, v in _get(w.doc, t).items()
                 if isinstance(v, dict) or (isinstance(v, list) and v
                                            and all(isinstance(x, dict) for x in v))]
        table, key = w.rng.choice(pairs)
        new, how = misspell(key, w.rng)
        if not w.is_new(table, new):
            return None
        _rename(_get(doc, table), key, new)
        return (*table, new), f"table {dotted((*table, key))} misspelt {new!r} ({how})", None
    # an unknown table added: at the top level one time in three (``[extra]``), else anywhere
    table = () if w.rng.random() < 1 / 3 else w.rng.choice(_tables(w.doc, w.schema))
    name = w.rng.choice(EXTRA_TABLES)
    if not w.is_new(table, name):
        return None
    _get(doc, table)[name] = w.rng.choice([{"note": "added by hand"}, {"value": 1.0}, {}])
    return (*table, name), f"unknown table {dotted((*table, name))} added", None


def _duplicated(w: _Draw, doc: Any) -> Found | None:
    table, key = w.key()
    return (*table, key), f"{dotted((*table, key))} written twice", (*table, key)


_DRAWS: dict[str, Callable[[_Draw, Any], Found | None]] = {
    "misspelt": _misspelt, "case": _case, "moved": _moved, "unknown-table": _unknown_table,
    "duplicated": _duplicated}


# --------------------------------------------------------------------------------------------
# writing the mutated file


@dataclass
class KeyMutation:
    family: str
    path: str          # the mutated key's dotted path, which a refusal must name
    what: str
    data: bytes        # the mutated file


def dump(doc: Any, fmt: str, twice: KeyPath | None = None) -> bytes:
    """The document as TOML or JSON text, key ``twice`` written twice (the same value)."""
    if twice is not None:
        doc = copy.deepcopy(doc)
        parent = _get(doc, twice[:-1])
        _insert_after(parent, str(twice[-1]), SENTINEL, copy.deepcopy(parent[twice[-1]]))
    if fmt == "toml":
        text = tomli_w.dumps(doc)
        if twice is not None:
            key = str(twice[-1])
            text = text.replace(SENTINEL, key if re.fullmatch(r"[\w-]+", key, re.ASCII)
                                else json.dumps(key))
    else:
        text = json.dumps(doc, indent=1)
        if twice is not None:
            text = text.replace(json.dumps(SENTINEL), json.dumps(str(twice[-1])))
    return text.encode()


def mutate_keys(doc: Any, schema: Schema, fmt: str, family: str,
                rng: random.Random) -> KeyMutation:
    """One mutation of ``family`` drawn into a copy of ``doc`` (drawn again, up to 200 times,
    while it would make a key the schema has)."""
    draw = _Draw(doc, schema, rng)
    for _ in range(200):
        work = copy.deepcopy(doc)
        found = _DRAWS[family](draw, work)
        if found is not None:
            path, what, twice = found
            return KeyMutation(family, dotted(path), f"{family}: {what}", dump(work, fmt, twice))
    raise RuntimeError(f"no {family} mutation of a key found")


# --------------------------------------------------------------------------------------------
# the lab's rig for key mutations, and the cases


def write_key_rig(root: Path) -> Path:
    """The lab's rig with more of its optional keys given (a gauge's and a probe's scale, the
    actuator's scales, the temperature and the mains, a ``[channels]`` table naming each
    channel as it is): ``ROOT/rig_keys.toml``. Every value is the default's or the truth's, so
    the rig runs as the lab's does."""
    doc = tomllib.loads((root / "rig.toml").read_text(encoding="utf-8"))
    doc["gauges"][1]["scale"] = 1.0
    doc["sensors"][0]["scale"] = 1.0
    doc["actuator"].update(current_scale=1.0, flux_scale=1.0)
    doc["acquisition"].update(temperature=21.5, mains=50.0)
    doc["channels"] = {"time": "time", "R1": "R1", "s2": "s2", "i": "i"}
    path = root / "rig_keys.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path


def key_case(lab: Lab, d: Path, rng: random.Random, kind: str, family: str) -> Case:
    """A case of key kind ``kind`` (:data:`KEY_KINDS`): one ``family`` mutation of the rig
    (read by ``scan`` or ``reconstruct``; one time in four the broadband rig, with its band,
    averages and drive), the model (``reconstruct``; a steady model, or one
    time in four the broadband one) or the calibration (``predict``)."""
    from fuzz_inputs import Case  # fuzz_inputs imports this module

    f = lab.files
    if kind == "rig-keys":
        broadband = rng.random() < 0.25
        target = d / "rig.toml"
        doc = tomllib.loads(f["rig_frf" if broadband else "rig_keys"].read_text(encoding="utf-8"))
        m = mutate_keys(doc, rig_schema(doc), "toml", family, rng)
        out = d / "out"
        if broadband:
            argv = ["reconstruct", str(target), str(f["model_frf"]), str(f["run_csv"]), "-o",
                    str(out)]
        elif rng.random() < 0.7:
            out = d / "model.json"
            argv = ["scan", str(target), str(f["scan_npz"]), "-o", str(out)]
        else:
            argv = ["reconstruct", str(target), str(f["model"]), str(f["run_csv"]), "-o", str(out)]
    elif kind == "model-keys":
        broadband = rng.random() < 0.25
        target = d / "model.json"
        doc = json.loads(f["model_frf" if broadband else "model"].read_bytes())
        m = mutate_keys(doc, BROADBAND if broadband else MODEL, "json", family, rng)
        out = d / "out"
        argv = ["reconstruct", str(f["rig_frf" if broadband else "rig"]), str(target),
                str(f["run_csv"]), "-o", str(out)]
    else:
        target = d / "calibration.json"
        m = mutate_keys(json.loads(f["calibration"].read_bytes()), CALIBRATION, "json", family,
                        rng)
        out = d / "prediction"  # predict writes nothing: a stray file would show here
        argv = ["predict", str(target), "--current", "1.0", "--gap", "0.0009"]
        if rng.random() < 0.5:
            argv.append("--json")
    write_file(target, m.data)
    return Case(kind, 0, m.what, argv, (str(target), target.name), [out], argv[0],
                key=m.path)
