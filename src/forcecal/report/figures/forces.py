"""Forces of a run over a few periods (the paper's fig. 8): inertia, reactions and forces.

Three panels share the time axis, each on its own scale: the inertia term J_r(t) of every gauge
(the method's point, a small fraction of the reactions), the reactions R_r(t), and the forces
F_n(t) with their +-2 sigma band, the reactions-only estimate and, when given, the truth.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ...errors import DimensionError
from ...forces.steady import ForceEstimate
from ._common import (
    DEFAULT_PERIODS,
    MARKERS,
    fourier_series,
    legend_right,
    measured_width,
    panel_title,
    time_window,
)

__all__ = ["fig_forces"]

_MARKS_PER_PERIOD = 8


def force_sigma(estimate: ForceEstimate) -> np.ndarray:
    """Standard uncertainty of every force's waveform and of the total, constant over time.

    sigma = sqrt(sum_n std_n^2) over the harmonics 0..H: each harmonic's real and imaginary
    parts carry the standard uncertainty std_n, so Re(F_n exp(j n w0 t)) has the variance
    std_n^2 at every instant (the fundamental's own uncertainty is left out).

    Parameters
    ----------
    estimate : ForceEstimate
        The forces of one run.

    Returns
    -------
    numpy.ndarray
        ``(n_forces + 1,)`` [N]: every force, then the total.
    """
    std = np.vstack([estimate.force_std, estimate.total_std])
    sigma: np.ndarray = np.sqrt(np.sum(std**2, axis=1))
    return sigma


def fig_forces(estimate: ForceEstimate, truth: Mapping[str, np.ndarray] | None = None,
               periods: float = DEFAULT_PERIODS) -> Figure:
    """Inertia, reactions and the reconstructed forces over a few periods (fig. 8).

    Three panels sharing the time axis: (1) the inertia term J_r(t) of every gauge, (2) the
    reactions R_r(t) (the Fourier series fitted to the gauges, the forces on the structure),
    (3) every force and their total (solid, one colour and marker each) with a shaded +-2 sigma
    band (:func:`force_sigma`, constant over time), the reactions-only estimate -Psi^+ R(t)
    sample by sample (dashed) and, if given, the truth (thin black dotted, on top).

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
        3 axes. Lines are labelled with the gauge names (top two panels) and "NAME", "total",
        "NAME reactions only", "total reactions only", "NAME truth", "total truth" (bottom),
        whose bands are labelled "NAME ±2σ"; time in ms, forces in N.

    Raises
    ------
    DimensionError
        When a truth column of a force has not one value per sample.
    """
    if truth is not None:
        _check_truth(estimate, truth)
    t = estimate.time
    w = time_window(t, estimate.f0, periods)
    fig = Figure(figsize=(10.5, 9.0), layout="constrained")
    ax_j, ax_r, ax_f = fig.subplots(3, 1, sharex=True, height_ratios=(1.0, 1.0, 1.5))
    fig.suptitle(f"Run '{estimate.run_name}': forces from reactions and inertia "
                 f"(f0 = {estimate.f0:.4f} Hz; inertia {100 * estimate.inertia_share:.1f} % "
                 "of the AC force)")
    step = max(int((w.stop - w.start) / (periods * _MARKS_PER_PERIOD)), 1)
    _draw_gauges(ax_j, t[w], estimate, estimate.inertia, step)
    ax_j.set_ylabel("inertia $J_r(t)$ [N]")
    panel_title(ax_j, "Inertia term $J_r$ of every gauge (mass couplings $m_{r,n}$ times the "
                "accelerations of the generalized coordinates)")
    _draw_gauges(ax_r, t[w], estimate, estimate.reactions, step)
    ax_r.set_ylabel("reaction $R_r(t)$ [N]")
    panel_title(ax_r, "Reactions $R_r$ (fitted to the gauges; the forces on the structure)")
    _draw_forces(ax_f, w, estimate, truth, step)
    ax_f.set_xlabel("time [ms]")
    for ax in (ax_j, ax_r, ax_f):
        ax.grid(alpha=0.3)
    ax_f.set_xlim(t[w][0] * 1e3, t[w][-1] * 1e3)
    return fig


def _draw_gauges(ax: Axes, t: np.ndarray, estimate: ForceEstimate, phasors: np.ndarray,
                 step: int) -> None:
    """The series of ``phasors`` (n_gauges, H+1) [N] of every gauge at times ``t`` [s]."""
    values = fourier_series(phasors, estimate.f0, t)
    for r, g in enumerate(estimate.gauge_names):
        ax.plot(t * 1e3, values[r], "-", color=f"C{(r + 4) % 10}", lw=measured_width(r),
                alpha=0.8, marker=MARKERS[(r + 4) % len(MARKERS)], ms=5, mfc="none",
                markevery=(r * step // 2, step), label=g)
    ax.axhline(0.0, color="0.6", lw=0.6)
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
                 truth: Mapping[str, np.ndarray] | None, step: int) -> None:
    """Every force and the total over the samples ``w``: with inertia and its band, reactions
    only, truth."""
    tm = estimate.time[w] * 1e3
    sigma = force_sigma(estimate)
    names = (*estimate.force_names, "total")
    series = np.vstack([estimate.series, estimate.total_series])
    static = np.vstack([estimate.static_series, estimate.static_series.sum(axis=0)])
    handles: list[Line2D | Patch] = []
    for k, name in enumerate(names):
        color = "C3" if name == "total" else f"C{k % 3}"
        marker = MARKERS[k % len(MARKERS)]
        lw = 2.0 if name == "total" else measured_width(k)
        y = series[k, w]
        ax.fill_between(tm, y - 2 * sigma[k], y + 2 * sigma[k], color=color, alpha=0.25,
                        lw=0, label=f"{name} ±2σ")
        ax.plot(tm, y, "-", color=color, lw=lw, alpha=0.75, marker=marker, ms=5, mfc="none",
                markevery=(k * step // 3, step), label=name)
        ax.plot(tm, static[k, w], "--", color=color, lw=1.1, label=f"{name} reactions only")
        if truth is not None and name in truth:
            ax.plot(tm, np.asarray(truth[name])[w], ":", color="k", lw=1.0, zorder=5,
                    label=f"{name} truth")
        handles.append(Line2D([], [], color=color, lw=lw, marker=marker, mfc="none",
                              label=f"{name} (σ = {1e3 * sigma[k]:.2g} mN)"))
    handles.append(Line2D([], [], color="0.3", ls="-", label="with inertia"))
    handles.append(Patch(color="0.3", alpha=0.25, label="±2σ (σ = √Σₙσₙ²,\nconstant in time)"))
    handles.append(Line2D([], [], color="0.3", ls="--", label="reactions only"))
    if truth is not None:
        handles.append(Line2D([], [], color="k", ls=":", lw=1.0, label="truth"))
    legend_right(ax, handles=handles)
    ax.set_ylabel("force $F_n(t)$ [N]")
    panel_title(ax, "Forces on the structure " + r"$F = \Psi^{+}(J - R)$" + " and their total")
