"""One self-contained HTML page of results: headings, paragraphs, tables and figures.

Figures are embedded as base64 PNG or SVG data URIs (a PDF figure is linked, with a PNG preview
embedded), the style sheet is inline: the page needs no other file and no network. A figure is
shown at its drawn size (96 CSS pixels per inch), so its text reads at the size it was set in.
Every text is escaped with :func:`html.escape`, so a run or channel name can never inject
markup. The page around the sections is the package's template
``templates/page.html.j2`` with its style sheet ``templates/style.css``, which the calibration
certificate (:mod:`forcecal.report.certificate`) shares.

A page is a title and a sequence of :class:`Section`; a section's content is a sequence of
blocks:

- ``str``: a paragraph (blank lines separate paragraphs);
- :class:`Table`, or a bare list of rows (the first row is the header);
- a :class:`matplotlib.figure.Figure`, PNG or SVG ``bytes``, or an :class:`Image`;
- :class:`Preformatted` text (e.g. :func:`forcecal.actuator.report_text`);
- a nested :class:`Section` (one heading level down).

:func:`estimate_table` formats a :class:`~forcecal.forces.estimate.ForceEstimate` as table rows.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from markupsafe import Markup
from matplotlib.figure import Figure

from .._atomic import write_text_atomic
from ..errors import InputError
from ..forces.steady import ForceEstimate
from ._templates import render
from .cells import unc, value
from .figures import figure_bytes

__all__ = [
    "Image",
    "Preformatted",
    "Section",
    "Table",
    "build_report",
    "estimate_table",
    "write_report",
]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

CSS_PX_PER_INCH = 96
"""CSS pixels per inch: a figure drawn W inches wide is shown W * 96 pixels wide."""



@dataclass(frozen=True)
class Table:
    """A table of text cells.

    Attributes
    ----------
    rows : Sequence of Sequence
        Rows of cells (any value; formatted with ``str``), the body of the table.
    header : Sequence, optional
        The column names, or None for a table without a header row.
    caption : str
        A title above the table.
    """

    rows: Sequence[Sequence[Any]]
    header: Sequence[Any] | None = None
    caption: str = ""


@dataclass(frozen=True)
class Image:
    """A figure with a caption: a matplotlib Figure (rendered as PNG at ``dpi``), or the bytes
    of a PNG or SVG file.

    Attributes
    ----------
    figure : matplotlib.figure.Figure or bytes
        The figure, or its PNG or SVG file's content.
    caption : str
        The caption below the figure.
    alt : str
        The alternative text; the caption (or "figure") when empty.
    dpi : float
        Resolution [dots per inch] a Figure is rendered at.
    width : float or None
        Width shown [CSS px]; None: a Figure's width at 96 px per inch, the bytes' own size.
    link : str
        A file the figure links to (its PDF, say), relative to the page; empty for none.
    """

    figure: Figure | bytes
    caption: str = ""
    alt: str = ""
    dpi: float = 100
    width: float | None = None
    link: str = ""


@dataclass(frozen=True)
class Preformatted:
    """Text shown as written, in a monospace font (tables of plain text, logs).

    Attributes
    ----------
    text : str
        The text.
    """

    text: str


@dataclass(frozen=True)
class Section:
    """A heading and its content.

    Attributes
    ----------
    title : str
        The heading.
    content : Sequence
        The blocks, in order (see the module docstring for the kinds of block).
    """

    title: str
    content: Sequence[Any] = ()


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _table(table: Table) -> str:
    parts = ['<div class="wide"><table>']
    if table.caption:
        parts.append(f"<caption>{_e(table.caption)}</caption>")
    if table.header is not None:
        parts.append("<thead><tr>" + "".join(f"<th>{_e(c)}</th>" for c in table.header)
                     + "</tr></thead>")
    parts.append("<tbody>")
    for row in table.rows:
        cells = []
        for cell in row:
            text = str(cell)
            cls = ' class="num"' if _is_number(text) else ""
            cells.append(f"<td{cls}>{_e(text)}</td>")
        parts.append("<tr>" + "".join(cells) + "</tr>")
    parts.append("</tbody></table></div>")
    return "\n".join(parts)


def data_uri(data: bytes) -> str:
    """A ``data:image/png;base64,...`` (or ``image/svg+xml``) URI of a PNG's (an SVG's) bytes.

    Parameters
    ----------
    data : bytes
        A PNG or an SVG file's content.

    Returns
    -------
    str
        The data URI.

    Raises
    ------
    InputError
        When the bytes are neither (no PNG signature, no ``<svg`` element).
    """
    if data.startswith(_PNG_SIGNATURE):
        mime = "image/png"
    elif b"<svg" in data[:4096]:
        mime = "image/svg+xml"      # shown by <img>: no script in it can run
    else:
        raise InputError("an embedded image must be PNG or SVG data (the PNG signature and "
                         "the <svg> element are missing)")
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def _image(image: Image) -> str:
    if isinstance(image.figure, bytes):
        data, width = image.figure, image.width
    else:
        data = figure_bytes(image.figure, "png", dpi=image.dpi)
        width = image.width or image.figure.get_figwidth() * CSS_PX_PER_INCH
    alt = image.alt or image.caption or "figure"
    size = "" if width is None else f' width="{round(width)}"'
    out = f'<img src="{data_uri(data)}"{size} alt="{_e(alt)}">'
    if image.link:
        out = f'<a href="{_e(image.link)}">{out}</a>'
    out = "<figure>" + out
    if image.caption:
        out += f"<figcaption>{_e(image.caption)}</figcaption>"
    return out + "</figure>"


def _paragraphs(text: str) -> str:
    blocks = [b.strip() for b in text.split("\n\n") if b.strip()]
    return "\n".join(f"<p>{_e(b)}</p>" for b in blocks)


def _block(block: Any, level: int) -> str:
    if isinstance(block, str):
        return _paragraphs(block)
    if isinstance(block, Section):
        return _section(block, level + 1)
    if isinstance(block, Table):
        return _table(block)
    if isinstance(block, Preformatted):
        return f"<pre>{_e(block.text)}</pre>"
    if isinstance(block, Image):
        return _image(block)
    if isinstance(block, Figure | bytes):
        return _image(Image(block))
    if isinstance(block, list | tuple) and all(isinstance(r, list | tuple) for r in block):
        rows = list(block)
        return _table(Table(rows=rows[1:], header=rows[0] if rows else None))
    raise InputError(f"report: cannot show a block of type {type(block).__name__} (expected "
                     "str, Table, list of rows, Figure, PNG bytes, Image, Preformatted or "
                     "Section)")


def _section(section: Section, level: int) -> str:
    h = min(level, 6)
    parts = [f"<section>\n<h{h}>{_e(section.title)}</h{h}>"]
    parts += [_block(b, level) for b in section.content]
    parts.append("</section>")
    return "\n".join(parts)


def build_report(title: str, sections: Sequence[Section]) -> str:
    """The HTML page: the title as <h1>, each section as <h2> with its content.

    Parameters
    ----------
    title : str
        The page title.
    sections : Sequence of Section
        The sections, in order (a bare block is accepted as a section's content too).

    Returns
    -------
    str
        A complete, self-contained HTML5 document (UTF-8).
    """
    body = [_section(s, 2) if isinstance(s, Section) else _block(s, 1) for s in sections]
    return render("page.html.j2", {"title": title, "body": Markup("\n".join(body))})


def write_report(path: str | Path, title: str, sections: Sequence[Section]) -> Path:
    """Write :func:`build_report`'s page to ``path`` atomically.

    Parameters
    ----------
    path : str or pathlib.Path
        The HTML file to write.
    title : str
        The page title.
    sections : Sequence of Section
        The sections, in order.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return write_text_atomic(path, build_report(title, sections))


# --------------------------------------------------------------------------------------------
# tables of results

ESTIMATE_HEADER = ("force", "harmonic", "frequency [Hz]", "amplitude [N]", "phase [rad]",
                   "std. uncertainty [N]", "reactions only [N]")


def estimate_table(estimate: ForceEstimate) -> list[list[str]]:
    """The forces of a run as text rows, header first.

    One row per force (and "total") per harmonic the estimate kept: harmonic n, its frequency,
    the amplitude |F_n|, the phase arg F_n (convention of :mod:`forcecal.signals.harmonics`), the
    standard uncertainty of Re and of Im of F_n, and the reactions-only amplitude. For n = 0 the
    amplitude column holds the signed mean force and the phase is empty; without DC-capable
    gauges (``dc_observed`` false) the DC row says "not observed". Every number has the digits
    its uncertainty warrants (:func:`forcecal.report.cells.value`): the uncertainty two
    significant ones, the amplitudes (the reactions-only one too) to the uncertainty's second,
    the phase to that of std / |F_n| [rad], the frequency to that of n times the fundamental's.

    Parameters
    ----------
    estimate : ForceEstimate
        The forces of one run.

    Returns
    -------
    list of list of str
        The rows, the first being :data:`ESTIMATE_HEADER`.
    """
    rows = [list(ESTIMATE_HEADER)]
    names = [*estimate.force_names, "total"]
    force = np.vstack([estimate.force, estimate.total[None, :]])
    std = np.vstack([estimate.force_std, estimate.total_std[None, :]])
    static = np.vstack([estimate.static, estimate.static.sum(axis=0)[None, :]])
    for k, name in enumerate(names):
        for n in estimate.harmonics:
            n = int(n)
            if not estimate.kept[n]:
                continue
            freq = value(n * estimate.f0, n * estimate.f0_std) if n else "0"
            u = float(std[k, n])
            if n == 0:
                rows.append([name, "0", freq, "not observed", "", "", ""]
                            if not estimate.dc_observed else
                            [name, "0", freq, value(force[k, 0].real, u), "", unc(u),
                             value(static[k, 0].real, u)])
                continue
            amp = float(abs(force[k, n]))
            phase = float(np.angle(force[k, n]))
            rows.append([name, str(n), freq, value(amp, u),
                         value(phase, u / amp) if amp > 0 else "n/a", unc(u),
                         value(float(abs(static[k, n])), u)])
    return rows
