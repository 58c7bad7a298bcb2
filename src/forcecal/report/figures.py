"""Figures of the method's stages, after the reference paper's figures 3 and 6 to 9.

Every function is pure: it takes the stage objects (SI units) and returns a new
:class:`matplotlib.figure.Figure` built without pyplot, so no global figure state is created
and nothing needs closing. Axes show readable units: positions in mm, time in ms, forces in N,
currents in A and displacements in the engineering prefix that suits their size (mm, µm, nm);
every label names its unit.

The figures:

- :func:`fig_shapes` (paper fig. 3): measured harmonic shapes with their fitted curves, and the
  normalized overlay of all harmonics with their MAC values;
- :func:`fig_signals` (fig. 6): measured current and probe displacements with their Fourier
  series;
- :func:`fig_coordinates` (fig. 7): probe signals, generalized coordinates, inertia terms;
- :func:`fig_forces` (fig. 8): inertia and reactions, reconstructed forces beside the
  reactions-only estimate and the truth;
- :func:`fig_residuals`: fit residuals, sensor-fit chi-square, force amplitudes per harmonic;
- :func:`fig_calibration` (fig. 9): force against DC current and AC amplitude per gap with the
  calibrated law.

:func:`save_png` writes a figure atomically; :func:`png_bytes` renders it in memory.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ..actuator import Calibration, ExtrapolationWarning, Selection, predict
from ..errors import DimensionError, InputError
from ..forces import ForceEstimate, channels_si
from ..harmonics import fit_harmonics
from ..io.atomic import atomic_path
from ..records import Run
from ..rig import Rig
from ..scan import HarmonicShapes
from ..spatial import ONE_SHAPE_MAC, SpatialModel

__all__ = [
    "CalibrationPoints",
    "fig_calibration",
    "fig_coordinates",
    "fig_forces",
    "fig_residuals",
    "fig_shapes",
    "fig_shapes_2d",
    "fig_shapes_body",
    "fig_signals",
    "law_harmonics",
    "png_bytes",
    "save_png",
]

DEFAULT_PERIODS = 3.0
"""Periods of the fundamental drawn by the time-history figures."""

_PREFIXES = ((1.0, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n"))


# --------------------------------------------------------------------------------------------
# helpers


def _unit(peak: float, base: str) -> tuple[float, str]:
    """Factor and unit that show values up to ``peak`` [base unit] as numbers of 1 to 999.

    >>> _unit(3e-5, "m")
    (1000000.0, 'µm')
    """
    peak = float(abs(peak))
    for size, prefix in _PREFIXES:
        if peak >= size:
            return 1.0 / size, prefix + base
    if peak == 0.0 or not np.isfinite(peak):
        return 1.0, base
    return 1e9, "n" + base


def _quantity(value: float, base: str, digits: int = 3) -> str:
    """``value`` with ``digits`` significant digits in the prefix that suits it: ``0.2 µm``."""
    factor, unit = _unit(value, base)
    v = value * factor
    if v == 0 or not np.isfinite(v):
        return f"{v:g} {unit}"
    places = digits - 1 - int(np.floor(np.log10(abs(v))))
    return f"{round(v, places):.{max(places, 0)}f} {unit}"


def _evaluate(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """Fourier series ``(..., H+1)`` phasors at absolute times t -> ``(..., n_t)``.

    The convention of :mod:`forcecal.harmonics`: x(t) = sum_n Re(X_n exp(j n w0 t)).
    """
    n = np.arange(phasors.shape[-1])
    cycles = np.mod(np.multiply.outer(n * f0, np.asarray(t, dtype=float)), 1.0)
    return (phasors @ np.exp(2j * np.pi * cycles)).real


def _window(t: np.ndarray, f0: float, periods: float) -> slice:
    """The leading samples of ``t`` that span ``periods`` periods of ``f0`` (at least 2)."""
    if periods <= 0:
        raise InputError(f"periods must be positive; got {periods}")
    end = t[0] + periods / f0
    m = int(np.searchsorted(t, end, side="right"))
    return slice(0, max(m, min(2, len(t))))


def _measured_width(k: int) -> float:
    """Line width of measured trace k: wide and translucent, wider for the first ones, so that
    traces that coincide (a symmetric rig) and the dashed fit on top all stay visible."""
    return max(3.2 - 1.2 * k, 1.2)


def _legend_right(ax, **kwargs) -> None:
    """A legend beside the axes, so that it never hides a curve."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
              borderaxespad=0.0, **kwargs)


def _sensor_fit(rig: Rig, run: Run, estimate: ForceEstimate):
    sig = channels_si(rig, run)
    h = len(estimate.harmonics) - 1
    sensors = np.stack([sig[s] for s in rig.sensor_names])
    return sig, sensors, fit_harmonics(sensors, run.fs, estimate.f0, h, t0=run.t0)


def _check_run(run: Run, estimate: ForceEstimate) -> None:
    if run.n_samples != len(estimate.time):
        raise DimensionError(
            f"run '{run.source}' has {run.n_samples} samples but the estimate of run "
            f"'{estimate.run_name}' has {len(estimate.time)}; pass the run it was computed from"
        )


# --------------------------------------------------------------------------------------------
# fig. 3: harmonic shapes


