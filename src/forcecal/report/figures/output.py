"""Figures as PNG: written atomically to a file, or rendered in memory."""

from __future__ import annotations

import io
from pathlib import Path

from matplotlib.figure import Figure

from ..._atomic import atomic_path

__all__ = ["png_bytes", "save_png"]


def save_png(fig: Figure, path: str | Path, dpi: float = 120) -> Path:
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


def png_bytes(fig: Figure, dpi: float = 100) -> bytes:
    """``fig`` rendered as PNG in memory.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    dpi : float
        Resolution [dots per inch].

    Returns
    -------
    bytes
        The PNG file's content.
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()
