"""A run's measured signals (the paper's fig. 6) and its generalized coordinates (fig. 7).

:func:`fig_signals` draws the measured current and every probe's displacement, each in its own
panel, with their Fourier series; :func:`fig_coordinates` the generalized coordinate of each
harmonic as the displacement and the acceleration it stands for, with its uncertainty, and the
inertia force each harmonic contributes over time.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ...forces.steady import ForceEstimate
from ...model.spatial import SpatialModel
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import HarmonicFit, fit_harmonics
from ..cells import plus_minus, prefixed_unit, quantity
from ._common import (
    DEFAULT_PERIODS,
    check_run,
    fourier_series,
    legend_right,
    panel_title,
    sensor_fit,
    time_window,
)

__all__ = ["fig_coordinates", "fig_signals"]


# --------------------------------------------------------------------------------------------
# fig. 6: measured signals and their Fourier series


def fig_signals(run: Run, rig: Rig, estimate: ForceEstimate,
                periods: float = DEFAULT_PERIODS) -> Figure:
    """Measured current and probe displacements with their fitted Fourier series (fig. 6).

    The series are fitted over the whole record with
    :func:`forcecal.signals.harmonics.fit_harmonics` at the estimate's fundamental and harmonic
    count, with the run's t0, and drawn over the first ``periods`` periods. Every probe has its
    own panel (two per row, one colour each, on one scale), so probes that read alike, as on a
    symmetric rig, stay apart.

    Parameters
    ----------
    run : Run
        The run the estimate was computed from.
    rig : Rig
        The rig it was measured on (channel names and scales).
    estimate : ForceEstimate
        The run's forces (fundamental and harmonic count).
    periods : float
        Periods of the fundamental drawn.

    Returns
    -------
    matplotlib.figure.Figure
        1 + n_sensors axes: the current (lines "i measured", "i Fourier series"; time in ms, A)
        and each probe (lines "NAME measured", "NAME Fourier series"; time in ms, the y label's
        unit).
    """
    check_run(run, estimate)
    sig, sensors, s_fit = sensor_fit(rig, run, estimate)
    h = len(estimate.harmonics) - 1
    name = rig.actuator.current
    i_fit = fit_harmonics(sig[name], run.fs, estimate.f0, h, t0=run.t0)
    w = time_window(run.time, estimate.f0, periods)
    t = run.time[w]
    n_s = len(rig.sensor_names)
    cols = min(n_s, 2)
    rows = -(-n_s // cols)
    fig = Figure(figsize=(12.0, 2.8 + 2.5 * rows), layout="constrained")
    grid = fig.add_gridspec(1 + rows, cols, height_ratios=(1.1,) + (1.0,) * rows)
    fig.suptitle(f"Run '{run.name}': measured signals and their Fourier series "
                 f"(f0 = {plus_minus(estimate.f0, estimate.f0_std)} Hz, harmonics 0..{h})")
    ax_i = fig.add_subplot(grid[0, :])
    _draw_current(ax_i, t, sig[name][w], i_fit, name)
    factor, unit = prefixed_unit(np.abs(sensors[:, w]).max(), "m")
    first: Axes | None = None
    for k, s in enumerate(rig.sensor_names):
        ax = fig.add_subplot(grid[1 + k // cols, k % cols], sharex=ax_i, sharey=first)
        first = first or ax
        _draw_probe(ax, t, sensors[k, w] * factor, s_fit, k, factor, s)
        ax.set_ylabel(f"displacement [{unit}]")
        ax.set_xlabel("time [ms]" if k // cols == rows - 1 else "")
    ax_i.tick_params(labelbottom=False)
    for ax in fig.axes:
        ax.grid(alpha=0.3)
    ax_i.set_xlim(t[0] * 1e3, t[-1] * 1e3)
    fig.legend(handles=[Line2D([], [], color="0.4", lw=3.0, alpha=0.5, label="measured"),
                        Line2D([], [], color="k", lw=1.0, ls="--",
                               label=f"Fourier series (harmonics 0..{h}, fitted over the "
                                     "whole record)")],
               loc="outside lower center", ncols=2, fontsize="small")
    return fig


def _draw_current(ax: Axes, t: np.ndarray, current: np.ndarray, fit: HarmonicFit,
                  name: str) -> None:
    """The current [A] measured at times ``t`` [s] (drawn in ms) and its Fourier series."""
    ax.plot(t * 1e3, current, "-", color="C0", lw=3.0, alpha=0.5, label=f"{name} measured")
    ax.plot(t * 1e3, fit.evaluate(t), "--", color="k", lw=1.0, label=f"{name} Fourier series")
    ax.set_ylabel(f"current {name} [A]")
    panel_title(ax, f"Coil current {name} (Fourier series residual rms "
                    f"{quantity(float(fit.residual_std), 'A', 2)})")


def _draw_probe(ax: Axes, t: np.ndarray, measured: np.ndarray, fit: HarmonicFit, k: int,
                factor: float, name: str) -> None:
    """Probe k measured at times ``t`` [s] (drawn in ms; already scaled by ``factor``), wide
    and translucent in its own colour, and its Fourier series dashed on top."""
    color = f"C{(k + 1) % 10}"
    ax.plot(t * 1e3, measured, "-", color=color, lw=3.0, alpha=0.5, label=f"{name} measured")
    ax.plot(t * 1e3, fit.evaluate(t)[k] * factor, "--", color="k", lw=1.0,
            label=f"{name} Fourier series")
    panel_title(ax, f"Probe {name} (Fourier series residual rms "
                    f"{quantity(float(fit.residual_std[k]), 'm', 2)})")


# --------------------------------------------------------------------------------------------
# fig. 7: generalized coordinates and the inertia they give


def shape_peaks(model: SpatialModel, rig: Rig, harmonics: np.ndarray) -> np.ndarray:
    """The largest |phi_n| over the structure of each harmonic's (first) scan shape [m].

    Parameters
    ----------
    model : SpatialModel
        The spatial model the coordinates refer to.
    rig : Rig
        Its rig (the structure's grid).
    harmonics : numpy.ndarray
        The harmonics.

    Returns
    -------
    numpy.ndarray
        ``(n_harmonics,)`` [m].
    """
    points = rig.structure.grid()
    return np.array([np.max(np.abs(model.shape_values(int(n), points))) for n in harmonics])


def fig_coordinates(run: Run, rig: Rig, estimate: ForceEstimate,
                    periods: float = DEFAULT_PERIODS, model: SpatialModel | None = None
                    ) -> Figure:
    """The generalized coordinates and the inertia they give (fig. 7).

    Top left: the amplitude of each harmonic's coordinate, |Q_n| times the largest |phi_n| of
    its scan shape over the structure (with ``model``: the displacement it stands for, else
    |Q_n| relative to the scan's shape [1]), with +-2 sigma error bars on a log axis; top
    right: the acceleration it gives, (n w0)^2 times that. Bottom: the inertia force each
    harmonic contributes, summed over the gauges, sum_r Re(J_{r,n} exp(j n w0 t)) [N], and
    their sum, over the first ``periods`` periods.

    Parameters
    ----------
    run : Run
        The run the estimate was computed from.
    rig : Rig
        The rig it was measured on.
    estimate : ForceEstimate
        The run's forces, with their coordinates and inertia terms.
    periods : float
        Periods of the fundamental drawn.
    model : SpatialModel, optional
        The spatial model the coordinates refer to, for their displacement.

    Returns
    -------
    matplotlib.figure.Figure
        3 axes: displacement (error bars labelled "displacement"; the y label's unit) and
        acceleration (labelled "acceleration") per harmonic, and the inertia (lines "n = N",
        "sum"; time in ms, N).
    """
    check_run(run, estimate)
    c = estimate.coordinates
    peaks = (shape_peaks(model, rig, c.harmonics) if model is not None
             else np.ones(len(c.harmonics)))
    w = time_window(run.time, estimate.f0, periods)
    fig = Figure(figsize=(12.0, 8.0), layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=(1.1, 1.0))
    ax_q, ax_a = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])
    ax_j = fig.add_subplot(grid[1, :])
    fig.suptitle(f"Run '{run.name}': generalized coordinates and the inertia they give "
                 f"(f0 = {plus_minus(estimate.f0, estimate.f0_std)} Hz)")
    w0 = 2 * np.pi * estimate.f0
    si = model is not None
    _draw_amplitudes(ax_q, c.harmonics, np.abs(c.q) * peaks, c.q_std * peaks,
                     "m" if si else "1", si, "displacement")
    _draw_amplitudes(ax_a, c.harmonics, (c.harmonics * w0) ** 2 * np.abs(c.q) * peaks,
                     (c.harmonics * w0) ** 2 * c.q_std * peaks, "m/s²" if si else "1/s²", si,
                     "acceleration")
    panel_title(ax_q, "Displacement of each harmonic at its shape's peak, $|Q_n|\\,"
                "\\max|\\varphi_n|$" if model is not None else
                "Coordinate of each harmonic, $|Q_n|$ (relative to the scan's shape)")
    panel_title(ax_a, "Acceleration it gives, $(n\\omega_0)^2$ times that")
    _draw_inertia(ax_j, run.time[w], estimate)
    return fig


def _draw_amplitudes(ax: Axes, harmonics: np.ndarray, amp: np.ndarray, std: np.ndarray,
                     base: str, prefixed: bool, what: str) -> None:
    """Amplitudes per harmonic [base] with +-2 sigma error bars on a log axis (in the prefix
    of ``base`` that suits the largest when ``prefixed``), each written as value +- standard
    uncertainty beside its marker."""
    factor, unit = prefixed_unit(float(np.max(amp)), base) if prefixed else (1.0, base)
    y, e = amp * factor, std * factor
    ax.errorbar(harmonics, y, yerr=np.vstack([np.minimum(2 * e, 0.95 * y), 2 * e]), fmt="o",
                ms=7, color="C0", capsize=4, label=what)
    for n, v, u in zip(harmonics, y, e, strict=True):
        ax.annotate(plus_minus(float(v), float(u), "" if unit == "1" else unit), (n, v),
                    textcoords="offset points",
                    xytext=(8, 4), fontsize="small")
    ax.set_yscale("log")
    ax.set_ylim(float(np.min(y - 2 * e, initial=np.inf, where=y - 2 * e > 0)) / 3,
                float(np.max(y + 2 * e)) * 4)
    ax.set_xticks(harmonics)
    ax.set_xlim(harmonics.min() - 0.5, harmonics.max() + 1.3)
    ax.set_xlabel("harmonic n")
    ax.set_ylabel(f"{what} [{unit}]")
    ax.grid(alpha=0.3, which="both")


def _draw_inertia(ax: Axes, t: np.ndarray, estimate: ForceEstimate) -> None:
    """The inertia force of each harmonic summed over the gauges [N] at times ``t`` [s], and
    the sum over the harmonics."""
    total = estimate.inertia.sum(axis=0)
    for j, n in enumerate(estimate.coordinates.harmonics):
        n = int(n)
        phasor = np.zeros(total.shape, dtype=complex)
        phasor[n] = total[n]
        ax.plot(t * 1e3, fourier_series(phasor, estimate.f0, t), "-", color=f"C{j % 10}",
                lw=1.4, label=f"n = {n}")
    ax.plot(t * 1e3, fourier_series(total, estimate.f0, t), "--", color="k", lw=1.2,
            label="sum")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlim(t[0] * 1e3, t[-1] * 1e3)
    ax.set_xlabel("time [ms]")
    ax.set_ylabel(r"$\sum_r J_{r,n}(t)$ [N]")
    panel_title(ax, r"Inertia force of each harmonic, summed over the gauges, "
                    r"$\sum_r m_{r,n}\,(-(n\omega_0)^2)\,Q_n\,e^{jn\omega_0 t}$")
    ax.grid(alpha=0.3)
    legend_right(ax)
