"""Time histories of a run: measured signals (the paper's fig. 6) and coordinates (fig. 7).

:func:`fig_signals` draws the measured current and probe displacements with their Fourier
series; :func:`fig_coordinates` the probes about their mean, the generalized coordinates and
the inertia terms they give at the gauges.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ...forces.steady import ForceEstimate
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import HarmonicFit, fit_harmonics
from ._common import (
    DEFAULT_PERIODS,
    MARKERS,
    check_run,
    fourier_series,
    legend_right,
    measured_width,
    panel_title,
    prefixed_unit,
    quantity,
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
    count, with the run's t0, and drawn over the first ``periods`` periods.

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
        2 axes: the current (lines "i measured", "i Fourier series"; time in ms, A) and the
        probes (lines "NAME measured", "NAME Fourier series"; time in ms, the y label's unit).
    """
    check_run(run, estimate)
    sig, sensors, s_fit = sensor_fit(rig, run, estimate)
    h = len(estimate.harmonics) - 1
    name = rig.actuator.current
    i_fit = fit_harmonics(sig[name], run.fs, estimate.f0, h, t0=run.t0)
    w = time_window(run.time, estimate.f0, periods)
    t = run.time[w]
    fig = Figure(figsize=(10.0, 6.5), layout="constrained")
    ax_i, ax_s = fig.subplots(2, 1, sharex=True)
    fig.suptitle(f"Run '{run.name}': measured signals and their Fourier series "
                 f"(f0 = {estimate.f0:.4f} Hz, harmonics 0..{h})")
    _draw_current(ax_i, t, sig[name][w], i_fit, name)
    _draw_probes(ax_s, t, sensors[:, w], s_fit, rig.sensor_names)
    ax_s.set_xlabel("time [ms]")
    for ax in (ax_i, ax_s):
        ax.grid(alpha=0.3)
        legend_right(ax)
    ax_s.set_xlim(t[0] * 1e3, t[-1] * 1e3)
    return fig


def _draw_current(ax: Axes, t: np.ndarray, current: np.ndarray, fit: HarmonicFit,
                  name: str) -> None:
    """The current [A] measured at times ``t`` [s] (drawn in ms) and its Fourier series."""
    ax.plot(t * 1e3, current, "-", color="C0", lw=2.5, alpha=0.5, label=f"{name} measured")
    ax.plot(t * 1e3, fit.evaluate(t), "--", color="k", lw=1.0,
            label=f"{name} Fourier series (residual rms "
                  f"{quantity(float(fit.residual_std), 'A', 2)})")
    ax.set_ylabel(f"current {name} [A]")
    panel_title(ax, "Coil current")


def _draw_probes(ax: Axes, t: np.ndarray, sensors: np.ndarray, fit: HarmonicFit,
                 names: list[str]) -> None:
    """The probes ``(n_sensors, n_t)`` [m] measured at times ``t`` and their Fourier series."""
    factor, unit = prefixed_unit(np.abs(sensors).max(), "m")
    series = fit.evaluate(t)
    for k, s in enumerate(names):
        _probe_pair(ax, t, k, len(names), sensors[k] * factor, series[k] * factor, s,
                    f"{s} Fourier series (residual rms "
                    f"{quantity(float(fit.residual_std[k]), 'm', 2)})")
    ax.set_ylabel(f"displacement [{unit}]")
    panel_title(ax, "Probe displacements")


