"""The schemas of the JSON files forcecal reads back: a spatial model and a calibration.

:func:`check_model_document` and :func:`check_calibration_document` look at a decoded document
before anything is built from it: its ``format`` (and ``version``), the type and the size of
every key, list lengths that must agree (harmonics, shapes, couplings; a shape's order, basis
and coefficients), and every number finite and within a physical bound. Each failure is an
:class:`~forcecal.errors.InputError` that names the file, the key (``shapes[1].order``), what
was found and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .errors import InputError
from .model._orthonormal_basis import FAMILIES, n_functions

__all__ = [
    "MAX_DOCUMENT_BYTES",
    "check_calibration_document",
    "check_model_document",
    "reject_constant",
]

MODEL_FORMAT = "forcecal spatial model 1"
"""The ``format`` a spatial model file carries."""
CALIBRATION_FORMAT = "forcecal-calibration"
"""The ``format`` a calibration file carries (with ``version`` 1)."""
CALIBRATION_VERSIONS = (1,)
MAX_ORDER = 64
"""Highest shape order (functions per axis) a model may hold; ``forcecal scan`` picks < 30."""
MAX_HARMONIC = 1000
"""Highest harmonic number of a model."""
MAX_NUMBER = 1e30
"""Largest magnitude of any number in a model or calibration file."""
MAX_FREQUENCY_HZ = 1e6
MAX_COUPLING = 1e6
"""kg m: a mass coupling beyond is not a laboratory structure's."""
MAX_RELATIVE_STD = 100.0
"""A shape coefficient's standard deviation may reach this many times the norm of the shape's
coefficients (or its residual's standard deviation, if larger): a broadband span's weakest
shape is known to about 4 times its size, a steady scan's weakest harmonic to its size."""
MAX_DOCUMENT_BYTES = 200_000_000
"""Largest model or calibration file read."""


class _Doc:
    """Typed access to one document's keys, every failure naming the file and the key."""

    def __init__(self, what: str, source: str) -> None:
        self.what, self.source = what, source

    def fail(self, key: str, text: str) -> InputError:
        return InputError(f"{self.what} '{self.source}': key '{key}' {text}")

    def get(self, obj: dict, key: str, path: str, kind: type | tuple, *,
            required: bool = True) -> Any:
        full = f"{path}.{key}" if path else key
        if key not in obj:
            if required:
                raise InputError(f"{self.what} '{self.source}': missing key '{full}'")
            return None
        value = obj[key]
        ok = isinstance(value, kind) and not (isinstance(value, bool) and bool not in
                                              (kind if isinstance(kind, tuple) else (kind,)))
        if not ok:
            names = (kind if isinstance(kind, tuple) else (kind,))
            raise self.fail(full, f"must be {' or '.join(_NAMES.get(k, k.__name__) for k in names)}"
                            f", found {_short(value)}")
        return value

    def number(self, value: Any, key: str, lo: float = -MAX_NUMBER, hi: float = MAX_NUMBER,
               *, open_lo: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"must be a number, found {_short(value)}")
        try:
            x = float(value)
        except OverflowError:
            raise self.fail(key, "is too large a number") from None
        if not math.isfinite(x):
            raise self.fail(key, f"must be a finite number, found {value!r}")
        if x < lo or x > hi or (open_lo and x == lo):
            bound = f"{'above' if open_lo else 'at least'} {lo:g} and at most {hi:g}"
            raise self.fail(key, f"= {x!r} is out of range; expected {bound}")
        return x

    def integer(self, value: Any, key: str, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"must be a whole number, found {_short(value)}")
        if not lo <= value <= hi:
            raise self.fail(key, f"= {_short(value)} is out of range; expected {lo} to {hi}")
        return value

    def vector(self, value: Any, key: str, n: int | None = None, lo: float = -MAX_NUMBER,
               hi: float = MAX_NUMBER) -> list[float]:
        if not isinstance(value, list):
            raise self.fail(key, f"must be a list of numbers, found {_short(value)}")
        if n is not None and len(value) != n:
            raise self.fail(key, f"has {len(value)} values; expected {n}")
        return [self.number(v, f"{key}[{k}]", lo, hi) for k, v in enumerate(value)]

    def matrix(self, value: Any, key: str, rows: int | None, cols: int | None,
               lo: float = -MAX_NUMBER, hi: float = MAX_NUMBER) -> list[list[float]]:
        if not isinstance(value, list):
            raise self.fail(key, f"must be a list of rows, found {_short(value)}")
        if rows is not None and len(value) != rows:
            raise self.fail(key, f"has {len(value)} rows; expected {rows}")
        out = []
        for k, row in enumerate(value):
            out.append(self.vector(row, f"{key}[{k}]", cols, lo, hi))
            cols = len(out[0]) if cols is None else cols
        return out

    def strings(self, value: Any, key: str) -> list[str]:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(key, f"must be a list of strings, found {_short(value)}")
        return value


