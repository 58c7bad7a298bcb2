"""Harmonic deflection shapes from the scan (the paper's fig. 3): beam, plate and body.

One figure per structure dimension: :func:`fig_shapes` draws a beam's shapes along x,
:func:`fig_shapes_2d` a plate's as contour maps, :func:`fig_shapes_body` a body's records
against the vector model.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.contour import QuadContourSet
from matplotlib.figure import Figure
from matplotlib.gridspec import GridSpec

from ...errors import DimensionError, InputError
from ...model.basis import ShapeFit
from ...model.scan import HarmonicShapes
from ...model.spatial import ONE_SHAPE_MAC, SpatialModel
from ..cells import prefixed_unit
from ._common import MARKERS, panel_title

__all__ = ["fig_shapes", "fig_shapes_2d", "fig_shapes_body"]


# --------------------------------------------------------------------------------------------
# beam


def fig_shapes(shapes: HarmonicShapes, model: SpatialModel, n_fine: int = 401) -> Figure:
    """The scan's harmonic shapes along a beam and their fit (the paper's fig. 3).

    Left, one panel per harmonic of the model: Re and Im of the measured phase-aligned phasor
    H_n(x_k) at the scan points (markers, with their standard uncertainty as error bars) and of
    the fitted shape phi_n(x) on a fine grid (lines). Right: every fitted shape normalized by
    its complex value of largest magnitude over the grid, so that identical shapes coincide,
    with the measured points normalized alike, the shapes' MAC values and whether one shape
    serves all harmonics (:attr:`SpatialModel.one_shape`).

    Parameters
    ----------
    shapes : HarmonicShapes
        The measured shapes, values ``(n_harm, n_points)`` complex [m] over 1-D points [m].
    model : SpatialModel
        The spatial model fitted to them.
    n_fine : int
        Number of grid points of the fitted curves, spanning the scan points.

    Returns
    -------
    matplotlib.figure.Figure
        ``len(model.harmonics) + 1`` axes (the per-harmonic panels first). The lines are
        labelled "Re measured", "Im measured", "Re fitted", "Im fitted" (x in mm, the shape in
        the unit of the y label) and, on the right, "n = N" (normalized fitted shape, Re).

    Raises
    ------
    DimensionError
        When the scan points are not 1-D.
    InputError
        When the model shares no harmonic with the shapes.
    """
    if shapes.points.shape[1] != 1:
        raise DimensionError(
            f"fig_shapes draws shapes along a beam (1-D points); the scan '{shapes.source}' "
            f"has points with {shapes.points.shape[1]} coordinates"
        )
    harmonics = [int(n) for n in model.harmonics if n in shapes.harmonics]
    if not harmonics:
        raise InputError("fig_shapes: the model shares no harmonic with the measured shapes")
    x = shapes.points[:, 0]
    xf = np.linspace(x.min(), x.max(), n_fine)
    fig = Figure(figsize=(12.0, 1.0 + 2.3 * max(len(harmonics), 2)), layout="constrained")
    grid = fig.add_gridspec(len(harmonics), 2, width_ratios=(1.2, 1.0))
    fig.suptitle(f"Harmonic deflection shapes from the scan '{Path(shapes.source).name}' "
                 f"(f0 = {shapes.f0:.4f} Hz, {len(x)} points)")
    _draw_beam_panels(fig, grid, shapes, model, harmonics, xf)
    _draw_normalized(fig.add_subplot(grid[:, 1]), shapes, model, harmonics, xf)
    return fig


def _row(shapes: HarmonicShapes, n: int) -> int:
    """The row of harmonic n in ``shapes.values``."""
    return int(np.flatnonzero(shapes.harmonics == n)[0])


def _draw_beam_panels(fig: Figure, grid: GridSpec, shapes: HarmonicShapes, model: SpatialModel,
                      harmonics: list[int], xf: np.ndarray) -> None:
    """One panel per harmonic in the grid's left column, sharing x [mm]."""
    panels: list[Axes] = []
    for row, n in enumerate(harmonics):
        ax = fig.add_subplot(grid[row, 0], sharex=panels[0] if panels else None)
        panels.append(ax)
        _draw_beam_harmonic(ax, shapes, model, n, xf)
        if row == 0:
            ax.legend(loc="best", fontsize="small", ncols=2)
        if row < len(harmonics) - 1:
            ax.tick_params(labelbottom=False)
    panels[0].set_xlim(xf[0] * 1e3, xf[-1] * 1e3)
    panels[-1].set_xlabel("x [mm]")


