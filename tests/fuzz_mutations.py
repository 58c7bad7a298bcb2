"""Damage to a parsed document or to a file's bytes: the fuzzer's mutators, whatever the
input kind (:mod:`fuzz_inputs` picks the input and the command that reads it)."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

BIG = [0.0, -1.0, 1e300, -1e300, 1e-300, 1e308, float("nan"), float("inf"), float("-inf"),
       1e6, 1e12, -1e-3]


def extreme(rng: random.Random, value: float | None = None) -> float:
    choices = list(BIG)
    if value is not None and value != 0:
        choices += [value * 1e3, value * 1e-3, value * 1e300, -value, value * 1e30]
    return rng.choice(choices)


def _leaves(obj: Any, path: tuple = ()) -> list[tuple]:
    """Paths of every leaf (number, string, bool, None) of a JSON/TOML document."""
    out: list[tuple] = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _leaves(v, (*path, k))
    elif isinstance(obj, list):
        for k, v in enumerate(obj):
            out += _leaves(v, (*path, k))
    else:
        out.append(path)
    return out


def _containers(obj: Any, path: tuple = ()) -> list[tuple]:
    out: list[tuple] = [path]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _containers(v, (*path, k)) if isinstance(v, dict | list) else []
    elif isinstance(obj, list):
        for k, v in enumerate(obj):
            out += _containers(v, (*path, k)) if isinstance(v, dict | list) else []
    return out


def _get(obj: Any, path: tuple) -> Any:
    for p in path:
        obj = obj[p]
    return obj


def _set(obj: Any, path: tuple, value: Any) -> None:
    _get(obj, path[:-1])[path[-1]] = value


def mutate_doc(doc: Any, rng: random.Random, numeric_bias: float = 0.7) -> str:
    """Mutate a parsed document in place; returns a description."""
    leaves = _leaves(doc)
    numeric = [p for p in leaves if isinstance(_get(doc, p), int | float)
               and not isinstance(_get(doc, p), bool)]
    r = rng.random()
    if numeric and r < numeric_bias:
        p = rng.choice(numeric)
        old = _get(doc, p)
        new = extreme(rng, float(old))
        if isinstance(old, int) and rng.random() < 0.5:
            new = rng.choice([0, -1, 999, 10**6, -(10**6), 2**62])
        _set(doc, p, new)
        return f"{'.'.join(map(str, p))} = {new!r} (was {old!r})"
    if r < 0.8 and leaves:
        p = rng.choice(leaves)
        new = rng.choice(["text", "", None, True, [], {}, [1.0, 2.0], "nan", -0.0])
        _set(doc, p, new)
        return f"{'.'.join(map(str, p))} = {new!r}"
    cont = [c for c in _containers(doc) if c and isinstance(_get(doc, c[:-1]), dict | list)]
    if r < 0.9 and cont:
        p = rng.choice(cont)
        parent = _get(doc, p[:-1])
        if isinstance(parent, dict):
            del parent[p[-1]]
            return f"deleted {'.'.join(map(str, p))}"
        value = _get(doc, p)
        if isinstance(value, list):
            if value and rng.random() < 0.5:
                value.append(value[-1])
                return f"{'.'.join(map(str, p))}: last item repeated"
            value.clear()
            return f"{'.'.join(map(str, p))} = []"
        return "no-op"
    paths = [p for p in leaves if p]
    if paths:
        p = rng.choice(paths)
        parent = _get(doc, p[:-1])
        if isinstance(parent, dict):
            del parent[p[-1]]
            return f"deleted {'.'.join(map(str, p))}"
        parent.pop(p[-1])
        return f"removed item {'.'.join(map(str, p))}"
    return "no-op"


def text_mutation(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Byte-level damage: flips, truncation, deep nesting, a huge number."""
    r = rng.random()
    if r < 0.3:
        n = rng.choice([1, 5, 50])
        buf = bytearray(data)
        for _ in range(n):
            k = rng.randrange(len(buf))
            buf[k] = rng.randrange(256)
        return bytes(buf), f"{n} random bytes"
    if r < 0.5:
        cut = rng.randrange(len(data))
        return data[:cut], f"truncated at byte {cut}"
    if r < 0.6:
        return data + b"\n" + b"[" * 100_000 + b"\n", "100000 brackets appended"
    if r < 0.7:
        return b"x = " + b"[" * 100_000 + b"\n", "100000 nested brackets"
    if r < 0.8:
        return data.replace(b"0.", b"9" * 5000 + b".", 1), "a 5000-digit number"
    if r < 0.9:
        return b"", "empty file"
    return data + b"\xff\xfe garbage \x00", "trailing binary garbage"


def write_file(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path