_NAMES = {dict: "an object", list: "a list", str: "a string", int: "a whole number",
          float: "a number"}


def _short(value: Any) -> str:
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# --------------------------------------------------------------------------------------------
# spatial model


def check_model_document(doc: Any, source: str) -> None:
    """Check a decoded spatial model file against its schema (see the module docstring).

    Parameters
    ----------
    doc : object
        What :func:`json.loads` gave.
    source : str
        The file, for the messages.

    Raises
    ------
    InputError
        Naming the file and the first key at fault.
    """
    d = _Doc("model", source)
    if not isinstance(doc, dict):
        raise InputError(f"model '{source}': expected a JSON object, found {_short(doc)}")
    fmt = d.get(doc, "format", "", str)
    if fmt != MODEL_FORMAT:
        raise d.fail("format", f"= {fmt!r}; expected {MODEL_FORMAT!r} (not a forcecal "
                     "spatial model, or one of another version)")
    d.number(d.get(doc, "f0_hz", "", (int, float)), "f0_hz", 0.0, MAX_FREQUENCY_HZ,
             open_lo=True)
    harmonics = d.get(doc, "harmonics", "", list)
    if not harmonics:
        raise d.fail("harmonics", "is empty; a model holds at least one harmonic")
    hs = [d.integer(n, f"harmonics[{k}]", 1, MAX_HARMONIC) for k, n in enumerate(harmonics)]
    if len(set(hs)) != len(hs):
        raise d.fail("harmonics", f"= {hs} names a harmonic twice")
    n_h = len(hs)
    gauges = d.strings(d.get(doc, "gauges", "", list), "gauges")
    if not gauges:
        raise d.fail("gauges", "is empty")
    n_g = len(gauges)
    shapes = d.get(doc, "shapes", "", list)
    if len(shapes) != n_h:
        raise d.fail("shapes", f"has {len(shapes)} shapes for {n_h} harmonics {hs}; expected "
                     "one shape per harmonic")
    for part in ("couplings_re", "couplings_im"):
        d.matrix(d.get(doc, part, "", list), part, n_h, n_g, -MAX_COUPLING, MAX_COUPLING)
    d.matrix(d.get(doc, "similarity_mac", "", list), "similarity_mac", n_h, n_h, -1e-6, 1 + 1e-6)
    snr = d.vector(d.get(doc, "snr", "", list), "snr", None, 0.0, MAX_NUMBER)
    if len(snr) < max(hs):
        raise d.fail("snr", f"has {len(snr)} values; expected one per harmonic 1..{max(hs)}")
    if "n_points" in doc:
        d.integer(doc["n_points"], "n_points", 0, 10**9)
    for key in ("source",):
        d.get(doc, key, "", str, required=False)
    d.strings(doc.get("notes", []), "notes")
    dropped = d.get(doc, "dropped", "", dict, required=False) or {}
    for k, v in dropped.items():
        if not (isinstance(k, str) and k.strip().isdigit() and isinstance(v, str)):
            raise d.fail(f"dropped.{k}", "must map a harmonic number to a reason")
    rig = d.get(doc, "rig", "", dict, required=False)
    if rig is not None:
        keys = d.get(rig, "keys", "rig", dict, required=False) or {}
        for k, v in keys.items():
            if isinstance(v, bool) or not isinstance(v, str | int | float):
                raise d.fail(f"rig.keys.{k}", f"must be a number or a name, found {_short(v)}")
            if isinstance(v, int | float):
                d.number(v, f"rig.keys.{k}")
    for k, s in enumerate(shapes):
        _check_shape(d, s, f"shapes[{k}]")
    if "span" in doc:
        _check_span(d, doc, hs, n_g)