def _draw_beam_harmonic(ax: Axes, shapes: HarmonicShapes, model: SpatialModel, n: int,
                        xf: np.ndarray) -> None:
    """Re and Im of harmonic n, measured (with error bars) and fitted over the grid ``xf``."""
    x = shapes.points[:, 0]
    k = _row(shapes, n)
    meas, std = shapes.values[k], shapes.std[k]
    fit = model.shape_values(n, xf)
    factor, unit = prefixed_unit(max(np.abs(meas).max(), np.abs(fit).max()), "m")
    ax.axhline(0.0, color="0.8", lw=0.6)
    ax.errorbar(x * 1e3, meas.real * factor, yerr=std * factor, fmt="o", ms=3.5, color="C0",
                elinewidth=0.6, label="Re measured")
    ax.errorbar(x * 1e3, meas.imag * factor, yerr=std * factor, fmt="s", ms=3.0,
                mfc="none", color="C1", elinewidth=0.6, label="Im measured")
    ax.plot(xf * 1e3, fit.real * factor, "-", color="C0", lw=1.4, label="Re fitted")
    ax.plot(xf * 1e3, fit.imag * factor, "--", color="C1", lw=1.4, label="Im fitted")
    aside = _set_aside(model, len(x))
    if aside.size:
        ax.plot(x[aside] * 1e3, meas[aside].real * factor, "x", color="C3", ms=8, mew=1.8,
                label="set aside")
    m = model.index(n)
    for j, (member, name) in enumerate(zip(model.members(m)[1:], model.member_names(m)[1:],
                                           strict=True)):
        # another scan's shape, at its own load: scaled and rotated onto this one to compare
        other = member.evaluate(xf)
        other = other * (np.vdot(other, fit) / np.vdot(other, other))
        ax.plot(xf * 1e3, other.real * factor, ":", color=f"C{4 + j}", lw=1.4,
                label=f"Re {Path(name).name} (scaled)")
    ax.set_title(f"harmonic {n}: {n * shapes.f0:.1f} Hz, polynomial order "
                 f"{model.shapes[m].order}, scan SNR {model.snr[n - 1]:.0f}",
                 loc="left", fontsize="medium")
    ax.set_ylabel(f"$H_{{{n}}}$ [{unit}]")
    ax.grid(alpha=0.3)


def _draw_normalized(ax: Axes, shapes: HarmonicShapes, model: SpatialModel,
                     harmonics: list[int], xf: np.ndarray) -> None:
    """Every fitted shape over its peak, with the measured points alike, and the MAC values."""
    x = shapes.points[:, 0]
    ax.axhline(0.0, color="0.8", lw=0.6)
    for j, n in enumerate(harmonics):
        fit = model.shape_values(n, xf)
        ref = fit[np.argmax(np.abs(fit))]
        color = f"C{j % 10}"
        ax.plot(xf * 1e3, (fit / ref).real, "-", lw=1.6, color=color,
                label=f"n = {n} ({n * shapes.f0:.0f} Hz)")
        # the measured points over every line, one open marker per harmonic, staggered so that
        # harmonics of one shape (points on the same curve) stay apart
        ax.plot(x[j::len(harmonics)] * 1e3,
                (shapes.values[_row(shapes, n)][j::len(harmonics)] / ref).real,
                MARKERS[j % len(MARKERS)], ms=4, mfc="none", mew=0.9, color=color, zorder=3,
                label=f"_measured {n}")
    ax.set_xlim(xf[0] * 1e3, xf[-1] * 1e3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel(r"Re $\varphi_n(x) / \varphi_n(x_\mathrm{peak})$ [1]")
    panel_title(ax, "Normalized shapes (lines: fitted, markers: measured"
                + (f", 1 point in {len(harmonics)})" if len(harmonics) > 1 else ")"))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small", title=_mac_text(model, harmonics),
              title_fontsize="small", alignment="left", framealpha=0.9)
    lo, hi = ax.get_ylim()
    ax.set_ylim(min(lo, -0.1), max(hi, 1.1))