def fig_shapes(shapes: HarmonicShapes, model: SpatialModel, n_fine: int = 401) -> Figure:
    """The scan's harmonic shapes and their fit (the paper's fig. 3).

    Left, one panel per harmonic of the model: Re and Im of the measured phase-aligned phasor
    H_n(x_k) at the scan points (markers, with their standard uncertainty as error bars) and of
    the fitted shape phi_n(x) on a fine grid (lines). Right: every fitted shape normalized by
    its complex value of largest magnitude over the grid, so that identical shapes coincide,
    with the measured points normalized alike, the shapes' MAC values and whether one shape
    serves all harmonics (:attr:`SpatialModel.one_shape`).

    Parameters
    ----------
    shapes : the measured shapes, values (n_harm, n_points) complex [m] over 1-D points [m]
    model : the spatial model fitted to them
    n_fine : number of grid points of the fitted curves, spanning the scan points

    Returns
    -------
    Figure with ``len(model.harmonics) + 1`` axes (the per-harmonic panels first). The lines
    are labelled "Re measured", "Im measured", "Re fitted", "Im fitted" (x in mm, the shape in
    the unit of the y label) and, on the right, "n = N" (normalized fitted shape, Re).
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
    first = None
    for row, n in enumerate(harmonics):
        ax = fig.add_subplot(grid[row, 0], sharex=first)
        first = first or ax
        k = int(np.flatnonzero(shapes.harmonics == n)[0])
        meas, std = shapes.values[k], shapes.std[k]
        fit = model.shape_values(n, xf)
        factor, unit = _unit(max(np.abs(meas).max(), np.abs(fit).max()), "m")
        ax.axhline(0.0, color="0.8", lw=0.6)
        ax.errorbar(x * 1e3, meas.real * factor, yerr=std * factor, fmt="o", ms=3.5, color="C0",
                    elinewidth=0.6, label="Re measured")
        ax.errorbar(x * 1e3, meas.imag * factor, yerr=std * factor, fmt="s", ms=3.0,
                    mfc="none", color="C1", elinewidth=0.6, label="Im measured")
        ax.plot(xf * 1e3, fit.real * factor, "-", color="C0", lw=1.4, label="Re fitted")
        ax.plot(xf * 1e3, fit.imag * factor, "--", color="C1", lw=1.4, label="Im fitted")
        m = model.index(n)
        ax.set_title(f"harmonic {n}: {n * shapes.f0:.1f} Hz, polynomial order "
                     f"{model.shapes[m].order}, scan SNR {model.snr[n - 1]:.0f}",
                     loc="left", fontsize="medium")
        ax.set_ylabel(f"$H_{{{n}}}$ [{unit}]")
        ax.grid(alpha=0.3)
        if row == 0:
            ax.legend(loc="best", fontsize="small", ncols=2)
        if row < len(harmonics) - 1:
            ax.tick_params(labelbottom=False)
    first.set_xlim(xf[0] * 1e3, xf[-1] * 1e3)
    ax.set_xlabel("x [mm]")

    right = fig.add_subplot(grid[:, 1])
    right.axhline(0.0, color="0.8", lw=0.6)
    for j, n in enumerate(harmonics):
        fit = model.shape_values(n, xf)
        ref = fit[np.argmax(np.abs(fit))]
        k = int(np.flatnonzero(shapes.harmonics == n)[0])
        color = f"C{j % 10}"
        right.plot(x * 1e3, (shapes.values[k] / ref).real, ".", ms=4, alpha=0.45, color=color,
                   label=f"_measured {n}")
        right.plot(xf * 1e3, (fit / ref).real, "-", lw=1.6, color=color,
                   label=f"n = {n} ({n * shapes.f0:.0f} Hz)")
    right.set_xlim(xf[0] * 1e3, xf[-1] * 1e3)
    right.set_xlabel("x [mm]")
    right.set_ylabel(r"Re $\varphi_n(x) / \varphi_n(x_\mathrm{peak})$ [1]")
    right.set_title("Normalized shapes (lines: fitted, dots: measured)", loc="left",
                    fontsize="medium")
    right.grid(alpha=0.3)
    right.legend(loc="best", fontsize="small", title=_mac_text(model, harmonics),
                 title_fontsize="small", alignment="left", framealpha=0.9)
    lo, hi = right.get_ylim()
    right.set_ylim(min(lo, -0.1), max(hi, 1.1))
    return fig


def fig_shapes_body(shapes: HarmonicShapes, model: SpatialModel) -> Figure:
    """Harmonic shapes of a 3-D body: every scan record's measured phasor against the vector
    model at its location, Re and Im, one panel per harmonic, one colour per axis.

    Points on the diagonal are records the model reproduces; the spread about it is the scan's
    noise plus what the polynomials miss.
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
        ax.set_aspect("equal")
        ax.set_xlabel("measured Re, Im [um]")
        if k == 0:
            ax.set_ylabel("vector model [um]")
            ax.legend(fontsize=8, loc="upper left")
        ax.set_title(f"harmonic {n}: {n * model.f0:.1f} Hz, order {model.shapes[k].order}",
                     fontsize=9)
    return fig


def fig_shapes_2d(shapes: HarmonicShapes, model: SpatialModel, n_fine: int = 81) -> Figure:
    """Harmonic deflection shapes of a plate: the fitted shape per harmonic as a contour map.

    Each panel shows Re of the fitted shape, rotated to its most real phase and normalized by
    its peak, over the outline's box, with the scan points as dots and the MAC of every
    harmonic against the first in its title.
    """
    harmonics = [int(n) for n in model.harmonics]
    fig = Figure(figsize=(4.2 * len(harmonics) + 0.8, 4.0), layout="constrained")
    axes = fig.subplots(1, len(harmonics), squeeze=False)[0]
    dom = model.shapes[0].basis.domain
    xs = np.linspace(dom[0, 0], dom[0, 1], n_fine)
    ys = np.linspace(dom[1, 0], dom[1, 1], n_fine)
    xx, yy = np.meshgrid(xs, ys)
    grid = np.column_stack([xx.ravel(), yy.ravel()])
    contour = None
    for k, (ax, n) in enumerate(zip(axes, harmonics, strict=True)):
        values = model.shape_values(n, grid)
        peak = values[np.argmax(np.abs(values))]
        z = (values / peak).real.reshape(xx.shape)
        contour = ax.contourf(xx * 1e3, yy * 1e3, z, levels=np.linspace(-1, 1, 21),
                              cmap="RdBu_r")
        ax.contour(xx * 1e3, yy * 1e3, z, levels=[0.0], colors="k", linewidths=0.8)
        ax.plot(shapes.points[:, 0] * 1e3, shapes.points[:, 1] * 1e3, ".", color="0.3", ms=2)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        if k == 0:
            ax.set_ylabel("y [mm]")
        ax.set_title(f"harmonic {n}: {n * model.f0:.1f} Hz, order {model.shapes[k].order}\n"
                     f"MAC with harmonic {harmonics[0]}: {model.similarity[0, k]:.4f}",
                     fontsize=9)
    fig.colorbar(contour, ax=list(axes), label=r"Re $\varphi_n / \varphi_n(\mathrm{peak})$ [1]",
                 shrink=0.8)
    fig.suptitle(f"Harmonic deflection shapes from the scan '{Path(shapes.source).name}' "
                 f"({shapes.points.shape[0]} points; black: node lines)")
    return fig


