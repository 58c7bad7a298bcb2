"""Declared keys: the base of every file schema, and the one reader that turns a validation
failure into forcecal's one-line message.

A schema is a tree of :class:`Keys` classes (pydantic models that refuse unknown keys and
coerce nothing: a string is not a number, a boolean not a whole number). :func:`validate`
checks a decoded document against one and raises the caller's error class with the message
``LABEL: key 'DOTTED.KEY' WHAT``: the file, the key in the document's own spelling
(``gauges[0].scale``), what was expected and what was found. An unknown key is named with
the nearest key of its table ("did you mean 'scale'?") or the table it belongs to.

pydantic is the validation library: its models declare types, bounds, defaults and
descriptions in one place, validate fast in compiled code, and write the JSON Schema an editor
checks a file against as it is typed.
"""

from __future__ import annotations

import difflib
import re
import types
import typing
from collections.abc import Iterator
from typing import Annotated, Any, ClassVar, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError
from pydantic.fields import FieldInfo

from ..errors import InputError

__all__ = ["Keys", "Number", "nearest_key", "short", "validate"]


class Keys(BaseModel):
    """One table of a file: its keys declared, every other key refused.

    Subclasses set :attr:`noun`, the name of one entry in messages ("gauge": "is not a gauge
    key").
    """

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True,
                              populate_by_name=True, use_attribute_docstrings=True)
    noun: ClassVar[str] = "table"


K = TypeVar("K", bound=Keys)


def Number(*, unit: str = "", ge: float | None = None, le: float | None = None,
           gt: float | None = None, hint: str = "", description: str | None = None,
           default: Any = ...) -> Any:
    """A finite number with its bounds and unit, as a field of a :class:`Keys` (its
    description is the attribute's docstring).

    A bound broken reads as a unit mistake (``= 1000.0 m is implausibly large (at most 1e4 m;
    a unit mistake?)``), or as ``= VALUE UNIT is HINT`` when ``hint`` is given; a value at or
    below zero under a positive lower bound, or ``gt=0``, as "must be positive"."""
    extra: dict[str, Any] = {"unit": unit} if unit else {}
    if hint:
        extra["hint"] = hint
    return Field(default, ge=ge, le=le, gt=gt, allow_inf_nan=False, description=description,
                 json_schema_extra=extra or None)


def _extra(info: FieldInfo | None, name: str) -> str:
    extra = info.json_schema_extra if info is not None else None
    return str(extra.get(name, "")) if isinstance(extra, dict) else ""


def field_unit(info: FieldInfo | None) -> str:
    """The unit a field declares (``""`` when none)."""
    return _extra(info, "unit")


# --------------------------------------------------------------------------------------------
# walking a schema along an error's location


def _unwrap(tp: Any) -> Any:
    while typing.get_origin(tp) is Annotated:
        tp = typing.get_args(tp)[0]
    return tp