def _set_aside(model: SpatialModel, n_records: int) -> np.ndarray:
    """Indices of the scan records the model set aside (:mod:`forcecal.model.screening`)."""
    return np.array([k for k in sorted(model.set_aside) if k < n_records], dtype=int)


def _mac_text(model: SpatialModel, harmonics: list[int]) -> str:
    """The legend title: MAC of the first harmonic's shape with the others, dropped harmonics."""
    idx = [model.index(n) for n in harmonics]
    mac = model.similarity[np.ix_(idx, idx)]
    lines = []
    if len(harmonics) > 1:
        pairs = [f"{harmonics[0]}-{n}: {mac[0, j]:.4f}" for j, n in enumerate(harmonics[1:], 1)]
        for start in range(0, len(pairs), 3):
            head = "MAC " if start == 0 else "    "
            lines.append(head + ", ".join(pairs[start:start + 3]))
        lines.append(f"smallest MAC {mac.min():.4f} (one shape needs >= {ONE_SHAPE_MAC})")
    lines.append(f"one shape serves all: {'yes' if model.one_shape else 'no'}")
    if model.dropped:
        dropped = sorted(model.dropped)
        snr = ", ".join(f"{model.snr[n - 1]:.1f}" for n in dropped if n - 1 < len(model.snr))
        lines.append(f"dropped: harmonics {', '.join(map(str, dropped))} (scan SNR {snr})")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# plate


def fig_shapes_2d(shapes: HarmonicShapes, model: SpatialModel, n_fine: int = 81) -> Figure:
    """Harmonic deflection shapes of a plate: the fitted shape per harmonic as a contour map.

    Each panel shows Re of the fitted shape, rotated to its most real phase and normalized by
    its peak, over the outline's box, with the scan points as dots and the MAC of every
    harmonic against the first in its title.

    Parameters
    ----------
    shapes : HarmonicShapes
        The measured shapes over 2-D points (x, y) [m] (their points are drawn).
    model : SpatialModel
        The spatial model fitted to them.
    n_fine : int
        Number of grid points along each side of the outline's box.

    Returns
    -------
    matplotlib.figure.Figure
        One axes per harmonic of the model (x, y in mm) and a colour bar.

    Raises
    ------
    DimensionError
        When the model holds a body's vector shapes.
    """
    first = model.shapes[0]
    if not isinstance(first, ShapeFit):
        raise DimensionError("fig_shapes_2d draws a plate's scalar shapes; the model of the "
                             f"scan '{model.source}' holds vector shapes (a body)")
    harmonics = [int(n) for n in model.harmonics]
    fig = Figure(figsize=(4.2 * len(harmonics) + 0.8, 4.0), layout="constrained")
    axes = fig.subplots(1, len(harmonics), squeeze=False)[0]
    dom = first.basis.domain
    xx, yy = np.meshgrid(np.linspace(dom[0, 0], dom[0, 1], n_fine),
                         np.linspace(dom[1, 0], dom[1, 1], n_fine))
    contours = [_draw_plate_harmonic(ax, shapes, model, harmonics, k, (xx, yy))
                for k, ax in enumerate(axes)]
    fig.colorbar(contours[-1], ax=list(axes),
                 label=r"Re $\varphi_n / \varphi_n(\mathrm{peak})$ [1]", shrink=0.8)
    fig.suptitle(f"Harmonic deflection shapes from the scan '{Path(shapes.source).name}' "
                 f"({shapes.points.shape[0]} points; black: node lines)")
    return fig