def _mac_text(model: SpatialModel, harmonics: list[int]) -> str:
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
# fig. 6: measured signals and their Fourier series


def fig_signals(run: Run, rig: Rig, estimate: ForceEstimate,
                periods: float = DEFAULT_PERIODS) -> Figure:
    """Measured current and probe displacements with their fitted Fourier series (fig. 6).

    The series are fitted over the whole record with :func:`forcecal.harmonics.fit_harmonics`
    at the estimate's fundamental and harmonic count, with the run's t0, and drawn over the
    first ``periods`` periods.

    Returns
    -------
    Figure with 2 axes: the current (lines "i measured", "i Fourier series"; time in ms, A) and
    the probes (lines "NAME measured", "NAME Fourier series"; time in ms, the y label's unit).
    """
    _check_run(run, estimate)
    sig, sensors, s_fit = _sensor_fit(rig, run, estimate)
    h = len(estimate.harmonics) - 1
    name = rig.actuator.current
    current = sig[name]
    i_fit = fit_harmonics(current, run.fs, estimate.f0, h, t0=run.t0)
    t = run.time
    w = _window(t, estimate.f0, periods)
    tm = t[w] * 1e3
    fig = Figure(figsize=(10.0, 6.5), layout="constrained")
    ax_i, ax_s = fig.subplots(2, 1, sharex=True)
    fig.suptitle(f"Run '{run.name}': measured signals and their Fourier series "
                 f"(f0 = {estimate.f0:.4f} Hz, harmonics 0..{h})")
    ax_i.plot(tm, current[w], "-", color="C0", lw=2.5, alpha=0.5, label=f"{name} measured")
    ax_i.plot(tm, i_fit.evaluate(t[w]), "--", color="k", lw=1.0,
              label=f"{name} Fourier series (residual rms "
                    f"{_quantity(float(i_fit.residual_std), 'A', 2)})")
    ax_i.set_ylabel(f"current {name} [A]")
    ax_i.set_title("Coil current", loc="left", fontsize="medium")
    factor, unit = _unit(np.abs(sensors[:, w]).max(), "m")
    for k, s in enumerate(rig.sensor_names):
        ax_s.plot(tm, sensors[k, w] * factor, "-", color=f"C{(k + 1) % 10}",
                  lw=_measured_width(k), alpha=0.55, label=f"{s} measured")
        ax_s.plot(tm, s_fit.evaluate(t[w])[k] * factor, "--", color="k", lw=1.0,
                  label=f"{s} Fourier series (residual rms "
                        f"{_quantity(float(s_fit.residual_std[k]), 'm', 2)})")
    ax_s.set_ylabel(f"displacement [{unit}]")
    ax_s.set_title("Probe displacements", loc="left", fontsize="medium")
    ax_s.set_xlabel("time [ms]")
    for ax in (ax_i, ax_s):
        ax.grid(alpha=0.3)
        _legend_right(ax)
    ax_s.set_xlim(tm[0], tm[-1])
    return fig


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

    Returns
    -------
    Figure with 3 axes; lines "NAME measured" / "NAME Fourier series" (top), "n = N" (middle,
    [1]), "J NAME" (bottom, [N]); time in ms.
    """
    _check_run(run, estimate)
    _, sensors, s_fit = _sensor_fit(rig, run, estimate)
    t = run.time
    w = _window(t, estimate.f0, periods)
    tm = t[w] * 1e3
    f0 = estimate.f0
    fig = Figure(figsize=(10.0, 8.5), layout="constrained")
    ax_s, ax_q, ax_j = fig.subplots(3, 1, sharex=True)
    fig.suptitle(f"Run '{run.name}': probes, generalized coordinates and inertia "
                 f"(f0 = {f0:.4f} Hz)")
    mean = s_fit.phasors[:, 0].real[:, None]
    ac = sensors[:, w] - mean
    series = s_fit.evaluate(t[w]) - mean
    factor, unit = _unit(np.abs(ac).max(), "m")
    for k, s in enumerate(rig.sensor_names):
        ax_s.plot(tm, ac[k] * factor, "-", color=f"C{(k + 1) % 10}", lw=_measured_width(k),
                  alpha=0.55, label=f"{s} measured")
        ax_s.plot(tm, series[k] * factor, "--", color="k", lw=1.0, label=f"{s} Fourier series")
    ax_s.set_ylabel(f"displacement − mean [{unit}]")
    ax_s.set_title("Probe displacements about their mean", loc="left", fontsize="medium")

    c = estimate.coordinates
    for j, n in enumerate(c.harmonics):
        n = int(n)
        phasor = np.zeros(n + 1, dtype=complex)
        phasor[n] = c.q[j]
        ax_q.plot(tm, _evaluate(phasor, f0, t[w]), "-", color=f"C{j % 10}", lw=1.2,
                  label=f"n = {n}: |Q| = {abs(c.q[j]):#.4g} ± {c.q_std[j]:.1g}")
    ax_q.set_ylabel(r"Re$(Q_n e^{jn\omega_0 t})$ [1]")
    ax_q.set_title(r"Generalized coordinate of each harmonic (relative to the scan's shape "
                   r"$\varphi_n$)", loc="left", fontsize="medium")

    inertia = _evaluate(estimate.inertia, f0, t[w])
    for r, g in enumerate(estimate.gauge_names):
        ax_j.plot(tm, inertia[r], ["-", "--", ":", "-."][r % 4], color=f"C{(r + 4) % 10}",
                  lw=1.4, label=f"J {g}")
    ax_j.set_ylabel("inertia term $J_r$ [N]")
    ax_j.set_title(r"Inertia at each gauge, $\sum_n m_{r,n}\,(-(n\omega_0)^2)\,Q_n"
                   r"\,e^{jn\omega_0 t}$", loc="left", fontsize="medium")
    ax_j.set_xlabel("time [ms]")
    for ax in (ax_s, ax_q, ax_j):
        ax.grid(alpha=0.3)
        _legend_right(ax)
    ax_j.set_xlim(tm[0], tm[-1])
    return fig


# --------------------------------------------------------------------------------------------
# fig. 8: forces


def fig_forces(estimate: ForceEstimate, truth: Mapping[str, np.ndarray] | None = None,
               periods: float = DEFAULT_PERIODS) -> Figure:
    """Inertia, reactions and the reconstructed forces over a few periods (fig. 8).

    Top: per gauge, the reaction R_r(t) (the Fourier series fitted to the gauge, the force on
    the structure) and the inertia term J_r(t). Bottom: every reconstructed force and their
    total (solid), the reactions-only (static) estimate -Psi^+ R(t) sample by sample (dashed)
    and, if given, the truth (dotted).

    Parameters
    ----------
    estimate : the forces of one run
    truth : force name (and optionally "total") -> (n_samples,) [N] over ``estimate.time``, as
        :func:`forcecal.io.run_files.read_table_csv` reads ``truth/NAME.forces.csv``; other
        columns are ignored
    periods : periods of the fundamental drawn

    Returns
    -------
    Figure with 2 axes. Lines are labelled "R NAME", "J NAME" (top) and "NAME", "total",
    "NAME reactions only", "total reactions only", "NAME truth", "total truth" (bottom);
    time in ms, forces in N.
    """
    t = estimate.time
    w = _window(t, estimate.f0, periods)
    tm = t[w] * 1e3
    fig = Figure(figsize=(10.0, 7.5), layout="constrained")
    ax_r, ax_f = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.3))
    fig.suptitle(f"Run '{estimate.run_name}': reconstructed forces (f0 = {estimate.f0:.4f} Hz, "
                 f"inertia {100 * estimate.inertia_share:.1f} % of the AC force)")
    reactions = _evaluate(estimate.reactions, estimate.f0, t[w])
    inertia = _evaluate(estimate.inertia, estimate.f0, t[w])
    for r, g in enumerate(estimate.gauge_names):
        color = f"C{r % 10}"
        ax_r.plot(tm, reactions[r], "-", color=color, lw=1.4, label=f"R {g}")
        ax_r.plot(tm, inertia[r], "--", color=color, lw=1.4, label=f"J {g}")
    ax_r.axhline(0.0, color="0.6", lw=0.6)
    ax_r.set_ylabel("force [N]")
    ax_r.set_title("Reactions R (fitted, force on the structure) and inertia terms J per gauge",
                   loc="left", fontsize="medium")
    _legend_right(ax_r)

    if truth is not None:
        for name, values in truth.items():
            if np.shape(values) != t.shape and (name in estimate.force_names or name == "total"):
                raise DimensionError(
                    f"truth column '{name}' has shape {np.shape(values)}; expected {t.shape} "
                    f"(one value per sample of run '{estimate.run_name}')")
    items = [(name, estimate.series[k], estimate.static_series[k], f"C{(k + 2) % 10}")
             for k, name in enumerate(estimate.force_names)]
    items.append(("total", estimate.total_series, estimate.static_series.sum(axis=0), "k"))
    handles = []
    for name, series, static, color in items:
        lw = 1.8 if name == "total" else 1.3
        ax_f.plot(tm, series[w], "-", color=color, lw=lw, label=name)
        ax_f.plot(tm, static[w], "--", color=color, lw=1.0, label=f"{name} reactions only")
        if truth is not None and name in truth:
            ax_f.plot(tm, np.asarray(truth[name])[w], ":", color=color, lw=3.5, alpha=0.45,
                      label=f"{name} truth")
        handles.append(Line2D([], [], color=color, lw=lw, label=name))
    handles.append(Line2D([], [], color="0.3", ls="-", label="with inertia"))
    handles.append(Line2D([], [], color="0.3", ls="--", label="reactions only"))
    if truth is not None:
        handles.append(Line2D([], [], color="0.3", ls=":", lw=3.5, alpha=0.45, label="truth"))
    _legend_right(ax_f, handles=handles)
    ax_f.set_ylabel("force on the structure [N]")
    ax_f.set_title("Reconstructed forces " + r"$\Psi^{+}(J - R)$" + " and their total",
                   loc="left", fontsize="medium")
    ax_f.set_xlabel("time [ms]")
    for ax in (ax_r, ax_f):
        ax.grid(alpha=0.3)
    ax_f.set_xlim(tm[0], tm[-1])
    return fig


# --------------------------------------------------------------------------------------------
# diagnostics


_CHANNEL_UNITS = {"gauge": "N", "sensor": "m", "current": "A", "flux": "Wb"}


def fig_residuals(estimate: ForceEstimate, run: Run | None = None, rig: Rig | None = None
                  ) -> Figure:
    """Diagnostics of one run's estimate.

    With ``run`` and ``rig``: the harmonic-fit residuals of every channel over the record, each
    divided by its residual standard deviation (stated in the channel's unit) and stacked. Then
    the reduced chi-square of the sensor fit per harmonic (about 1 when the shape model explains
    the probes), and the amplitude of each force per harmonic with its standard uncertainty
    (error bars) on a log axis, beside the reactions-only amplitude (open markers); harmonics the
    estimate did not keep are left out.

    Returns
    -------
    Figure with 3 axes (residuals, chi-square, amplitudes) when ``run`` and ``rig`` are given,
    else 2. The amplitude lines are labelled "NAME" (with inertia) and "NAME reactions only",
    x = harmonic number (offset by a few hundredths per force), y = amplitude [N]; the
    chi-square line is labelled "chi2".
    """
    if (run is None) != (rig is None):
        raise InputError("fig_residuals: the channel residuals need both the run and the rig")
    with_run = run is not None
    fig = Figure(figsize=(11.0, 8.0 if with_run else 4.5), layout="constrained")
    fig.suptitle(f"Run '{estimate.run_name}': fit residuals and force amplitudes per harmonic")
    if with_run:
        _check_run(run, estimate)
        grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 2.2), height_ratios=(1.3, 1.0))
        _draw_residuals(fig.add_subplot(grid[0, :]), run, rig, estimate)
        ax_c, ax_a = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    else:
        ax_c, ax_a = fig.subplots(1, 2, width_ratios=(1.0, 2.2))

    c = estimate.coordinates
    ax_c.axhline(1.0, color="0.5", lw=0.8, ls="--", label="expected (1)")
    finite = np.isfinite(c.chi2)
    if finite.any():
        ax_c.plot(c.harmonics[finite], c.chi2[finite], "o", color="C0", ms=7, label="chi2")
        for n, v in zip(c.harmonics[finite], c.chi2[finite], strict=True):
            ax_c.annotate(f"{v:.2g}", (n, v), textcoords="offset points", xytext=(6, 4),
                          fontsize="small")
        ax_c.set_yscale("log")
        lo, hi = np.nanmin(c.chi2[finite]), np.nanmax(c.chi2[finite])
        ax_c.set_ylim(min(lo, 1.0) / 3, max(hi, 1.0) * 3)
        ax_c.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        ax_c.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax_c.yaxis.set_minor_formatter(NullFormatter())
    else:
        ax_c.text(0.5, 0.5, "one sensor:\nno chi-square\n(the fit is exact)",
                  transform=ax_c.transAxes, ha="center", va="center")
    ax_c.set_xticks(c.harmonics)
    ax_c.set_xlim(c.harmonics.min() - 0.6, c.harmonics.max() + 0.6)
    ax_c.set_xlabel("harmonic n")
    ax_c.set_ylabel(r"reduced $\chi^2$ of the sensor fit [1]")
    ax_c.set_title("Shape model vs probes", loc="left", fontsize="medium")
    ax_c.grid(alpha=0.3, which="both")
    ax_c.legend(loc="upper left", fontsize="small")

    harmonics = estimate.harmonics
    show = estimate.kept.copy()
    show[0] = show[0] and estimate.dc_observed
    n_f = len(estimate.force_names)
    offsets = (np.arange(n_f) - (n_f - 1) / 2) * 0.18
    for k, name in enumerate(estimate.force_names):
        amp = np.abs(estimate.force[k])
        std = estimate.force_std[k]
        ok = show & (amp > 0)
        x = harmonics[ok] + offsets[k]
        lower = np.minimum(std[ok], 0.95 * amp[ok])
        color = f"C{(k + 2) % 10}"
        ax_a.errorbar(x, amp[ok], yerr=np.vstack([lower, std[ok]]), fmt="o", ms=6, color=color,
                      capsize=3, label=name)
        stat = np.abs(estimate.static[k])
        ok_s = show & (stat > 0)
        ax_a.plot(harmonics[ok_s] + offsets[k] + 0.07, stat[ok_s], "D", ms=6, mfc="none",
                  color=color, label=f"{name} reactions only")
    ax_a.set_yscale("log")
    ax_a.set_xticks(harmonics)
    ax_a.set_xticklabels([f"{n}\n{n * estimate.f0:.0f} Hz" if n else "0\nDC" for n in harmonics])
    ax_a.set_xlabel("harmonic n")
    ax_a.set_ylabel("amplitude $|F_n|$ [N]")
    ax_a.set_title("Force amplitudes (error bars: standard uncertainty)", loc="left",
                   fontsize="medium")
    ax_a.grid(alpha=0.3, which="both")
    ax_a.legend(loc="upper right", fontsize="small", ncols=2)
    dropped = [int(n) for n in harmonics[~estimate.kept]]
    if dropped:
        ax_a.text(0.01, 0.02, "not kept (not supported by the data): "
                  + ", ".join(map(str, dropped)), transform=ax_a.transAxes, fontsize="small",
                  va="bottom")
    return fig


def _draw_residuals(ax, run: Run, rig: Rig, estimate: ForceEstimate) -> None:
    sig = channels_si(rig, run)
    kinds = [(g, "gauge") for g in rig.gauge_names] + [(s, "sensor") for s in rig.sensor_names]
    kinds.append((rig.actuator.current, "current"))
    if rig.actuator.flux and rig.actuator.flux in sig:
        kinds.append((rig.actuator.flux, "flux"))
    h = len(estimate.harmonics) - 1
    fit = fit_harmonics(np.stack([sig[name] for name, _ in kinds]), run.fs, estimate.f0, h,
                        t0=run.t0)
    t = run.time
    spacing = 10.0
    ticks, labels = [], []
    for k, (name, kind) in enumerate(kinds):
        sigma = float(fit.residual_std[k])
        offset = (len(kinds) - 1 - k) * spacing
        scaled = fit.residuals[k] / sigma if sigma > 0 else fit.residuals[k] * 0.0
        ax.plot(t, scaled + offset, "-", lw=0.4, color=f"C{k % 10}", label=name)
        ticks.append(offset)
        labels.append(f"{name}\nσ = {_quantity(sigma, _CHANNEL_UNITS[kind], 2)}")
    ax.set_yticks(ticks)
    ax.set_yticklabels(labels, fontsize="small")
    ax.set_ylim(-spacing / 2 - 1.5, (len(kinds) - 1) * spacing + spacing / 2 + 1.5)
    ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("residual / σ [1], stacked")
    ax.set_title(f"Residuals of the harmonic fits (harmonics 0..{h}) over the whole record",
                 loc="left", fontsize="medium")
    ax.grid(alpha=0.3, axis="x")


# --------------------------------------------------------------------------------------------
# fig. 9: calibration


@dataclass(frozen=True)
class CalibrationPoints:
    """One point per run of a calibration campaign, for :func:`fig_calibration`.

    Attributes
    ----------
    gap : (n_runs,) [m] static air gap of the run (every pole)
    dc : (n_runs,) [A] mean coil current I_0
    ac : (n_runs,) [A] amplitude of the current's fundamental |I_1|
    force_dc : (n_runs,) [N] mean total actuator force F_0 (the estimate's ``total[0]``)
    force_ac : (n_runs,) [N] amplitude of the total force's fundamental |F_1|
    force_dc_std, force_ac_std : (n_runs,) [N] or None, standard uncertainties (error bars)
    law_dc, law_ac : (n_runs,) [N] or None: the calibrated law's mean and fundamental amplitude
        of the total force for each run's own instantaneous current and gaps (see
        :func:`law_harmonics`). They include the structure's motion, which closes the gap
        during a run; without them the law can only be drawn at the static gap.
    names : run names (one per run) or empty
    """

    gap: np.ndarray
    dc: np.ndarray
    ac: np.ndarray
    force_dc: np.ndarray
    force_ac: np.ndarray
    force_dc_std: np.ndarray | None = None
    force_ac_std: np.ndarray | None = None
    law_dc: np.ndarray | None = None
    law_ac: np.ndarray | None = None
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = None
        for key in ("gap", "dc", "ac", "force_dc", "force_ac", "force_dc_std", "force_ac_std",
                    "law_dc", "law_ac"):
            value = getattr(self, key)
            if value is None:
                continue
            arr = np.atleast_1d(np.asarray(value, dtype=float))
            n = arr.shape[0] if n is None else n
            if arr.shape != (n,):
                raise DimensionError(f"calibration points: '{key}' has shape {arr.shape}; "
                                     f"expected ({n},), one value per run")
            object.__setattr__(self, key, arr)
        if n == 0:
            raise InputError("calibration points: no runs")
        if not np.all(self.gap > 0):
            raise InputError("calibration points: every 'gap' must be a positive length [m]")
        if (self.law_dc is None) != (self.law_ac is None):
            raise InputError("calibration points: give both 'law_dc' and 'law_ac' or neither")
        names = tuple(str(s) for s in self.names)
        if names and len(names) != n:
            raise DimensionError(f"calibration points: {len(names)} names for {n} runs")
        object.__setattr__(self, "names", names)

    @property
    def n_runs(self) -> int:
        return int(self.gap.shape[0])

    @classmethod
    def from_estimates(cls, rig: Rig, runs: Sequence[Run], estimates: Sequence[ForceEstimate],
                       gaps: Sequence[float] | None = None) -> CalibrationPoints:
        """Points from runs and their force estimates.

        The current's mean and fundamental amplitude are fitted from each run's current channel
        (the rig's scale applied) at the estimate's fundamental; the force's are the estimate's
        total phasors. ``gaps`` [m] gives each run's static gap (e.g. the manifest's ``gap``);
        None takes the rig's first force point's gap. Add the law's values per run with
        ``dataclasses.replace(points, law_dc=..., law_ac=...)`` (see :func:`law_harmonics`).
        """
        if len(runs) != len(estimates):
            raise DimensionError(f"{len(runs)} runs but {len(estimates)} estimates")
        if gaps is None:
            gap0 = rig.forces[0].gap if rig.forces else None
            if gap0 is None:
                raise InputError(f"rig '{rig.source}': no static gap for the calibration points; "
                                 "give 'gap' in [[forces]] or pass gaps")
            gaps = [gap0] * len(runs)
        if len(gaps) != len(runs):
            raise DimensionError(f"{len(gaps)} gaps for {len(runs)} runs")
        dc, ac = [], []
        for run, est in zip(runs, estimates, strict=True):
            current = channels_si(rig, run)[rig.actuator.current]
            fit = fit_harmonics(current, run.fs, est.f0, 1, t0=run.t0)
            dc.append(fit.phasors[0].real)
            ac.append(abs(fit.phasors[1]))
        return cls(
            gap=np.asarray(gaps, dtype=float), dc=np.array(dc), ac=np.array(ac),
            force_dc=np.array([e.total[0].real for e in estimates]),
            force_ac=np.array([abs(e.total[1]) for e in estimates]),
            force_dc_std=np.array([e.total_std[0] for e in estimates]),
            force_ac_std=np.array([e.total_std[1] for e in estimates]),
            names=tuple(e.run_name for e in estimates),
        )


def law_harmonics(calibration: Calibration, current: np.ndarray, gaps: np.ndarray, fs: float,
                  f0: float, t0: float = 0.0) -> tuple[float, float]:
    """The law's mean and fundamental amplitude of the total force over one run.

    Parameters
    ----------
    calibration : a (current, gap) law
    current : (n_samples,) [A] the run's coil current
    gaps : (n_samples, n_poles) or (n_samples,) [m] the instantaneous air gap at each pole
    fs : [Hz] sampling rate; f0 : [Hz] the run's fundamental; t0 : [s] time of the first sample

    Returns
    -------
    (F_0, |F_1|) [N] of :func:`forcecal.actuator.predict`'s total force, by a harmonic fit
    """
    current = np.asarray(current, dtype=float)
    gaps = np.asarray(gaps, dtype=float)
    if gaps.ndim == 1:
        gaps = gaps[:, None]
    with warnings.catch_warnings():
        # the runs the law was fitted to: samples left out of the fit may reach a little past
        # the calibrated range, which is no extrapolation worth a warning
        warnings.simplefilter("ignore", ExtrapolationWarning)
        total = predict(calibration, current, gaps).total
    fit = fit_harmonics(total, fs, f0, 1, t0=t0)
    return float(fit.phasors[0].real), float(abs(fit.phasors[1]))


def _clusters(values: np.ndarray, tol: float) -> np.ndarray:
    """Cluster label per value; neighbours (sorted) closer than ``tol`` share a label."""
    order = np.argsort(values)
    labels = np.empty(len(values), dtype=int)
    current = 0
    for j, i in enumerate(order):
        if j and values[i] - values[order[j - 1]] > tol:
            current += 1
        labels[i] = current
    return labels


def _law_cycle(cal: Calibration, dc: np.ndarray, ac: float, gap: float,
               n_phase: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Mean and fundamental amplitude [N] of the law's total force over one cycle.

    The current i = dc + ac cos(theta) at the static gap (the structure's motion neglected);
    both (len(dc),).
    """
    theta = 2 * np.pi * np.arange(n_phase) / n_phase
    current = (np.asarray(dc, dtype=float)[:, None] + ac * np.cos(theta)).ravel()
    with warnings.catch_warnings():
        # a static gap may lie just outside the range of the instantaneous gaps fitted
        warnings.simplefilter("ignore", ExtrapolationWarning)
        total = predict(cal, current, gap).total.reshape(len(dc), n_phase)
    mean = total.mean(axis=1)
    fundamental = 2 * np.abs(np.mean(total * np.exp(-1j * theta), axis=1))
    return mean, fundamental


_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
_DASHES = ("-", "--", "-.", ":")


def fig_calibration(points: CalibrationPoints | Mapping[str, Sequence[float]],
                    law: Calibration | Selection | None = None) -> Figure:
    """Force against DC current and AC amplitude for every gap, with the calibrated law (fig. 9).

    Top left: the mean total force F_0 against the DC current I_0; top right: the amplitude of
    the force's fundamental |F_1| against I_0. One colour per static gap, one marker (and line
    style) per AC amplitude, one open marker per run, so that repeated runs show as overlapping
    markers (their count is written beside them).

    With a (current, gap) law, the bottom panels show each run's relative residual against the
    law, and the law is drawn in one of two ways:

    - when ``points`` carries ``law_dc`` and ``law_ac`` (the law at each run's own
      instantaneous current and gaps, :func:`law_harmonics`): as a small filled marker per run,
      joined by thin lines per gap and AC amplitude; the residuals are taken against them;
    - otherwise: as smooth curves of the law's total force (:func:`forcecal.actuator.predict`)
      over one cycle of i = I_0 + I_1 cos(theta) at the static gap, its mean and fundamental
      amplitude, over the calibrated current range. The structure's motion, which closes the
      gap during a run, is neglected there, which the legend and the residual panel say.

    Parameters
    ----------
    points : :class:`CalibrationPoints` (e.g. from :meth:`CalibrationPoints.from_estimates`),
        or a mapping with its field names (gap, dc, ac, force_dc, force_ac, ...)
    law : the calibration (or the selection whose chosen law is drawn); None draws the points
        only. A flux law cannot be drawn against current: it is named in a note, without curves.

    Returns
    -------
    Figure with 4 axes (F_0, |F_1|, and their residuals in %) when a (current, gap) law is
    given, else 2. The runs' lines are labelled "gap G mm, AC A A" (x: A, y: N); the law's
    "law gap G mm, AC A A"; the residuals' lines carry the runs' labels (y: %).
    """
    pts = points if isinstance(points, CalibrationPoints) else CalibrationPoints(**points)
    cal = law.calibration() if isinstance(law, Selection) else law
    drawable = cal is not None and not cal.law_object.needs_flux
    at_runs = drawable and pts.law_dc is not None
    gap_id = _clusters(pts.gap, 1e-3 * float(np.median(pts.gap)))
    ac_id = _clusters(pts.ac, 0.05 * max(float(np.max(pts.ac)), 1e-12))
    fig = Figure(figsize=(12.0, 9.5 if drawable else 5.5), layout="constrained")
    if drawable:
        (ax0, ax1), (rx0, rx1) = fig.subplots(2, 2, sharex=True, height_ratios=(2.0, 1.0))
        dc_law, ac_law = (pts.law_dc, pts.law_ac) if at_runs else _static_law(cal, pts)
    else:
        ax0, ax1 = fig.subplots(1, 2, sharex=True)
    fig.suptitle(_calibration_title(pts, cal, int(gap_id.max()) + 1))
    handles = []
    for g in range(gap_id.max() + 1):
        in_gap = gap_id == g
        gap = float(np.mean(pts.gap[in_gap]))
        color = f"C{g % 10}"
        handles.append(Line2D([], [], color=color, lw=2, label=f"gap {gap * 1e3:.2f} mm"))
        for a in range(ac_id.max() + 1):
            sel = in_gap & (ac_id == a)
            if not sel.any():
                continue
            amp = float(np.mean(pts.ac[sel]))
            tag = f"gap {gap * 1e3:.2f} mm, AC {amp:.3g} A"
            marker = _MARKERS[a % len(_MARKERS)]
            dash = _DASHES[a % len(_DASHES)]
            style = {"fmt": marker, "color": color, "ms": 7, "mfc": "none", "mew": 1.4,
                     "capsize": 2, "label": tag}
            ax0.errorbar(pts.dc[sel], pts.force_dc[sel], yerr=_err(pts.force_dc_std, sel),
                         **style)
            ax1.errorbar(pts.dc[sel], pts.force_ac[sel], yerr=_err(pts.force_ac_std, sel),
                         **style)
            _mark_repeats(ax0, pts.dc[sel], pts.force_dc[sel])
            _mark_repeats(ax1, pts.dc[sel], pts.force_ac[sel])
            if not drawable:
                continue
            if at_runs:
                order = np.argsort(pts.dc[sel])
                for ax, values in ((ax0, pts.law_dc), (ax1, pts.law_ac)):
                    ax.plot(pts.dc[sel][order], values[sel][order], dash, color=color, lw=1.0,
                            marker=marker, ms=3.5, label=f"law {tag}")
            else:
                lo = max(cal.current_range[0] + amp, 0.0)
                hi = cal.current_range[1] - amp
                if hi > lo:
                    grid = np.linspace(lo, hi, 60)
                    mean, fund = _law_cycle(cal, grid, amp, gap)
                    ax0.plot(grid, mean, dash, color=color, lw=1.2, label=f"law {tag}")
                    ax1.plot(grid, fund, dash, color=color, lw=1.2, label=f"law {tag}")
            for rx, measured, model in ((rx0, pts.force_dc, dc_law), (rx1, pts.force_ac, ac_law)):
                floor = 0.01 * max(float(np.median(np.abs(measured))), 1e-12)
                rel = (measured[sel] - model[sel]) / np.maximum(np.abs(model[sel]), floor)
                rx.plot(pts.dc[sel], 100 * rel, marker, color=color, ms=7, mfc="none", mew=1.4,
                        label=tag)
    for a in range(ac_id.max() + 1):
        amp = float(np.mean(pts.ac[ac_id == a]))
        handles.append(Line2D([], [], color="0.3", marker=_MARKERS[a % len(_MARKERS)],
                              mfc="none", ls=_DASHES[a % len(_DASHES)] if drawable else "none",
                              label=f"AC {amp:.3g} A"))
    if at_runs:
        handles.append(Line2D([], [], color="0.3", marker="o", ms=3.5, ls="-", lw=1.0,
                              label="law at each run's current and gap"))
    elif drawable:
        handles.append(Line2D([], [], color="0.3", ls="-", lw=1.2,
                              label="law at the static gap (motion neglected)"))
    if cal is not None and not drawable:
        ax0.text(0.02, 0.98, f"law '{cal.law}' predicts from flux:\nno curve against current",
                 transform=ax0.transAxes, va="top", fontsize="small")
    ax0.set_ylabel("mean force $F_0$ [N]")
    ax0.set_title("Mean total force vs DC current", loc="left", fontsize="medium")
    ax1.set_ylabel("fundamental amplitude $|F_1|$ [N]")
    ax1.set_title("Fundamental of the total force vs DC current", loc="left", fontsize="medium")
    axes = [ax0, ax1]
    if drawable:
        for rx, what in ((rx0, "$F_0$"), (rx1, "$|F_1|$")):
            rx.axhline(0.0, color="0.5", lw=0.8)
            rx.set_ylabel(f"{what}: (run − law) / law [%]")
            rx.set_xlabel("DC current $I_0$ [A]")
        where = ("at each run's current and gap" if at_runs
                 else "at the static gap (the structure's motion neglected)")
        rx0.set_title(f"Residuals against the law {where}", loc="left", fontsize="medium")
        axes += [rx0, rx1]
    else:
        ax0.set_xlabel("DC current $I_0$ [A]")
        ax1.set_xlabel("DC current $I_0$ [A]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 4),
               fontsize="small")
    return fig


def _static_law(cal: Calibration, pts: CalibrationPoints) -> tuple[np.ndarray, np.ndarray]:
    """The law's (F_0, |F_1|) for every run at its static gap, (n_runs,) each [N]."""
    dc, ac = np.empty(pts.n_runs), np.empty(pts.n_runs)
    for k in range(pts.n_runs):
        mean, fund = _law_cycle(cal, pts.dc[k:k + 1], float(pts.ac[k]), float(pts.gap[k]))
        dc[k], ac[k] = mean[0], fund[0]
    return dc, ac


def _calibration_title(pts: CalibrationPoints, cal: Calibration | None, n_gaps: int) -> str:
    title = f"Actuator calibration: {pts.n_runs} runs at {n_gaps} gaps"
    if cal is None:
        return title
    law = cal.law_object
    params = [f"{n} = {_param(v, e, u)}" for n, v, e, u in
              zip(law.param_names, cal.params, cal.stderr, law.param_units, strict=True)]
    lines = [title, f"law '{cal.law}': {law.formula}"]
    for start in range(0, len(params), 3):
        lines.append("; ".join(params[start:start + 3]))
    return "\n".join(lines)


def _param(value: float, std: float, unit: str) -> str:
    unit = "" if unit in ("-", "1") else unit
    return f"{value:.5g} ± {std:.2g} {unit}".strip()


def _err(std: np.ndarray | None, sel: np.ndarray) -> np.ndarray | None:
    return None if std is None else std[sel]


def _mark_repeats(ax, x: np.ndarray, y: np.ndarray) -> None:
    """Write the count beside markers of runs with the same setpoint (x within 2 %)."""
    ids = _clusters(x, 0.02 * max(float(np.max(np.abs(x))), 1e-12))
    for c in range(ids.max() + 1 if len(ids) else 0):
        sel = ids == c
        if sel.sum() > 1:
            ax.annotate(f"×{int(sel.sum())}", (float(np.mean(x[sel])), float(np.mean(y[sel]))),
                        textcoords="offset points", xytext=(7, -3), fontsize="small")


# --------------------------------------------------------------------------------------------
# output


def save_png(fig: Figure, path: str | Path, dpi: float = 120) -> Path:
    """Write ``fig`` as PNG to ``path`` atomically (a temporary name, then a rename).

    On any failure the temporary file is removed and an existing ``path`` is left untouched.
    """
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return Path(path)


def png_bytes(fig: Figure, dpi: float = 100) -> bytes:
    """``fig`` rendered as PNG in memory."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()
