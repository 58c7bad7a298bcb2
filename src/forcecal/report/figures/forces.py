"""Forces of a run over a few periods (the paper's fig. 8): inertia, reactions, forces, errors.

The inertia term J_r(t) of every gauge (the method's point, a small fraction of the reactions)
and the reactions R_r(t) span the figure; below, one column per force and one for the total:
the force beside the reactions-only estimate and the truth, and under it the error on its own
scale (estimate minus truth or, without a truth, the residual about its Fourier series averaged
over the record's periods), where the +-2 sigma band of the estimate is visible.
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
from ..cells import plus_minus, prefixed_unit, quantity
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
    """Inertia, reactions, the reconstructed forces and their errors over a few periods (fig. 8).

    Rows sharing the time axis: (1) the inertia term J_r(t) of every gauge, (2) the reactions
    R_r(t) (the Fourier series fitted to the gauges, the forces on the structure), then one
    column per force and one for the total: (3) the force (solid), the reactions-only estimate
    -Psi^+ R(t) sample by sample (dashed) and, if given, the truth (black dotted, on top);
    (4) its error on its own scale with the +-2 sigma band of the estimate about zero
    (:func:`force_sigma`, constant over time): estimate minus truth or, without a truth, the
    residual of the per-sample force about its Fourier series averaged over the record's
    periods (:func:`_folded_residual`: noise at the estimate's resolution, and any periodic
    part the kept harmonics miss).

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
        2 + 2 (n_forces + 1) axes: J, R, then per force and the total its force panel (lines
        "NAME", "NAME reactions only", "NAME truth"; N) and its error panel (line "NAME error"
        or "NAME residual", band "NAME ±2σ"; the y label's unit); time in ms.

    Raises
    ------
    DimensionError
        When a truth column of a force has not one value per sample.
    """
    if truth is not None:
        _check_truth(estimate, truth)
    t = estimate.time
    w = time_window(t, estimate.f0, periods)
    names = (*estimate.force_names, "total")
    fig = Figure(figsize=(12.0, 11.0), layout="constrained")
    grid = fig.add_gridspec(4, len(names), height_ratios=(1.0, 1.0, 1.3, 1.1))
    ax_j = fig.add_subplot(grid[0, :])
    ax_r = fig.add_subplot(grid[1, :], sharex=ax_j)
    fig.suptitle(f"Run '{estimate.run_name}': forces from reactions and inertia "
                 f"(f0 = {plus_minus(estimate.f0, estimate.f0_std)} Hz; inertia "
                 f"{100 * estimate.inertia_share:.1f} % of the AC force)")
    step = max(int((w.stop - w.start) / (periods * _MARKS_PER_PERIOD)), 1)
    _draw_gauges(ax_j, t[w], estimate, estimate.inertia, step)
    ax_j.set_ylabel("inertia $J_r(t)$ [N]")
    panel_title(ax_j, "Inertia term $J_r$ of every gauge (mass couplings $m_{r,n}$ times the "
                "accelerations of the generalized coordinates)")
    _draw_gauges(ax_r, t[w], estimate, estimate.reactions, step)
    ax_r.set_ylabel("reaction $R_r(t)$ [N]")
    panel_title(ax_r, "Reactions $R_r$ (fitted to the gauges; the forces on the structure)")
    ax_j.tick_params(labelbottom=False)
    ax_r.tick_params(labelbottom=False)
    _draw_columns(fig, grid, ax_j, w, estimate, truth)
    for ax in fig.axes:
        ax.grid(alpha=0.3)
    ax_j.set_xlim(t[w][0] * 1e3, t[w][-1] * 1e3)
    _legend(fig, truth is not None)
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


def _errors(estimate: ForceEstimate, truth: Mapping[str, np.ndarray] | None, w: slice
            ) -> tuple[np.ndarray, np.ndarray, bool]:
    """Per force and the total over the samples ``w`` [N]: the error of the estimate and of the
    reactions-only estimate against the truth, and True; without a truth, the residual
    (:func:`_folded_residual`) twice, and False."""
    series = np.vstack([estimate.series, estimate.total_series])[:, w]
    static = np.vstack([estimate.static_series, estimate.static_series.sum(axis=0)])[:, w]
    if truth is not None and all(n in truth for n in estimate.force_names):
        true = np.vstack([np.asarray(truth[n])[w] for n in estimate.force_names])
        total = np.asarray(truth["total"])[w] if "total" in truth else true.sum(axis=0)
        true = np.vstack([true, total])
        return series - true, static - true, True
    residual = _folded_residual(estimate)[:, w]
    return residual, residual, False


def _folded_residual(estimate: ForceEstimate) -> np.ndarray:
    """The per-sample force less its Fourier series, averaged over the record's periods.

    The per-sample force, -Psi^+ R(t) from the gauges' samples plus the inertia's series, less
    the estimate's series, is the reactions-only force less its own series (the inertia is a
    series). Averaged at each phase over every period, in 2H + 1 bins a period (H the highest
    harmonic), its standard deviation is about the estimate's sigma: what is left is noise at
    the estimate's resolution, or a periodic part the kept harmonics miss.

    Returns
    -------
    numpy.ndarray
        ``(n_forces + 1, n_samples)`` [N]: every force, then the total, at every sample.
    """
    t = estimate.time
    phasors = np.vstack([estimate.static, estimate.static.sum(axis=0)])
    static = np.vstack([estimate.static_series, estimate.static_series.sum(axis=0)])
    residual = static - fourier_series(phasors, estimate.f0, t)
    n_bins = 2 * (len(estimate.harmonics) - 1) + 1
    bins = np.minimum((np.mod(t * estimate.f0, 1.0) * n_bins).astype(int), n_bins - 1)
    counts = np.maximum(np.bincount(bins, minlength=n_bins), 1)
    means = np.stack([np.bincount(bins, weights=r, minlength=n_bins) / counts
                      for r in residual])
    folded: np.ndarray = means[:, bins]
    return folded


def _draw_columns(fig: Figure, grid, ax_t: Axes, w: slice, estimate: ForceEstimate,
                  truth: Mapping[str, np.ndarray] | None) -> None:
    """One column per force and the total: the force panel, and below it the error panel."""
    tm = estimate.time[w] * 1e3
    names = (*estimate.force_names, "total")
    sigma = force_sigma(estimate)
    series = np.vstack([estimate.series, estimate.total_series])[:, w]
    static = np.vstack([estimate.static_series, estimate.static_series.sum(axis=0)])[:, w]
    error, static_error, is_error = _errors(estimate, truth, w)
    span = max(3.0 * float(sigma.max()), float(np.quantile(np.abs(error), 0.995)) * 1.1)
    factor, unit = prefixed_unit(span, "N")
    first_f: Axes | None = None
    first_e: Axes | None = None
    for k, name in enumerate(names):
        color = "C3" if name == "total" else f"C{k % 3}"
        share = first_f if name != "total" else None
        ax_f = fig.add_subplot(grid[2, k], sharex=ax_t, sharey=share)
        ax_e = fig.add_subplot(grid[3, k], sharex=ax_t, sharey=first_e)
        first_f, first_e = first_f or ax_f, first_e or ax_e
        ax_f.plot(tm, series[k], "-", color=color, lw=2.0, alpha=0.8, label=name)
        ax_f.plot(tm, static[k], "--", color=color, lw=1.1, label=f"{name} reactions only")
        if truth is not None and name in truth:
            ax_f.plot(tm, np.asarray(truth[name])[w], ":", color="k", lw=1.2, zorder=5,
                      label=f"{name} truth")
        panel_title(ax_f, f"{name}" + (" (sum of the forces)" if name == "total" else ""))
        ax_f.tick_params(labelbottom=False)
        _draw_error(ax_e, tm, error[k] * factor, 2 * sigma[k] * factor, color, name, is_error)
        panel_title(ax_e, f"{'error' if is_error else 'residual'}; ±2σ = "
                          f"±{2 * sigma[k] * factor:.2g} {unit}")
        if is_error:
            ax_e.text(0.01, 0.03, "reactions only: RMS error "
                      + quantity(float(np.sqrt(np.mean(static_error[k] ** 2))), "N", 2)
                      + " (off this scale)", transform=ax_e.transAxes, fontsize="small")
        ax_e.set_xlabel("time [ms]")
        if k == 0:
            ax_f.set_ylabel("force [N]")
            ax_e.set_ylabel(("estimate − truth" if is_error else "residual") + f" [{unit}]")
            ax_e.set_ylim(-span * factor, span * factor)      # shared by every error panel


def _draw_error(ax: Axes, tm: np.ndarray, error: np.ndarray, band: float, color: str,
                name: str, is_error: bool) -> None:
    """An error (or residual) trace and the +-2 sigma band about zero, in the axis' unit."""
    ax.axhspan(-band, band, color=color, alpha=0.22, lw=0, label=f"{name} ±2σ")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.plot(tm, error, "-", color=color, lw=0.9,
            label=f"{name} {'error' if is_error else 'residual'}")


def _legend(fig: Figure, with_truth: bool) -> None:
    """The figure's legend of the line styles of the force and error panels."""
    handles: list[Line2D | Patch] = [
        Line2D([], [], color="0.3", lw=2.0, label="estimate (reactions and inertia)"),
        Line2D([], [], color="0.3", ls="--", lw=1.1, label="reactions only (inertia ignored)"),
    ]
    if with_truth:
        handles.append(Line2D([], [], color="k", ls=":", lw=1.2, label="truth"))
    handles.append(Line2D([], [], color="0.3", lw=0.9,
                          label="estimate − truth" if with_truth else
                          "residual: per-sample force − its Fourier series, averaged over "
                          "the record's periods"))
    handles.append(Patch(color="0.3", alpha=0.22,
                         label="±2σ of the estimate (σ = √Σₙσₙ², constant in time)"))
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize="small")
