"""Figures as files: PNG, SVG or PDF, written atomically or rendered in memory.

The figures are drawn at the size they are meant to be read at (at most 12 inches wide, the
reports' page width at 96 CSS pixels per inch), so their text keeps its size on the page.
"""

from __future__ import annotations

import io
from pathlib import Path

from matplotlib import rc_context
from matplotlib.figure import Figure

from ..._atomic import atomic_path
from ...errors import InputError

__all__ = ["figure_bytes", "save_png"]

FORMATS = ("png", "svg", "pdf")
"""The file formats of the figures, the default first."""

PNG_DPI = 120
"""Resolution of a PNG file [dots per inch]: 1.25 pixels per CSS pixel on the page."""


def figure_bytes(fig: Figure, fmt: str = "png", dpi: float = PNG_DPI) -> bytes:
    """``fig`` rendered in memory as PNG, SVG or PDF.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    fmt : str
        ``"png"``, ``"svg"`` or ``"pdf"``.
    dpi : float
        Resolution of a PNG [dots per inch] (SVG and PDF are vector graphics).

    Returns
    -------
    bytes
        The file's content.

    Raises
    ------
    InputError
        For another format.
    """
    if fmt not in FORMATS:
        raise InputError(f"figure format '{fmt}': expected one of {', '.join(FORMATS)}")
    buffer = io.BytesIO()
    # without a date, and with the SVG's ids derived from their content alone (one id, one
    # definition, however many SVGs a page inlines), the files of one input do not change
    metadata = {"svg": {"Date": None}, "pdf": {"CreationDate": None}}.get(fmt)
    with rc_context({"svg.hashsalt": "forcecal"}):
        fig.savefig(buffer, format=fmt, dpi=dpi, metadata=metadata)
    return buffer.getvalue()


def save_png(fig: Figure, path: str | Path, dpi: float = PNG_DPI) -> Path:
    """Write ``fig`` as PNG to ``path`` atomically (a temporary name, then a rename).

    On any failure the temporary file is removed and an existing ``path`` is left untouched.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or pathlib.Path
        The PNG file to write.
    dpi : float
        Resolution [dots per inch].

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return Path(path)


def write_bytes(data: bytes, path: str | Path) -> Path:
    """Write ``data`` to ``path`` atomically.

    Parameters
    ----------
    data : bytes
        A figure's file (:func:`figure_bytes`).
    path : str or pathlib.Path
        The file to write.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(data)
    return Path(path)
