"""What the JSON files forcecal reads back share (a spatial model, a calibration): the largest
file read, JSON's own numbers only (no NaN or Infinity), no name written twice in an object,
the number types and the provenance their schemas declare, and the checks across keys a
declared schema cannot state (sizes that must agree, a covariance, a range's order), each
fault one line ``LABEL: key 'KEY' WHAT`` (INTERFACES.md section 5).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Annotated, Any

from pydantic import ConfigDict, Field

from ..errors import InputError
from .keys import Keys, Number, nearest_key, short

__all__ = ["MAX_DOCUMENT_BYTES", "reject_constant"]

MAX_DOCUMENT_BYTES = 200_000_000
"""Largest model or calibration file read."""
MAX_NUMBER = 1e30
"""Largest magnitude of any number in a model or calibration file."""

Finite = Annotated[float, Number(ge=-MAX_NUMBER, le=MAX_NUMBER)]
"""A finite number of a model or calibration file."""
NonNegative = Annotated[float, Number(ge=0.0, le=MAX_NUMBER)]
"""A finite number, zero or above (a standard deviation, a score)."""
Matrix = list[list[Finite]]
"""Rows of finite numbers (their sizes checked by :meth:`Faults.matrix`)."""


class Table(Keys):
    """A table of a JSON file forcecal writes: its validator is built at the first document
    checked, not at import (most commands that import a reader read no file of its kind)."""

    model_config = ConfigDict(defer_build=True)


class InputFile(Table):
    """One input file of a result."""

    noun = "input"
    path: str
    """The file."""
    bytes: int | None = Field(None, ge=0)
    """Its size (absent when it was not a file)."""
    sha256: str | None = None
    """SHA-256 of its bytes."""


class Provenance(Table):
    """Where a result comes from (:func:`forcecal.provenance.provenance`)."""

    noun = "provenance"
    forcecal_version: str
    """The forcecal that wrote it."""
    created_utc: str
    """When (ISO 8601)."""
    command: str
    """The command line, shell-quoted."""
    python: str
    """Python's version."""
    inputs: list[InputFile]
    """The input files."""


def reject_constant(name: str) -> float:
    """``parse_constant`` for :func:`json.loads`: JSON has no NaN or Infinity, refuse them."""
    raise ValueError(f"{name} is not a JSON number")


class _Twice(dict[str, Any]):
    """A decoded JSON object that held ``twice``, a name written twice."""

    twice = ""


