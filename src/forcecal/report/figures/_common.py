"""Helpers shared by the figures: readable units, Fourier series over a window, line styles,
a calibrated law over a run or a cycle (fig. 9).

Nothing here draws a whole figure. Axes show readable units: positions in mm, time in ms,
forces in N, currents in A and displacements in the engineering prefix that suits their size
(mm, µm, nm, :func:`forcecal.report.cells.prefixed_unit`); every label names its unit.
"""

from __future__ import annotations

import re
import warnings
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from ...actuator import Calibration, ExtrapolationWarning, predict, predict_flux
from ...actuator.prediction import Prediction
from ...errors import DimensionError, InputError
from ...forces.steady import ForceEstimate, channels_si
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import HarmonicFit, fit_harmonics

__all__: list[str] = []

DEFAULT_PERIODS = 3.0
"""Periods of the fundamental drawn by the time-history figures."""

def math_unit(unit: str) -> str:
    """A plain-text unit as matplotlib math text: ``N m^2/A^2`` -> ``N m$^{2}$/A$^{2}$``.

    Parameters
    ----------
    unit : str
        The unit, with ``^`` for powers (a law's ``param_units``).

    Returns
    -------
    str
        The unit for a label; ``""`` for a dimensionless ``-`` or ``1``.
    """
    if unit in ("-", "1"):
        return ""
    return re.sub(r"\^\(?([-\w.]+)\)?", r"$^{\1}$", unit)


def fourier_series(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """A Fourier series at absolute times, x(t) = sum_n Re(X_n exp(j n w0 t)).

    Parameters
    ----------
    phasors : numpy.ndarray
        ``(..., H+1)`` complex phasors X_0..X_H (convention of :mod:`forcecal.signals.harmonics`).
    f0 : float
        The fundamental [Hz].
    t : numpy.ndarray
        ``(n_t,)`` absolute times [s].

    Returns
    -------
    numpy.ndarray
        ``(..., n_t)`` the series' values, in the phasors' unit.
    """
    n = np.arange(phasors.shape[-1])
    cycles = np.mod(np.multiply.outer(n * f0, np.asarray(t, dtype=float)), 1.0)
    return (phasors @ np.exp(2j * np.pi * cycles)).real


def time_window(t: np.ndarray, f0: float, periods: float) -> slice:
    """The leading samples of ``t`` that span ``periods`` periods of ``f0`` (at least 2).

    Parameters
    ----------
    t : numpy.ndarray
        ``(n_samples,)`` increasing sample times [s].
    f0 : float
        The fundamental [Hz].
    periods : float
        Periods to span; must be positive.

    Returns
    -------
    slice
        The leading samples.
    """
    if periods <= 0:
        raise InputError(f"periods must be positive; got {periods}")
    end = t[0] + periods / f0
    m = int(np.searchsorted(t, end, side="right"))
    return slice(0, max(m, min(2, len(t))))


MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
"""Marker of trace k (open, every few samples): traces that coincide stay distinguishable."""


def measured_width(k: int) -> float:
    """Line width of measured trace k: wide (drawn translucent), wider for the first ones.

    So traces that coincide (a symmetric rig) and the dashed fit on top all stay visible.

    Parameters
    ----------
    k : int
        Index of the trace.

    Returns
    -------
    float
        The line width [pt].
    """
    return max(3.2 - 1.2 * k, 1.2)


def legend_right(ax: Axes, **kwargs: Any) -> None:
    """A legend beside the axes, so that it never hides a curve.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes.
    **kwargs
        Further arguments of :meth:`matplotlib.axes.Axes.legend` (e.g. ``handles``).
    """
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
              borderaxespad=0.0, **kwargs)


def panel_title(ax: Axes, text: str) -> None:
    """The title of one panel, left-aligned in the medium font size.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The panel.
    text : str
        Its title.
    """
    ax.set_title(text, loc="left", fontsize="medium")