def _draw_plate_harmonic(ax: Axes, shapes: HarmonicShapes, model: SpatialModel,
                         harmonics: Sequence[int], k: int,
                         mesh: tuple[np.ndarray, np.ndarray]) -> QuadContourSet:
    """The contour map of the k-th harmonic's normalized shape over ``mesh`` (x, y) [m]."""
    n = harmonics[k]
    xx, yy = mesh
    values = model.shape_values(n, np.column_stack([xx.ravel(), yy.ravel()]))
    peak = values[np.argmax(np.abs(values))]
    z = (values / peak).real.reshape(xx.shape)
    contour = ax.contourf(xx * 1e3, yy * 1e3, z, levels=np.linspace(-1, 1, 21), cmap="RdBu_r")
    ax.contour(xx * 1e3, yy * 1e3, z, levels=[0.0], colors="k", linewidths=0.8)
    ax.plot(shapes.points[:, 0] * 1e3, shapes.points[:, 1] * 1e3, ".", color="0.3", ms=2)
    aside = _set_aside(model, len(shapes.points))
    if aside.size:
        ax.plot(shapes.points[aside, 0] * 1e3, shapes.points[aside, 1] * 1e3, "x", color="C3",
                ms=7, mew=1.6, label="set aside")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    if k == 0:
        ax.set_ylabel("y [mm]")
    ax.set_title(f"harmonic {n}: {n * model.f0:.1f} Hz, order {model.shapes[k].order}\n"
                 f"MAC with harmonic {harmonics[0]}: {model.similarity[0, k]:.4f}",
                 fontsize=9)
    return contour


# --------------------------------------------------------------------------------------------
# body


def fig_shapes_body(shapes: HarmonicShapes, model: SpatialModel) -> Figure:
    """Harmonic shapes of a 3-D body: every scan record's phasor against the vector model.

    Re and Im of every record's measured phasor against the vector model at its location, one
    panel per harmonic, one colour per measuring axis. Points on the diagonal are records the
    model reproduces; the spread about it is the scan's noise plus what the polynomials miss.

    Parameters
    ----------
    shapes : HarmonicShapes
        The measured shapes over locations ``(n_points, 6)`` (point [m], direction).
    model : SpatialModel
        The vector model fitted to them.

    Returns
    -------
    matplotlib.figure.Figure
        One axes per harmonic of the model, measured against modelled [um].
    """
    harmonics = [int(n) for n in model.harmonics]
    fig = Figure(figsize=(3.8 * len(harmonics) + 0.8, 3.8), layout="constrained")
    axes = fig.subplots(1, len(harmonics), squeeze=False)[0]
    axis_of = np.argmax(np.abs(shapes.points[:, 3:]), axis=1)
    for k, (ax, n) in enumerate(zip(axes, harmonics, strict=True)):
        measured = shapes.values[n - 1] * 1e6
        fitted = model.shape_values(n, shapes.points) * 1e6
        top = float(np.max(np.abs(np.concatenate([measured.view(float), fitted.view(float)]))))
        ax.plot([-top, top], [-top, top], color="0.6", lw=0.8)
        for a, colour in zip(range(3), ("C0", "C1", "C2"), strict=True):
            sel = axis_of == a
            if np.any(sel):
                ax.plot(measured[sel].real, fitted[sel].real, ".", color=colour, ms=3,
                        label=f"along {'xyz'[a]}")
                ax.plot(measured[sel].imag, fitted[sel].imag, ".", color=colour, ms=3)
        aside = _set_aside(model, len(measured))
        if aside.size:
            ax.plot(measured[aside].real, fitted[aside].real, "x", color="C3", ms=7,
                    label="set aside")
        ax.set_aspect("equal")
        ax.set_xlabel("measured Re, Im [um]")
        if k == 0:
            ax.set_ylabel("vector model [um]")
            ax.legend(fontsize=8, loc="upper left")
        ax.set_title(f"harmonic {n}: {n * model.f0:.1f} Hz, order {model.shapes[k].order}",
                     fontsize=9)
    return fig
