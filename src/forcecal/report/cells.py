"""Numbers as the reports write them, and the certificate's tables (:class:`Grid`).

Every value with an uncertainty, in a table, a caption or a figure, is written by one rule
(GUM 7.2.6): the uncertainty with two significant digits (:func:`unc`), the value to the digit
of the uncertainty's second (:func:`value`), together by :func:`plus_minus`. Quantities read in
the unit a laboratory writes (:func:`prefixed_unit`, :func:`quantity`: mm, µm, mN), other
numbers with a given number of significant digits (:func:`num`), fractions as percentages
(:func:`pct`, :func:`rel`), plain-text formulas as math text (:func:`math_text`), input paths
relative to one root (:func:`relative_paths`); a dash stands for what is missing.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

__all__: list[str] = []

MATH = (("mu0", "μ₀"), ("phi", "φ"), ("^2", "²"), ("^a", "ᵃ"), ("^b", "ᵇ"), (" * ", " · "))

NONE = "—"


@dataclass(frozen=True)
class Grid:
    """A table of the certificate, formatted.

    Attributes
    ----------
    caption : str
        Its title.
    header : tuple of str
        The column names.
    rows : tuple of tuple
        Cells: a str, or a tuple of str shown as lines of one cell.
    marks : tuple of str
        A CSS class per row (``""`` for none; ``chosen``, ``subtotal``, ``total``).
    """

    caption: str
    header: tuple[str, ...]
    rows: tuple[tuple[str | tuple[str, ...], ...], ...]
    marks: tuple[str, ...] = ()

    def mark(self, k: int) -> str:
        """The CSS class of row ``k``."""
        return self.marks[k] if k < len(self.marks) else ""


def unc(u: float) -> str:
    """An uncertainty: two significant digits."""
    if not math.isfinite(u):
        return "n/a"
    if u == 0:
        return "0"
    text = f"{u:#.2g}"                          # keeps a trailing zero: 1.0e-05
    return text.replace(".e", "e").rstrip(".")


def _last_digit(u: float) -> int:
    """The decade of the second significant digit of ``u`` as :func:`unc` writes it."""
    shown = float(f"{u:.2g}")                   # 0.000998 shows as 0.0010
    return math.floor(math.log10(shown)) - 1


def value(x: float, u: float) -> str:
    """A value to the digit of its uncertainty's second significant one (GUM 7.2.6).

    ``value(0.0012494, 0.00083)`` is ``0.00125``; a value smaller than that digit is ``0``
    to it (``0.0000`` for ``u = 0.0012``); without a positive uncertainty, six significant
    digits.
    """
    if not math.isfinite(x):
        return "n/a"
    if not (math.isfinite(u) and u > 0):
        return f"{x:.6g}"
    last = _last_digit(u)
    if x == 0 or math.floor(math.log10(abs(x))) < last:
        return f"{0.0:.{min(max(-last, 0), 12)}f}"
    digits = math.floor(math.log10(abs(x))) - last + 1
    text = f"{x:#.{min(digits, 15)}g}"          # keeps trailing zeros: 5.0e-05
    return text.replace(".e", "e").rstrip(".")


def plus_minus(x: float, u: float, unit: str = "") -> str:
    """``value ± uncertainty unit``, both by the rule of :func:`value` and :func:`unc`; the
    uncertainty in the value's notation (``20.014008 ± 0.000012``, not ``± 1.2e-05``)."""
    shown = value(x, u)
    spread = unc(u)
    if "e" not in shown and math.isfinite(u) and u > 0 and 0 <= -_last_digit(u) <= 12:
        spread = f"{float(spread):.{max(-_last_digit(u), 0)}f}"
    return f"{shown} ± {spread} {unit}".rstrip()


_PREFIXES = ((1.0, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n"))


def prefixed_unit(peak: float, base: str) -> tuple[float, str]:
    """Factor and unit that show values up to ``peak`` as numbers of 1 to 999.

    Parameters
    ----------
    peak : float
        The largest magnitude to show [base unit].
    base : str
        The SI unit, e.g. ``"m"``.

    Returns
    -------
    tuple of (float, str)
        The factor from the base unit and the prefixed unit.

    Examples
    --------
    >>> prefixed_unit(3e-5, "m")
    (1000000.0, 'µm')
    """
    peak = float(abs(peak))
    for size, prefix in _PREFIXES:
        if peak >= size:
            return 1.0 / size, prefix + base
    if peak == 0.0 or not math.isfinite(peak):
        return 1.0, base
    return 1e9, "n" + base


def quantity(x: float, base: str, digits: int = 3) -> str:
    """``x`` with ``digits`` significant digits in the prefix that suits it: ``0.2 µm``.

    Parameters
    ----------
    x : float
        The value [base unit].
    base : str
        The SI unit, e.g. ``"m"``.
    digits : int
        Significant digits shown.

    Returns
    -------
    str
        The number and its prefixed unit.
    """
    factor, unit = prefixed_unit(x, base)
    v = x * factor
    if v == 0 or not math.isfinite(v):
        return f"{v:g} {unit}"
    places = digits - 1 - math.floor(math.log10(abs(v)))
    return f"{round(v, places):.{max(places, 0)}f} {unit}"


def lab_unit(x: float, unit: str) -> tuple[float, str]:
    """Factor and unit a laboratory writes ``x`` in: a length, current or flux in the prefix
    that suits it (``4.97e-05 m`` as µm), any other unit as it is.

    Parameters
    ----------
    x : float
        The value [unit].
    unit : str
        Its SI unit.

    Returns
    -------
    tuple of (float, str)
        The factor from ``unit`` and the unit shown.
    """
    return prefixed_unit(x, unit) if unit in ("m", "A", "Wb") else (1.0, unit)


def relative_paths(paths: Sequence[str | Path]) -> tuple[str, list[str]]:
    """Input paths relative to one root: the deepest folder that holds every one that exists.

    Relative paths are taken from the working folder, as the command that read them did; a
    path that is not there (a scan moved away, an in-memory source) is kept as given.

    Parameters
    ----------
    paths : sequence of str or Path

    Returns
    -------
    tuple of (str, list of str)
        The root (absolute) and every path relative to it, with ``/`` separators.
    """
    full = [os.path.abspath(p) for p in paths]
    there = [os.path.dirname(p) for p in full if os.path.exists(p)]
    root = os.path.commonpath(there) if there else os.path.abspath(os.curdir)
    return root, [Path(os.path.relpath(f, root)).as_posix() if os.path.exists(f) else str(p)
                  for p, f in zip(paths, full, strict=True)]


def num(x: float | None, digits: int = 6) -> str:
    """A number with ``digits`` significant digits; a dash for None or not finite."""
    if x is None or not math.isfinite(x):
        return NONE
    return f"{x:.{digits}g}"


def pct(x: float | None, decimals: int = 3, sign: bool = False) -> str:
    """A fraction as a percentage."""
    if x is None or not math.isfinite(x):
        return NONE
    return f"{100 * x:{'+' if sign else ''}.{decimals}f} %"


def rel(x: float) -> str:
    """A relative uncertainty as a percentage, two significant digits."""
    return f"{100 * x:.2g} %" if math.isfinite(x) else NONE


def math_text(text: str) -> str:
    """A plain-text formula or unit as math text: ``K i^2 / s^2`` -> ``K i² / s²``."""
    for plain, pretty in MATH:
        text = text.replace(plain, pretty)
    return text
