"""The certificate's cells: tables (:class:`Grid`) and numbers written as GUM 7.2.6 suggests.

Uncertainties with two significant digits (:func:`unc`), values to the digit of their standard
uncertainty's second (:func:`value`), other numbers to a given number of significant digits
(:func:`num`), fractions as percentages (:func:`pct`, :func:`rel`) and plain-text formulas as
math text (:func:`math_text`); a dash stands for what is missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


def value(x: float, u: float) -> str:
    """A value to the digit of its uncertainty's second significant one (GUM 7.2.6)."""
    if not math.isfinite(x):
        return "n/a"
    if x == 0 or not (math.isfinite(u) and u > 0):
        return f"{x:.6g}"
    digits = math.floor(math.log10(abs(x))) - math.floor(math.log10(u)) + 2
    text = f"{x:#.{min(max(digits, 2), 12)}g}"    # keeps trailing zeros: 5.0e-05
    return text.replace(".e", "e").rstrip(".")


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