def _check_span(d: _Doc, doc: dict, hs: list[int], n_g: int) -> None:
    """A multi-scan model's span: per harmonic the other scans' shapes and couplings."""
    scans = d.strings(d.get(doc, "scans", "", list), "scans")
    span = d.get(doc, "span", "", list)
    if len(span) != len(hs):
        raise d.fail("span", f"has {len(span)} entries for {len(hs)} harmonics; expected one "
                     "per harmonic")
    for k, m in enumerate(span):
        key = f"span[{k}]"
        if not isinstance(m, dict):
            raise d.fail(key, f"must be an object, found {_short(m)}")
        if d.get(m, "harmonic", key, int) != hs[k]:
            raise d.fail(f"{key}.harmonic", f"= {m['harmonic']}; expected {hs[k]}, the "
                         f"harmonic of shapes[{k}]")
        extra = d.get(m, "shapes", key, list)
        idx = d.get(m, "scans", key, list)
        if len(idx) != len(extra) + 1:
            raise d.fail(f"{key}.scans", f"has {len(idx)} entries for {len(extra) + 1} shapes; "
                         "expected the scan of shapes[k] then of each shape of the span")
        for j, i in enumerate(idx):
            d.integer(i, f"{key}.scans[{j}]", 0, len(scans) - 1)
        for j, s in enumerate(extra):
            _check_shape(d, s, f"{key}.shapes[{j}]")
        for part in ("couplings_re", "couplings_im"):
            d.matrix(d.get(m, part, key, list), f"{key}.{part}", n_g, len(extra),
                     -MAX_COUPLING, MAX_COUPLING)


def _check_shape(d: _Doc, s: Any, key: str) -> None:
    if not isinstance(s, dict):
        raise d.fail(key, f"must be an object, found {_short(s)}")
    if "components" in s:
        comps = d.get(s, "components", key, list)
        if not 1 <= len(comps) <= 3:
            raise d.fail(f"{key}.components", f"has {len(comps)} entries; expected 1 to 3")
        axes = []
        for j, c in enumerate(comps):
            ck = f"{key}.components[{j}]"
            if not isinstance(c, dict):
                raise d.fail(ck, f"must be an object, found {_short(c)}")
            axis = d.get(c, "axis", ck, str)
            if axis not in ("x", "y", "z") or axis in axes:
                raise d.fail(f"{ck}.axis", f"= {axis!r}; expected one of 'x', 'y', 'z', once")
            axes.append(axis)
            _check_scalar_shape(d, c, ck)
        return
    _check_scalar_shape(d, s, key)