def sensor_fit(rig: Rig, run: Run, estimate: ForceEstimate
               ) -> tuple[dict[str, np.ndarray], np.ndarray, HarmonicFit]:
    """The run's channels in SI and the Fourier series of its sensors.

    Parameters
    ----------
    rig : Rig
        The rig the run was measured on (channel scales).
    run : Run
        The run.
    estimate : ForceEstimate
        The run's forces: its fundamental and harmonic count are used.

    Returns
    -------
    tuple of (dict, numpy.ndarray, HarmonicFit)
        Every channel in SI by name, the sensors ``(n_sensors, n_samples)`` [m] and their fit.
    """
    sig = channels_si(rig, run)
    h = len(estimate.harmonics) - 1
    sensors = np.stack([sig[s] for s in rig.sensor_names])
    return sig, sensors, fit_harmonics(sensors, run.fs, estimate.f0, h, t0=run.t0)


def check_run(run: Run, estimate: ForceEstimate) -> None:
    """Refuse a run that is not the one the estimate was computed from.

    Parameters
    ----------
    run : Run
        The run.
    estimate : ForceEstimate
        The estimate drawn with it.

    Raises
    ------
    DimensionError
        When their sample counts differ.
    """
    if run.n_samples != len(estimate.time):
        raise DimensionError(
            f"run '{run.source}' has {run.n_samples} samples but the estimate of run "
            f"'{estimate.run_name}' has {len(estimate.time)}; pass the run it was computed from"
        )


# --------------------------------------------------------------------------------------------
# a calibrated law over a run or a cycle


def law_harmonics(calibration: Calibration, current: np.ndarray, gaps: np.ndarray, fs: float,
                  f0: float, t0: float = 0.0,
                  flux: np.ndarray | None = None) -> tuple[float, float]:
    """The law's mean and fundamental amplitude of the total force over one run.

    Parameters
    ----------
    calibration : Calibration
        A (current, gap) law, or the flux law (then ``flux`` is needed).
    current : numpy.ndarray
        ``(n_samples,)`` [A] the run's coil current.
    gaps : numpy.ndarray
        ``(n_samples, n_poles)`` or ``(n_samples,)`` [m] the instantaneous air gap at each pole.
    fs : float
        [Hz] sampling rate.
    f0 : float
        [Hz] the run's fundamental.
    t0 : float
        [s] time of the first sample.
    flux : numpy.ndarray or None
        ``(n_samples,)`` [Wb] the flux through one pole, for the flux law.

    Returns
    -------
    tuple of (float, float)
        (F_0, |F_1|) [N] of the law's total force (:func:`forcecal.actuator.predict`, or
        :func:`forcecal.actuator.predict_flux` for the flux law), by a harmonic fit.
    """
    total = law_at(calibration, current, gaps, flux).total
    fit = fit_harmonics(total, fs, f0, 1, t0=t0)
    return float(fit.phasors[0].real), float(abs(fit.phasors[1]))


def law_at(calibration: Calibration, current: np.ndarray, gaps: np.ndarray,
           flux: np.ndarray | None = None) -> Prediction:
    """The law's Prediction at samples the law was fitted to: from the flux for the flux law,
    else from the current and gaps (``(n,)`` or ``(n, n_poles)``); no extrapolation warning
    (samples left out of the fit may reach a little past the calibrated range)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)
        if calibration.law_object.needs_flux:
            if flux is None:
                raise InputError(f"calibration law '{calibration.law}' predicts from flux; the "
                                 "runs carry none")
            return predict_flux(calibration, np.asarray(flux, dtype=float))
        gaps = np.asarray(gaps, dtype=float)
        return predict(calibration, np.asarray(current, dtype=float),
                       gaps[:, None] if gaps.ndim == 1 else gaps)


def law_cycle(cal: Calibration, dc: np.ndarray, ac: float, gap: float,
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


def running_max(values: np.ndarray, width: int) -> np.ndarray:
    """The largest of ``values`` within ``width`` neighbours each side (a smooth envelope)."""
    padded = np.pad(values, width, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * width + 1)
    out: np.ndarray = windows.max(axis=1)
    return out