def _probe_pair(ax: Axes, t: np.ndarray, k: int, n_probes: int, measured: np.ndarray,
                fitted: np.ndarray, name: str, fit_label: str) -> None:
    """Probe k's measured trace (wide, translucent) and its Fourier series (dashed, in its
    colour, with its marker, the markers staggered between probes: probes that read alike, as
    on a symmetric rig, stay apart), at times ``t`` [s] drawn in ms."""
    color = f"C{(k + 1) % 10}"
    step = max(len(t) // 12, 1)
    ax.plot(t * 1e3, measured, "-", color=color, lw=measured_width(k), alpha=0.55,
            label=f"{name} measured")
    ax.plot(t * 1e3, fitted, "--", color=color, lw=1.2, marker=MARKERS[k % len(MARKERS)],
            ms=5, mfc="none", markevery=(k * step // max(n_probes, 1), step), label=fit_label)


# --------------------------------------------------------------------------------------------
# fig. 7: probes, generalized coordinates, inertia


def fig_coordinates(run: Run, rig: Rig, estimate: ForceEstimate,
                    periods: float = DEFAULT_PERIODS) -> Figure:
    """Probe signals, generalized coordinates and the inertia terms over time (fig. 7).

    Top: the probe displacements with their mean removed (measured, and their Fourier series
    dashed). Middle: the generalized coordinate of each harmonic, Re(Q_n exp(j n w0 t)) [1]
    (Q_n is relative to the scan's shape phi_n, so a run driven like the scan has |Q_n| near 1).
    Bottom: the inertia term of every gauge, J_r(t) = sum_n Re(m_{r,n} (-(n w0)^2) Q_n
    exp(j n w0 t)) [N], where the factor (n w0)^2 amplifies the higher harmonics.

    Parameters
    ----------
    run : Run
        The run the estimate was computed from.
    rig : Rig
        The rig it was measured on (channel names and scales).
    estimate : ForceEstimate
        The run's forces, with their coordinates and inertia terms.
    periods : float
        Periods of the fundamental drawn.

    Returns
    -------
    matplotlib.figure.Figure
        3 axes; lines "NAME measured" / "NAME Fourier series" (top), "n = N" (middle, [1]),
        "J NAME" (bottom, [N]); time in ms.
    """
    check_run(run, estimate)
    _, sensors, s_fit = sensor_fit(rig, run, estimate)
    w = time_window(run.time, estimate.f0, periods)
    t = run.time[w]
    fig = Figure(figsize=(10.0, 8.5), layout="constrained")
    ax_s, ax_q, ax_j = fig.subplots(3, 1, sharex=True)
    fig.suptitle(f"Run '{run.name}': probes, generalized coordinates and inertia "
                 f"(f0 = {estimate.f0:.4f} Hz)")
    _draw_probes_ac(ax_s, t, sensors[:, w], s_fit, rig.sensor_names)
    _draw_coordinates(ax_q, t, estimate)
    _draw_inertia(ax_j, t, estimate)
    ax_j.set_xlabel("time [ms]")
    for ax in (ax_s, ax_q, ax_j):
        ax.grid(alpha=0.3)
        legend_right(ax)
    ax_j.set_xlim(t[0] * 1e3, t[-1] * 1e3)
    return fig


def _draw_probes_ac(ax: Axes, t: np.ndarray, sensors: np.ndarray, fit: HarmonicFit,
                    names: list[str]) -> None:
    """The probes ``(n_sensors, n_t)`` [m] and their Fourier series, less the series' mean."""
    mean = fit.phasors[:, 0].real[:, None]
    ac = sensors - mean
    series = fit.evaluate(t) - mean
    factor, unit = prefixed_unit(np.abs(ac).max(), "m")
    for k, s in enumerate(names):
        _probe_pair(ax, t, k, len(names), ac[k] * factor, series[k] * factor, s,
                    f"{s} Fourier series")
    ax.set_ylabel(f"displacement − mean [{unit}]")
    panel_title(ax, "Probe displacements about their mean")


def _draw_coordinates(ax: Axes, t: np.ndarray, estimate: ForceEstimate) -> None:
    """Re(Q_n exp(j n w0 t)) [1] of every harmonic at times ``t`` [s]."""
    c = estimate.coordinates
    for j, n in enumerate(c.harmonics):
        n = int(n)
        phasor = np.zeros(n + 1, dtype=complex)
        phasor[n] = c.q[j]
        ax.plot(t * 1e3, fourier_series(phasor, estimate.f0, t), "-", color=f"C{j % 10}",
                lw=1.2, label=f"n = {n}: |Q| = {abs(c.q[j]):#.4g} ± {c.q_std[j]:.1g}")
    ax.set_ylabel(r"Re$(Q_n e^{jn\omega_0 t})$ [1]")
    panel_title(ax, r"Generalized coordinate of each harmonic (relative to the scan's shape "
                    r"$\varphi_n$)")


def _draw_inertia(ax: Axes, t: np.ndarray, estimate: ForceEstimate) -> None:
    """The inertia term J_r [N] of every gauge at times ``t`` [s]."""
    inertia = fourier_series(estimate.inertia, estimate.f0, t)
    for r, g in enumerate(estimate.gauge_names):
        ax.plot(t * 1e3, inertia[r], ["-", "--", ":", "-."][r % 4], color=f"C{(r + 4) % 10}",
                lw=1.4, label=f"J {g}")
    ax.set_ylabel("inertia term $J_r$ [N]")
    panel_title(ax, r"Inertia at each gauge, $\sum_n m_{r,n}\,(-(n\omega_0)^2)\,Q_n"
                    r"\,e^{jn\omega_0 t}$")