def _check_scalar_shape(d: _Doc, s: dict, key: str) -> None:
    order = d.integer(d.get(s, "order", key, int), f"{key}.order", 1, MAX_ORDER)
    domain = d.matrix(d.get(s, "domain", key, list), f"{key}.domain", None, 2, -1e4, 1e4)
    if not 1 <= len(domain) <= 3:
        raise d.fail(f"{key}.domain", f"has {len(domain)} axes; expected 1 to 3 [lo, hi] pairs")
    for j, (lo, hi) in enumerate(domain):
        if not hi - lo >= 1e-6:
            raise d.fail(f"{key}.domain[{j}]", f"= [{lo}, {hi}] is empty or narrower than 1 um; "
                         "expected lo < hi (m)")
    family = d.get(s, "family", key, str, required=False) or "legendre"
    if family not in FAMILIES:
        raise d.fail(f"{key}.family", f"= {family!r}; expected one of {', '.join(FAMILIES)}")
    d.get(s, "criterion", key, str)
    basis_order = order
    if s.get("basis_order") is not None:
        basis_order = d.integer(d.get(s, "basis_order", key, int), f"{key}.basis_order", order,
                                MAX_ORDER)
    available = n_functions(basis_order, len(domain))
    columns = s.get("columns")
    if columns is not None:
        if not isinstance(columns, list) or not columns:
            raise d.fail(f"{key}.columns", f"must be a list of function indices, found "
                         f"{_short(columns)}")
        cols = [d.integer(c, f"{key}.columns[{j}]", 0, available - 1)
                for j, c in enumerate(columns)]
        n = len(cols)
    else:
        n = available
    d.matrix(d.get(s, "basis", key, list), f"{key}.basis", n, n)
    re = d.vector(d.get(s, "coefficients_re", key, list), f"{key}.coefficients_re", n, -1e3, 1e3)
    im = d.vector(d.get(s, "coefficients_im", key, list), f"{key}.coefficients_im", n, -1e3, 1e3)
    cov = d.matrix(d.get(s, "coefficient_covariance", key, list),
                   f"{key}.coefficient_covariance", n, n, -1e6, 1e6)
    _covariance(d, cov, f"{key}.coefficient_covariance")
    sigma = d.number(d.get(s, "residual_std", key, (int, float)), f"{key}.residual_std", 0.0,
                     1e3)
    scale = max(math.sqrt(sum(v * v for v in (*re, *im))), sigma)
    for j, row in enumerate(cov):
        if math.sqrt(row[j]) > MAX_RELATIVE_STD * scale:
            raise d.fail(f"{key}.coefficient_covariance[{j}][{j}]",
                         f"= {row[j]!r}: a standard deviation "
                         f"{math.sqrt(row[j]) / max(scale, 1e-300):.3g} times the shape's own "
                         f"coefficients (at most {MAX_RELATIVE_STD:g}); a shape this uncertain "
                         "gives no force (is the file corrupt?)")
    orders = d.get(s, "orders", key, list)
    score = d.get(s, "score", key, list)
    for j, o in enumerate(orders):
        d.integer(o, f"{key}.orders[{j}]", 0, 10 * MAX_ORDER)
    if len(score) != len(orders):
        raise d.fail(f"{key}.score", f"has {len(score)} values for {len(orders)} orders")
    for j, v in enumerate(score):
        if v is not None:
            d.number(v, f"{key}.score[{j}]")


# --------------------------------------------------------------------------------------------
# calibration


def check_calibration_document(doc: Any, source: str, get_law: Callable[[str], Any]) -> None:
    """Check a decoded calibration file against its schema (see the module docstring).

    Parameters
    ----------
    doc : object
        What :func:`json.loads` gave.
    source : str
        The file, for the messages.
    get_law : callable
        The law of a name (:func:`forcecal.actuator.laws.get_law`), to check the parameters'
        names and count.

    Raises
    ------
    InputError
        Naming the file and the first key at fault.
    """
    d = _Doc("calibration", source)
    if not isinstance(doc, dict):
        raise InputError(f"calibration '{source}': expected a JSON object, found {_short(doc)}")
    fmt = d.get(doc, "format", "", str)
    if fmt != CALIBRATION_FORMAT:
        raise d.fail("format", f"= {fmt!r}; expected {CALIBRATION_FORMAT!r}")
    version = d.get(doc, "version", "", int)
    if version not in CALIBRATION_VERSIONS:
        raise d.fail("version", f"= {version!r}; this forcecal reads version "
                     f"{', '.join(map(str, CALIBRATION_VERSIONS))}")
    name = d.get(doc, "law", "", str)
    try:
        law = get_law(name)
    except (KeyError, ValueError, InputError):
        raise d.fail("law", f"= {name!r} is not a known law") from None
    _check_calibration_values(d, doc, law)
    unc = d.get(doc, "uncertainty", "", dict, required=False)
    if unc is None:
        return
    _check_calibration_budget(d, unc, law)


