"""Forces of a run over a few periods (the paper's fig. 8): reactions, inertia and forces."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ...errors import DimensionError
from ...forces import ForceEstimate
from ._common import DEFAULT_PERIODS, fourier_series, legend_right, panel_title, time_window

__all__ = ["fig_forces"]


def fig_forces(estimate: ForceEstimate, truth: Mapping[str, np.ndarray] | None = None,
               periods: float = DEFAULT_PERIODS) -> Figure:
    """Inertia, reactions and the reconstructed forces over a few periods (fig. 8).

    Top: per gauge, the reaction R_r(t) (the Fourier series fitted to the gauge, the force on
    the structure) and the inertia term J_r(t). Bottom: every reconstructed force and their
    total (solid), the reactions-only (static) estimate -Psi^+ R(t) sample by sample (dashed)
    and, if given, the truth (dotted).

    Parameters
    ----------
    estimate : ForceEstimate
        The forces of one run.
    truth : Mapping of str to numpy.ndarray, optional
        Force name (and optionally "total") -> ``(n_samples,)`` [N] over ``estimate.time``, as
        :func:`forcecal.io.run_files.read_table_csv` reads ``truth/NAME.forces.csv``; other
        columns are ignored.
    periods : float
        Periods of the fundamental drawn.

    Returns
    -------
    matplotlib.figure.Figure
        2 axes. Lines are labelled "R NAME", "J NAME" (top) and "NAME", "total",
        "NAME reactions only", "total reactions only", "NAME truth", "total truth" (bottom);
        time in ms, forces in N.

    Raises
    ------
    DimensionError
        When a truth column of a force has not one value per sample.
    """
    t = estimate.time
    w = time_window(t, estimate.f0, periods)
    fig = Figure(figsize=(10.0, 7.5), layout="constrained")
    ax_r, ax_f = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.3))
    fig.suptitle(f"Run '{estimate.run_name}': reconstructed forces (f0 = {estimate.f0:.4f} Hz, "
                 f"inertia {100 * estimate.inertia_share:.1f} % of the AC force)")
    _draw_reactions(ax_r, t[w], estimate)
    if truth is not None:
        _check_truth(estimate, truth)
    _draw_forces(ax_f, w, estimate, truth)
    ax_f.set_xlabel("time [ms]")
    for ax in (ax_r, ax_f):
        ax.grid(alpha=0.3)
    ax_f.set_xlim(t[w][0] * 1e3, t[w][-1] * 1e3)
    return fig


def _draw_reactions(ax: Axes, t: np.ndarray, estimate: ForceEstimate) -> None:
    """The reaction R_r and the inertia term J_r [N] of every gauge at times ``t`` [s]."""
    reactions = fourier_series(estimate.reactions, estimate.f0, t)
    inertia = fourier_series(estimate.inertia, estimate.f0, t)
    for r, g in enumerate(estimate.gauge_names):
        color = f"C{r % 10}"
        ax.plot(t * 1e3, reactions[r], "-", color=color, lw=1.4, label=f"R {g}")
        ax.plot(t * 1e3, inertia[r], "--", color=color, lw=1.4, label=f"J {g}")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_ylabel("force [N]")
    panel_title(ax, "Reactions R (fitted, force on the structure) and inertia terms J per gauge")
    legend_right(ax)


def _check_truth(estimate: ForceEstimate, truth: Mapping[str, np.ndarray]) -> None:
    """Refuse a truth column of a force (or the total) without one value per sample."""
    t = estimate.time
    for name, values in truth.items():
        if np.shape(values) != t.shape and (name in estimate.force_names or name == "total"):
            raise DimensionError(
                f"truth column '{name}' has shape {np.shape(values)}; expected {t.shape} "
                f"(one value per sample of run '{estimate.run_name}')")


def _draw_forces(ax: Axes, w: slice, estimate: ForceEstimate,
                 truth: Mapping[str, np.ndarray] | None) -> None:
    """Every force and the total over the samples ``w``: with inertia, reactions only, truth."""
    tm = estimate.time[w] * 1e3
    items = [(name, estimate.series[k], estimate.static_series[k], f"C{(k + 2) % 10}")
             for k, name in enumerate(estimate.force_names)]
    items.append(("total", estimate.total_series, estimate.static_series.sum(axis=0), "k"))
    handles = []
    for name, series, static, color in items:
        lw = 1.8 if name == "total" else 1.3
        ax.plot(tm, series[w], "-", color=color, lw=lw, label=name)
        ax.plot(tm, static[w], "--", color=color, lw=1.0, label=f"{name} reactions only")
        if truth is not None and name in truth:
            ax.plot(tm, np.asarray(truth[name])[w], ":", color=color, lw=3.5, alpha=0.45,
                    label=f"{name} truth")
        handles.append(Line2D([], [], color=color, lw=lw, label=name))
    handles.append(Line2D([], [], color="0.3", ls="-", label="with inertia"))
    handles.append(Line2D([], [], color="0.3", ls="--", label="reactions only"))
    if truth is not None:
        handles.append(Line2D([], [], color="0.3", ls=":", lw=3.5, alpha=0.45, label="truth"))
    legend_right(ax, handles=handles)
    ax.set_ylabel("force on the structure [N]")
    panel_title(ax, "Reconstructed forces " + r"$\Psi^{+}(J - R)$" + " and their total")