def object_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` for :func:`json.loads`: an object as a dict, one that holds a name
    twice marked (:func:`json.loads` alone keeps the last value without a word; which of the two
    was meant cannot be told), for :meth:`Faults.written_twice` to name."""
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    marked, seen = _Twice(out), set()
    for k, _ in pairs:
        if k in seen:
            marked.twice = k
            break
        seen.add(k)
    return marked


def _first_twice(doc: Any) -> str | None:
    """The dotted key of the first name written twice in ``doc``, in document order (walked
    without recursion: a document may be nested as deep as the JSON decoder allows)."""
    stack: list[tuple[Any, str]] = [(doc, "")]
    while stack:
        value, key = stack.pop()
        if isinstance(value, _Twice):
            return f"{key}.{value.twice}" if key else value.twice
        if isinstance(value, dict):
            items = [(v, f"{key}.{k}" if key else str(k)) for k, v in value.items()
                     if isinstance(v, dict | list)]
        elif isinstance(value, list) and value and isinstance(value[0], dict | list):
            items = [(v, f"{key}[{k}]") for k, v in enumerate(value)]
        else:
            continue
        stack.extend(reversed(items))
    return None


def opened(doc: Any, label: str, key: str, expected: str, what: str = "") -> Faults:
    """The checks of a document's opening, before its schema: a JSON object, no key written
    twice, and its identifying ``key`` (absent, or ``expected``): another file's keys are not
    this one's to name.

    Returns
    -------
    Faults
        The document's checks, for what follows its schema.

    Raises
    ------
    InputError
    """
    if not isinstance(doc, dict):
        raise InputError(f"{label}: expected a JSON object, found {short(doc)}")
    f = Faults(label)
    f.written_twice(doc)
    found = doc.get(key, expected)
    if found != expected:
        raise f.fail(key, f"= {short(found)}; expected {expected!r}{what}")
    return f


class Faults:
    """The checks across the keys of one document, after its schema: each fault an
    :class:`~forcecal.errors.InputError` ``LABEL: key 'KEY' WHAT``.

    Parameters
    ----------
    label : str
        How messages name the file: ``"model 'MODEL.json'"``.
    """

    def __init__(self, label: str) -> None:
        self.label = label

    def fail(self, key: str, what: str) -> InputError:
        """The error naming ``key``."""
        return InputError(f"{self.label}: key '{key}' {what}")

    def written_twice(self, doc: Any) -> None:
        """No name written twice in one object of ``doc`` (decoded with
        :func:`object_pairs`)."""
        twice = _first_twice(doc)
        if twice is not None:
            raise self.fail(twice, "is written twice; a key is given once per table (JSON "
                            "keeps one of the values, and which was meant cannot be told)")

    def count(self, values: Sequence[Any], key: str, n: int, what: str = "values") -> None:
        """``values`` holds ``n`` entries."""
        if len(values) != n:
            raise self.fail(key, f"has {len(values)} {what}; expected {n}")

    def whole(self, value: int, key: str, lo: int, hi: int) -> None:
        """``lo <= value <= hi``."""
        if not lo <= value <= hi:
            raise self.fail(key, f"= {short(value)} is out of range; expected {lo} to {hi}")

    def matrix(self, rows: Sequence[Sequence[float]], key: str, n_rows: int | None,
               n_cols: int | None) -> None:
        """``rows`` is ``n_rows`` by ``n_cols`` (None: any number of rows; as many columns as
        its first row)."""
        if n_rows is not None:
            self.count(rows, key, n_rows, "rows")
        for k, row in enumerate(rows):
            self.count(row, f"{key}[{k}]", len(rows[0]) if n_cols is None else n_cols)

    def covariance(self, cov: Sequence[Sequence[float]], key: str) -> None:
        """A square ``cov``'s variances non-negative, symmetric, |correlation| <= 1 (to
        rounding)."""
        for j, row in enumerate(cov):
            if row[j] < 0:
                raise self.fail(f"{key}[{j}][{j}]", f"= {row[j]!r} is a negative variance")
        for j, row in enumerate(cov):
            for k in range(j):
                a, b = row[k], cov[k][j]
                bound = math.sqrt(row[j] * cov[k][k]) * (1 + 1e-6) + 1e-300
                if abs(a - b) > 1e-6 * bound or abs(a) > bound:
                    raise self.fail(f"{key}[{j}][{k}]", f"= {a!r} does not belong to a "
                                    "covariance (not symmetric, or a correlation beyond 1)")

    def ordered(self, pair: Sequence[float], key: str) -> None:
        """``pair`` is ``[lo, hi]`` with ``lo <= hi``."""
        lo, hi = pair
        if hi < lo:
            raise self.fail(key, f"= [{lo}, {hi}]; expected [lo, hi] with lo <= hi")

    def names(self, keys: Iterable[str], key: str, expected: Sequence[str], whose: str) -> None:
        """The keys of the table at ``key`` are exactly ``expected`` (the parameters of a law,
        ``whose``): the first missing or unknown one named."""
        keys = list(keys)
        for n in keys:  # first: a misspelt name explains the name then missing
            if n not in expected:
                near = nearest_key(n, list(expected))
                hint = f"; did you mean '{near}'?" if near else \
                    f" (expected one of {', '.join(expected)})"
                raise self.fail(f"{key}.{n}", f"is not a parameter of {whose}{hint}")
        for n in expected:
            if n not in keys:
                raise self.fail(f"{key}.{n}", f"is missing ({whose} has {', '.join(expected)})")
