"""Calibration samples: what each run contributes to the fit of the actuator's law.

Each run contributes ``samples_per_period`` instants spread over one period of its fitted
Fourier series, holding the coil current [A], the instantaneous air gap of every pole [m] (see
:mod:`forcecal.actuator.gaps`), the reconstructed total actuator force (reactions plus
inertia) [N] and beside it the reactions-only total, and the flux through a pole [Wb] when the
rig names a flux channel. :func:`calibration_data` pools the samples of the runs for
:mod:`forcecal.actuator` (METHOD.md section 5).

Shapes: ``n_poles`` force points of the actuator, ``n`` samples. SI units throughout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..actuator import CalibrationData
from ..actuator.ac_only import DEFAULT_SAMPLES_PER_PERIOD
from ..actuator.gaps import PoleMotion, fourier_series, pole_motion
from ..errors import FitError, InputError
from ..forces.steady import ForceEstimate, channels_si
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from ..signals.harmonics import fit_harmonics
from .noise import RunNoise, run_noise

if TYPE_CHECKING:
    from .runs import RunResult

__all__ = ["CalibrationSamples", "calibration_data"]


@dataclass(frozen=True)
class CalibrationSamples:
    """The calibration samples of one run, evenly spread over one period.

    Attributes
    ----------
    time : (n,) array [s]
        Absolute instants ``t0 + k / (n f0)``.
    current : (n,) array [A]
        Coil current from its harmonic fit.
    gaps : (n, n_poles) array [m]
        Instantaneous air gap at every pole.
    force : (n,) array [N]
        Reconstructed total actuator force (reactions and inertia).
    static_force : (n,) array [N]
        Reactions-only total force.
    flux : (n,) array [Wb] or None
        Flux through one pole, when the rig names a flux channel present in the run.
    motion : PoleMotion
        The displacement at the poles, to evaluate the gaps at any time.
    noise : RunNoise or None
        What the run's errors do to the samples, per source (for the calibration's parameter
        uncertainties, :mod:`forcecal.campaign.statistics`); None when not described.
    """

    time: np.ndarray
    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    static_force: np.ndarray
    flux: np.ndarray | None
    motion: PoleMotion
    noise: RunNoise | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def static_gap(self) -> float:
        """The run's static gap [m] (mean over the poles)."""
        return float(np.mean(self.motion.static_gap))


def run_samples(
    rig: Rig,
    model: SpatialModel,
    run: Run,
    estimate: ForceEstimate,
    tare: Run | None = None,
    samples_per_period: int = DEFAULT_SAMPLES_PER_PERIOD,
    tare_name: str | None = None,
) -> CalibrationSamples:
    """Calibration samples of one reconstructed run.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps (see :func:`forcecal.campaign.rig_for_entry`).
    model : SpatialModel
        The harmonic shapes, as for :func:`forcecal.actuator.gaps.pole_motion`.
    run : Run
        The recording.
    estimate : ForceEstimate
        The run's reconstructed forces and coordinates.
    tare : Run or None
        A zero-current record, the probes' zero.
    samples_per_period : int
        Instants taken over one period of the fundamental (at least ``2 H + 2``).
    tare_name : str or None
        The tare's name: runs that share a tare share its noise.

    Returns
    -------
    CalibrationSamples
        Current, gaps, forces and flux at ``samples_per_period`` instants over one period,
        with what the run's errors do to them (:func:`forcecal.campaign.noise.run_noise`).

    Raises
    ------
    InputError
        When ``samples_per_period`` cannot represent the harmonics, or a pole has no static gap.
    """
    h = int(estimate.harmonics[-1])
    if samples_per_period < 2 * h + 2:
        raise InputError(
            f"samples_per_period = {samples_per_period} cannot represent {h} harmonics; "
            f"use at least {2 * h + 2}"
        )
    motion = pole_motion(rig, model, run, estimate, tare)
    t = run.t0 + np.arange(samples_per_period) / (samples_per_period * estimate.f0)
    sig = channels_si(rig, run)
    act = rig.actuator
    current = fit_harmonics(sig[act.current], run.fs, estimate.f0, h, t0=run.t0)
    flux = None
    if act.flux and act.flux in sig:
        fit = fit_harmonics(sig[act.flux], run.fs, estimate.f0, h, t0=run.t0)
        flux = fourier_series(fit.phasors, estimate.f0, t)
    return CalibrationSamples(
        time=t,
        current=fourier_series(current.phasors, estimate.f0, t),
        gaps=motion.gaps(t).T,
        force=fourier_series(estimate.total, estimate.f0, t),
        static_force=fourier_series(estimate.static.sum(axis=0), estimate.f0, t),
        flux=flux,
        motion=motion,
        noise=run_noise(rig, model, run, estimate, tare, tare_name, current),
    )


def _run_forces(
    results: Sequence[RunResult], source: str, ac_only: bool
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The force samples of every run and, AC-only, their per-run RMS as uncertainty.

    Returns
    -------
    forces : list of (n,) arrays [N]
        Each run's force, zero-mean when ``ac_only``.
    sigma : list of (n,) arrays [N]
        Each run's RMS force, repeated (empty unless ``ac_only``).

    Raises
    ------
    FitError
        AC-only, when a run has no AC force.
    """
    forces, sigma = [], []
    for r in results:
        f = r.samples.force if source == "total" else r.samples.static_force
        if ac_only:
            f = f - f.mean()
            rms = float(np.sqrt(np.mean(f**2)))
            if not rms > 0:
                raise FitError(f"run '{r.name}': no AC force; AC-only calibration needs a drive")
            sigma.append(np.full(f.size, rms))
        forces.append(f)
    return forces, sigma


def calibration_data(
    results: Sequence[RunResult], source: str = "total", ac_only: bool = False
) -> CalibrationData:
    """Pool the calibration samples of the runs.

    Parameters
    ----------
    results : sequence of RunResult
        The reconstructed runs.
    source : {"total", "static"}
        The reconstructed total force (reactions and inertia) or the reactions-only one.
    ac_only : bool
        Make each run's force zero-mean, and weight the relative residuals of each run by its
        own RMS force (the floor of the relative residual is the median of these RMS values), as
        AC-only laws need.

    Returns
    -------
    CalibrationData
        ``group`` is the run's position in ``results``, ``static_gap`` the run's static gap.

    Raises
    ------
    InputError
        When ``source`` is unknown or there is no run.
    FitError
        AC-only, when a run has no AC force.
    """
    if source not in ("total", "static"):
        raise InputError(f"calibration source '{source}' is neither 'total' nor 'static'")
    if not results:
        raise InputError("no runs to calibrate")
    forces, sigma = _run_forces(results, source, ac_only)
    has_flux = all(r.samples.flux is not None for r in results)
    floor = float(np.median([s[0] for s in sigma])) if ac_only else None
    return CalibrationData(
        current=np.concatenate([r.samples.current for r in results]),
        gaps=np.concatenate([r.samples.gaps for r in results]),
        force=np.concatenate(forces),
        static_gap=np.concatenate([np.full(r.samples.n, r.samples.static_gap) for r in results]),
        flux=np.concatenate([r.samples.flux for r in results]) if has_flux else None,
        sigma=np.concatenate(sigma) if ac_only else None,
        group=np.concatenate([np.full(r.samples.n, k) for k, r in enumerate(results)]),
        force_floor=floor,
    )