def _check_calibration_values(d: _Doc, doc: dict, law: Any) -> None:
    """A calibration's parameters for ``law`` (a :class:`~forcecal.actuator.laws.Law`), their
    covariance, the pole count, the calibrated ranges and the candidate laws' rows."""
    params = d.get(doc, "params", "", dict)
    p = law.n_params
    for n in law.param_names:
        if n not in params:
            raise d.fail("params", f"lacks {n!r} for law {law.name!r}")
        d.number(params[n], f"params.{n}", -1e12, 1e12)
    _covariance(d, d.matrix(d.get(doc, "covariance", "", list), "covariance", p, p, -1e24, 1e24),
                "covariance")
    d.integer(d.get(doc, "n_poles", "", int), "n_poles", 1, 1000)
    lo, hi = d.vector(d.get(doc, "current_range", "", list), "current_range", 2, -1e5, 1e5)
    _ordered(d, "current_range", lo, hi)
    lo, hi = d.vector(d.get(doc, "gap_range", "", list), "gap_range", 2, 0.0, 0.1)
    _ordered(d, "gap_range", lo, hi)
    if doc.get("flux_range") is not None:
        lo, hi = d.vector(doc["flux_range"], "flux_range", 2, -10.0, 10.0)
        _ordered(d, "flux_range", lo, hi)
    cands = d.get(doc, "candidates", "", list, required=False) or []
    for k, row in enumerate(cands):
        if not isinstance(row, dict):
            raise d.fail(f"candidates[{k}]", f"must be an object, found {_short(row)}")


def _check_calibration_budget(d: _Doc, unc: dict, law: Any) -> None:
    """The ``uncertainty`` block of a calibration for ``law``: the parameters' uncertainty
    budget a campaign's calibration carries (optional)."""
    p = law.n_params
    names = d.strings(d.get(unc, "param_names", "uncertainty", list), "uncertainty.param_names")
    if names != list(law.param_names):
        raise d.fail("uncertainty.param_names", f"= {names!r}; expected "
                     f"{list(law.param_names)!r} for law {law.name!r}")
    d.number(d.get(unc, "coverage_factor", "uncertainty", (int, float)),
             "uncertainty.coverage_factor", 0.0, 10.0, open_lo=True)
    for key in ("stderr", "expanded"):
        values = d.get(unc, key, "uncertainty", dict)
        for n in names:
            d.number(values.get(n), f"uncertainty.{key}.{n}", 0.0)
    d.matrix(d.get(unc, "correlation", "uncertainty", list), "uncertainty.correlation", p, p,
             -1.0 - 1e-9, 1.0 + 1e-9)
    for part in ("statistical", "type_b"):
        block = d.get(unc, part, "uncertainty", dict)
        _covariance(d, d.matrix(d.get(block, "covariance", f"uncertainty.{part}", list),
                                f"uncertainty.{part}.covariance", p, p, -1e24, 1e24),
                    f"uncertainty.{part}.covariance")
    budget = d.get(unc, "budget", "uncertainty", dict)
    for source, row in budget.items():
        if not isinstance(row, dict):
            raise d.fail(f"uncertainty.budget.{source}", f"must be an object, found "
                         f"{_short(row)}")
        for n in names:
            d.number(row.get(n), f"uncertainty.budget.{source}.{n}", 0.0)


def _covariance(d: _Doc, cov: list[list[float]], key: str) -> None:
    """A covariance: non-negative variances, symmetric, |correlation| <= 1 (to rounding)."""
    for j, row in enumerate(cov):
        if row[j] < 0:
            raise d.fail(f"{key}[{j}][{j}]", f"= {row[j]!r} is a negative variance")
    for j, row in enumerate(cov):
        for k in range(j):
            a, b = row[k], cov[k][j]
            bound = math.sqrt(row[j] * cov[k][k]) * (1 + 1e-6) + 1e-300
            if abs(a - b) > 1e-6 * bound or abs(a) > bound:
                raise d.fail(f"{key}[{j}][{k}]", f"= {a!r} does not belong to a covariance "
                             "(not symmetric, or a correlation beyond 1)")


def _ordered(d: _Doc, key: str, lo: float, hi: float) -> None:
    if hi < lo:
        raise d.fail(key, f"= [{lo}, {hi}]; expected [lo, hi] with lo <= hi")


def reject_constant(name: str) -> float:
    """``parse_constant`` for :func:`json.loads`: JSON has no NaN or Infinity, refuse them."""
    raise ValueError(f"{name} is not a JSON number")