def _members(tp: Any) -> list[Any]:
    """The alternatives of a union (itself when not one), None dropped."""
    tp = _unwrap(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return [_unwrap(a) for a in typing.get_args(tp) if a is not type(None)]
    return [tp]


def _tags(tp: Any) -> dict[str, Any]:
    """A tagged union's tags and their classes (``{}`` when ``tp`` is not one)."""
    tp = typing.get_args(tp)[0] if typing.get_origin(tp) is Annotated else tp
    out: dict[str, Any] = {}
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        for a in typing.get_args(tp):
            if typing.get_origin(a) is Annotated:
                for meta in typing.get_args(a)[1:]:
                    tag = getattr(meta, "tag", None)
                    if isinstance(tag, str):
                        out[tag] = typing.get_args(a)[0]
    return out


def _step(tp: Any, part: str | int) -> tuple[Any, FieldInfo | None, bool]:
    """What lies at ``part`` below ``tp``: (its type, its field, whether ``part`` was a tag of
    a tagged union rather than a key)."""
    tags = _tags(tp)
    if isinstance(part, str) and part in tags:
        return tags[part], None, True
    for m in _members(tp):
        origin = typing.get_origin(m)
        if isinstance(m, type) and issubclass(m, BaseModel) and isinstance(part, str):
            info = m.model_fields.get(part) or next(
                (f for f in m.model_fields.values() if f.alias == part), None)
            if info is not None:
                return info.annotation, info, False
        elif origin in (list, tuple) and isinstance(part, int):
            args = typing.get_args(m)
            return (args[0] if origin is list or (len(args) == 2 and args[1] is Ellipsis)
                    else args[min(part, len(args) - 1)]), None, False
        elif origin is dict and isinstance(part, str):
            return typing.get_args(m)[1], None, False
    return None, None, False


def _walk(root: type[Keys], loc: tuple[str | int, ...]) -> tuple[str, Any, Any, FieldInfo | None]:
    """Along ``loc``: the dotted key (tags dropped), the type holding the last part, the last
    part's type and its field."""
    dotted = ""
    parent: Any = root
    here: Any = root
    info: FieldInfo | None = None
    for part in loc:
        nxt, nxt_info, is_tag = _step(here, part)
        if is_tag:
            here = nxt
            continue
        parent, here, info = here, nxt, nxt_info
        dotted += f"[{part}]" if isinstance(part, int) else (f".{part}" if dotted else part)
    return dotted, parent, here, info


def _model(tp: Any) -> type[Keys] | None:
    for m in _members(tp):
        if isinstance(m, type) and issubclass(m, Keys):
            return m
    return None


def submodels(info: FieldInfo) -> list[type[Keys]]:
    """The tables a field holds: one, one per kind of a tagged union, or none."""
    tags = _tags(info.annotation)
    subs = list(tags.values()) if tags else [info.annotation]
    out = []
    for sub in subs:
        inner = _unwrap(sub)
        for m in _members(inner):
            if typing.get_origin(m) in (list, tuple):
                inner = typing.get_args(m)[0]
        model = _model(inner)
        if model is not None:
            out.append(model)
    return out


def is_array(info: FieldInfo) -> bool:
    """Whether a field is an array (of tables or of values)."""
    return any(typing.get_origin(m) in (list, tuple) for m in _members(info.annotation))


def all_tables(root: type[Keys], path: str = "") -> Iterator[tuple[str, type[Keys]]]:
    """Every table of a schema with its dotted path (arrays as ``key[]``)."""
    yield path, root
    for name, info in root.model_fields.items():
        key = (info.alias or name) + ("[]" if is_array(info) else "")
        for model in submodels(info):
            yield from all_tables(model, f"{path}.{key}" if path else key)


def _keys_of(model: type[Keys]) -> list[str]:
    return [info.alias or name for name, info in model.model_fields.items()]


def nearest_key(word: str, keys: list[str]) -> str | None:
    """The key of ``keys`` nearest to ``word`` (case ignored), or None when none is near."""
    by_lower = {k.lower(): k for k in keys}
    match = difflib.get_close_matches(word.lower(), list(by_lower), n=1, cutoff=0.6)
    if match:
        return by_lower[match[0]]
    swapped = [k for low, k in by_lower.items() if sorted(low) == sorted(word.lower())]
    return swapped[0] if swapped else None          # two letters swapped in a short key


# --------------------------------------------------------------------------------------------
# messages


def short(value: Any) -> str:
    """``value`` for a message: its repr, cut to 40 characters (a huge integer by its bits)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


_TYPES = {"float": "a number", "int": "a whole number", "string": "a non-empty string",
          "bool": "true or false", "list": "a list", "tuple": "a list", "dict": "a table",
          "model": "a table", "model_attributes": "a table", "dataclass": "a table"}


def _unknown(root: type[Keys], key: str, parent: Any, name: str) -> str:
    model = _model(parent) or root
    keys = _keys_of(model)
    here = re.sub(r"\[\d+\]", "[]", key.rpartition(".")[0] if "." in key else "")
    expected = f"expected one of {', '.join(keys)}"
    tables = [(path, other) for path, other in all_tables(root)
              if name in _keys_of(other) and other is not model]
    for path, other in tables:
        if path == here:                     # a key of another kind of this table
            return (f"is not {_article(model.noun)} key (it is {_article(other.noun)}'s); "
                    f"{expected}")
    near = nearest_key(name, keys)
    if near is not None:
        return f"is not {_article(model.noun)} key; did you mean '{near}'?"
    for path, _ in tables:
        where = (f"[[{path[:-2]}]]" if path.endswith("[]") and "." not in path
                 else f"[{path}]" if path else "the top level")
        return f"is not {_article(model.noun)} key; it belongs in {where}"
    return f"is not {_article(model.noun)} key ({expected})"


def _article(noun: str) -> str:
    return f"an {noun}" if noun[:1] in "aeiou" else f"a {noun}"


def _what(root: type[Keys], err: dict[str, Any]) -> tuple[str, str]:
    """(dotted key, what is wrong) of one pydantic error."""
    fault, loc, value = err["type"], tuple(err["loc"]), err.get("input")
    ctx = err.get("ctx") or {}
    key, parent, here, info = _walk(root, loc)
    if fault == "extra_forbidden":
        return key, _unknown(root, key, parent, str(loc[-1]))
    if fault == "missing":
        return key, "is missing"
    if fault in ("union_tag_invalid", "literal_error"):
        expected = ctx.get("expected_tags") or ctx.get("expected", "")
        if fault == "union_tag_invalid":
            tag = str(ctx.get("discriminator", "")).strip("'").removesuffix("()")
            key, value = f"{key}.{tag}".strip("."), ctx.get("tag")
        return key, f"must be one of {expected}, found {short(value)}"
    if fault == "union_tag_not_found":
        return key, f"must be a table, found {short(value)}"
    if fault == "finite_number":
        return key, f"must be finite, found {value!r}"
    if fault.startswith(("greater_than", "less_than")):
        return key, _bound(fault, value, ctx, info)
    if fault == "string_too_short":
        return key, f"must be a non-empty string, found {value!r}"
    if fault in ("too_short", "too_long"):
        lengths = _lengths(info.annotation if info is not None else here)
        return key, f"has {ctx.get('actual_length')} entries; {_expected_length(lengths or ctx)}"
    if fault == "value_error":
        return key, str(ctx.get("error", err.get("msg", "")))
    base = fault.removesuffix("_type").removesuffix("_parsing")
    if base in _TYPES:
        expected = _TYPES["model" if _model(here) else base]
        return key, f"must be {expected}, found {short(value)}"
    return key, f"is not valid ({err.get('msg', fault)}), found {short(value)}"


def _bound(fault: str, value: Any, ctx: dict[str, Any], info: FieldInfo | None) -> str:
    """What a number beyond its bound is: not positive, negative, or a unit mistake."""
    unit = field_unit(info)
    u = f" {unit}" if unit and unit != "1" else ""
    bound = float(ctx.get("gt", ctx.get("ge", ctx.get("lt", ctx.get("le", 0.0)))))
    below = fault.startswith("greater_than")
    if below and isinstance(value, int | float) and value <= 0 and (
            bound > 0 or fault == "greater_than"):
        return f"must be positive, found {short(value)}"
    if below and bound == 0:
        return f"must not be negative, found {short(value)}"
    hint = _extra(info, "hint")
    if hint:
        return f"= {short(value)}{u} is {hint}"
    size, side = ("small", "at least") if below else ("large", "at most")
    return f"= {short(value)}{u} is implausibly {size} ({side} {bound:g}{u}; a unit mistake?)"


def _expected_length(ctx: dict[str, Any]) -> str:
    lo, hi = ctx.get("min_length"), ctx.get("max_length")
    if lo is not None and lo == hi:
        return f"expected {lo}"
    return f"expected at least {lo}" if lo is not None else f"expected at most {hi}"


def _lengths(tp: Any) -> dict[str, Any]:
    """The min_length and max_length an annotation declares ({} when none)."""
    for m in [tp, *typing.get_args(_unwrap(tp))]:
        if typing.get_origin(m) is Annotated:
            for meta in typing.get_args(m)[1:]:
                for c in getattr(meta, "metadata", [meta]):
                    if hasattr(c, "min_length") or hasattr(c, "max_length"):
                        out = {"min_length": getattr(c, "min_length", None)}
                        for c2 in getattr(meta, "metadata", [meta]):
                            if hasattr(c2, "max_length"):
                                out["max_length"] = c2.max_length
                        return out
    return {}




def validate(model: type[K], doc: Any, label: str,
             error: type[InputError] = InputError) -> K:
    """``doc`` checked against ``model``.

    Parameters
    ----------
    model : type
        A :class:`Keys` class (the root table of a file).
    doc : object
        The decoded document.
    label : str
        How messages name the file: ``"rig 'lab/rig.toml'"``.
    error : type
        The error class raised.

    Returns
    -------
    The validated document.

    Raises
    ------
    InputError (or ``error``)
        ``LABEL: key 'KEY' WHAT`` for the first fault (see the module docstring).
    """
    if not isinstance(doc, dict):
        raise error(f"{label}: expected a table of keys, found {short(doc)}")
    try:
        return model.model_validate(doc)
    except ValidationError as exc:
        # unknown keys first: a misspelt key explains the key then missing
        errors = sorted(exc.errors(include_url=False),
                        key=lambda e: e["type"] != "extra_forbidden")
        key, what = _what(model, dict(errors[0]))
        raise error(f"{label}: key '{key}' {what}" if key else f"{label}: {what}") from None

