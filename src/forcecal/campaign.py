"""Calibration of the electromagnet over a campaign of runs (METHOD.md section 5).

A campaign is a manifest (INTERFACES.md section 4) listing runs at several static gaps and
currents, and zero-current tare records. Every run is reconstructed (:func:`forcecal.forces.
reconstruct`, in parallel when there are many), and each run contributes *calibration samples*:
``samples_per_period`` instants spread over one period of its fitted Fourier series, holding

- the coil current ``i(t)`` [A], from the harmonic fit of the current channel;
- the instantaneous air gap of every pole, ``s_p(t) = s_0,p - w(x_p, t)`` [m], where the
  displacement at the pole comes from the spatial model and the run's generalized coordinates,
  ``w(x_p, t) = w_dc(x_p) + sum_n Re(phi_n(x_p) Q_n exp(j n w0 t))`` (not the mean gap);
- the reconstructed total actuator force (reactions plus inertia) [N], and beside it the
  reactions-only total, both evaluated from their phasors;
- the flux through a pole [Wb], when the rig names a flux channel.

The DC deflection
-----------------
The harmonic shapes phi_n come from the scan and say nothing about the static (DC) deflection,
yet the DC pull of the magnet bends the structure by a sizeable fraction of the gap. The probes
measure it: their DC values (minus the tare record's, which fixes the probes' zero at zero
current) are fitted by least squares with ONE quasi-static shape, the real part of the
fundamental's shape phi_1 after rotating it to its most real phase, and that shape gives the DC
deflection at the poles. This is an approximation whose limits are:

- phi_1 is the response at w0, so it carries the inertia loading of the drive frequency; the
  static shape lacks it. The error grows like (f0 / f1)^2 relative to the first bending
  resonance f1 (a 20 Hz drive below a 71 Hz mode leaves well under 1 % of the DC deflection);
  near a resonance the approximation fails.
- The DC load must be distributed over the poles like the AC load: true for one magnet whose
  poles carry one flux, not for several magnets driven with different DC/AC ratios.
- Any other static load (preload, a change of gravity sag) must be in the tare.
- With more probes than one, the misfit of the probes' DC to the shape is reported per run
  (``dc_misfit``); it is the warning sign that the quasi-static shape does not hold.

Fitting the laws
----------------
The samples of all runs are pooled in a :class:`forcecal.actuator.CalibrationData` (``group`` =
run index, ``static_gap`` = the run's static gap) and :func:`forcecal.actuator.select_law`
chooses the law. The same candidate laws are fitted to the reactions-only force, to show how far
off a calibration that ignores the inertia would be.

AC-coupled (piezoelectric) gauges do not measure the DC force. With ``ac_only=True`` every law
is wrapped in :class:`ACOnlyLaw`, which removes the per-run mean of the modelled total force
(each run's samples form one block of ``samples_per_period`` instants over one period, so the
block mean is the DC part exactly); the measured force of every run is also made zero-mean.
The law's parameters are thus fitted to the harmonics alone and still predict the full force,
DC included.

Shapes: ``n_poles`` force points of the actuator, ``n`` samples. SI units throughout.
"""

from __future__ import annotations

import contextlib
import json
import math
import multiprocessing
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from .actuator import (
    K_I0_SFE2,
    K_I2_S2,
    K_I2_SFE2,
    POWER,
    Calibration,
    CalibrationData,
    Law,
    Selection,
    select_law,
)
from .errors import FitError, InputError
from .forces import ForceEstimate, channels_si, reconstruct
from .harmonics import fit_harmonics
from .io.atomic import write_text_atomic
from .io.manifest import ManifestEntry, read_manifest
from .io.run_files import read_run
from .records import Run
from .rig import Rig
from .spatial import SpatialModel, structure_coordinates, structure_grid

__all__ = [
    "CURRENT_GAP_LAWS",
    "DEFAULT_SAMPLES_PER_PERIOD",
    "ACOnlyLaw",
    "CalibrationSamples",
    "CampaignResult",
    "PoleMotion",
    "ReactionsOnly",
    "Repeatability",
    "RunResult",
    "calibrate_campaign",
    "calibrate_runs",
    "calibration_data",
    "load_calibration",
    "pole_motion",
    "quasi_static_shape",
    "reconstruct_campaign",
    "report_text",
    "rig_for_entry",
    "run_samples",
    "write_calibration",
]

DEFAULT_SAMPLES_PER_PERIOD = 64
"""Calibration samples taken from each run, evenly over one period of its fitted series."""

CURRENT_GAP_LAWS: tuple[Law, ...] = (K_I2_S2, K_I2_SFE2, K_I0_SFE2, POWER)
"""The laws tried by default: those predicting from (current, gap), which is what
``forcecal predict --current --gap`` needs. The flux law is fitted only when asked for."""

PARALLEL_MIN_RUNS = 3
"""Campaigns with fewer runs than this are reconstructed serially whatever ``workers`` says."""

_SHAPE_GRID = 401
_MIN_AC_RUNS = 3


# --------------------------------------------------------------------------------------------
# Pole motion and instantaneous gaps


def _evaluate(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """Fourier series ``X_0 + sum Re(X_n exp(j n w0 t))`` at absolute times.

    phasors : (..., H+1) complex; t : (n_t,) [s]; returns (..., n_t), real.
    """
    n = np.arange(phasors.shape[-1])
    cycles = np.mod(np.multiply.outer(n * f0, np.asarray(t, dtype=float)), 1.0)
    return (phasors @ np.exp(2j * np.pi * cycles)).real


def quasi_static_shape(model: SpatialModel, rig: Rig) -> Callable[[np.ndarray], np.ndarray]:
    """The shape used for the DC deflection: Re of the lowest harmonic's shape, made real.

    The fundamental's shape phi_1 (or the lowest harmonic the model has) is rotated by the
    phase that makes it most real, ``theta = arg(sum phi^2) / 2`` over the structure, and its
    real part is taken (see the module docstring for the limits of this approximation).

    Returns
    -------
    callable
        ``points -> (n,) [m]``, the shape at points of the structure (as
        :func:`forcecal.spatial.structure_coordinates` gives them); its scale and sign are
        arbitrary (the DC amplitude is fitted to the probes).
    """
    n1 = 1 if 1 in model.harmonics else int(np.min(model.harmonics))
    phi = model.shape_values(n1, structure_grid(rig, _SHAPE_GRID))
    rotor = np.exp(-0.5j * np.angle(np.sum(phi**2)))

    def shape(points: np.ndarray) -> np.ndarray:
        return (model.shape_values(n1, structure_coordinates(rig, points)) * rotor).real

    return shape


@dataclass(frozen=True)
class PoleMotion:
    """Displacement of the structure at the actuator's poles over one run.

    Attributes
    ----------
    f0 : float [Hz]
        The run's fundamental.
    phasors : (n_poles, H+1) complex array [m]
        ``w(x_p)`` as a Fourier series; column 0 is the DC deflection (real), the others
        ``phi_n(x_p) Q_n`` (zero for harmonics without a shape in the model).
    static_gap : (n_poles,) array [m]
        Static gap of every pole with the structure at w = 0 (the manifest's, else the rig's).
    dc_misfit : float [m]
        RMS misfit of the probes' DC values to the quasi-static shape (NaN with one probe).
    """

    f0: float
    phasors: np.ndarray
    static_gap: np.ndarray
    dc_misfit: float

    @property
    def dc(self) -> np.ndarray:
        """DC deflection at every pole, (n_poles,) [m], positive toward the magnet."""
        return self.phasors[:, 0].real

    def deflection(self, t: np.ndarray) -> np.ndarray:
        """``w(x_p, t)`` at absolute times ``t`` (n_t,) [s] -> (n_poles, n_t) [m]."""
        return _evaluate(self.phasors, self.f0, t)

    def gaps(self, t: np.ndarray) -> np.ndarray:
        """Instantaneous air gaps ``s_0,p - w(x_p, t)``, (n_poles, n_t) [m]."""
        return self.static_gap[:, None] - self.deflection(t)


def _static_gaps(rig: Rig) -> np.ndarray:
    missing = [f.name for f in rig.forces if f.gap is None]
    if missing:
        raise InputError(
            f"rig '{rig.source}': no static gap for force point {', '.join(missing)}; give "
            "'gap' in the rig's [[forces]] or a 'gap' column in the manifest"
        )
    return np.array([float(f.gap) for f in rig.forces])


def pole_motion(
    rig: Rig, model: SpatialModel, run: Run, estimate: ForceEstimate, tare: Run | None = None
) -> PoleMotion:
    """Displacement at the poles from the spatial model, the run's coordinates and probes' DC.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps in ``rig.forces`` (see :func:`rig_for_entry`).
    model : SpatialModel
    run : Run
        The recording, for the probes' DC values.
    estimate : ForceEstimate
        Its ``coordinates`` (Q_n) and refined ``f0``.
    tare : Run or None
        A zero-current record; its probe means are the probes' zero.

    Returns
    -------
    PoleMotion
    """
    h = int(estimate.harmonics[-1])
    xp = structure_coordinates(rig, rig.force_points)
    phasors = np.zeros((len(rig.forces), h + 1), dtype=complex)
    coords = estimate.coordinates
    for k, n in enumerate(coords.harmonics):
        n = int(n)
        if n <= h:
            phasors[:, n] = model.shape_values(n, xp) * coords.q[k]
    sig = channels_si(rig, run)
    probes = np.stack([sig[s] for s in rig.sensor_names])
    fit = fit_harmonics(probes, run.fs, estimate.f0, h, t0=run.t0)
    dc = fit.phasors[:, 0].real
    var = fit.phasor_std[:, 0] ** 2
    if tare is not None:
        t_sig = channels_si(rig, tare)
        zero = np.array([t_sig[s].mean() for s in rig.sensor_names])
        dc = dc - zero
        var = var + np.array([t_sig[s].var() / t_sig[s].size for s in rig.sensor_names])
    shape = quasi_static_shape(model, rig)
    at_probes = shape(rig.sensor_points)
    w = 1.0 / np.maximum(var, np.finfo(float).tiny)
    amplitude = float(np.sum(w * at_probes * dc) / np.sum(w * at_probes**2))
    misfit = dc - amplitude * at_probes
    dc_misfit = float(np.sqrt(np.mean(misfit**2))) if dc.size > 1 else float("nan")
    phasors[:, 0] = amplitude * shape(xp)
    return PoleMotion(
        f0=estimate.f0, phasors=phasors, static_gap=_static_gaps(rig), dc_misfit=dc_misfit
    )


# --------------------------------------------------------------------------------------------
# Calibration samples of one run


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
    """

    time: np.ndarray
    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    static_force: np.ndarray
    flux: np.ndarray | None
    motion: PoleMotion

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
) -> CalibrationSamples:
    """Calibration samples of one reconstructed run.

    Parameters
    ----------
    rig : Rig
        With the run's static gaps (see :func:`rig_for_entry`).
    model, run, estimate, tare
        As for :func:`pole_motion`.
    samples_per_period : int
        Instants taken over one period of the fundamental (at least ``2 H + 2``).

    Returns
    -------
    CalibrationSamples
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
        flux = _evaluate(fit.phasors, estimate.f0, t)
    return CalibrationSamples(
        time=t,
        current=_evaluate(current.phasors, estimate.f0, t),
        gaps=motion.gaps(t).T,
        force=_evaluate(estimate.total, estimate.f0, t),
        static_force=_evaluate(estimate.static.sum(axis=0), estimate.f0, t),
        flux=flux,
        motion=motion,
    )


# --------------------------------------------------------------------------------------------
# Reconstructing a campaign


@dataclass(frozen=True)
class RunResult:
    """One reconstructed run of a campaign.

    Attributes
    ----------
    entry : ManifestEntry
        Its manifest row.
    estimate : ForceEstimate
        The forces of the run.
    samples : CalibrationSamples
        Its calibration samples.
    tare : str or None
        Name of the tare record used.
    """

    entry: ManifestEntry
    estimate: ForceEstimate
    samples: CalibrationSamples
    tare: str | None = None

    @property
    def name(self) -> str:
        """The run's name (file stem)."""
        return self.estimate.run_name


def rig_for_entry(rig: Rig, entry: ManifestEntry, manifest: str | Path = "<manifest>") -> Rig:
    """The rig with the static gaps of a manifest row (``gap``, then ``gap_<force name>``)."""
    names = {f.name for f in rig.forces}
    unknown = sorted(set(entry.gaps) - names)
    if unknown:
        raise InputError(
            f"manifest '{manifest}': column 'gap_{unknown[0]}' names no force point of rig "
            f"'{rig.source}' (force points: {', '.join(sorted(names))})"
        )
    forces = []
    for f in rig.forces:
        gap = entry.gaps.get(f.name, entry.gap if entry.gap is not None else f.gap)
        forces.append(replace(f, gap=gap))
    return replace(rig, forces=tuple(forces))


@dataclass(frozen=True)
class _Task:
    index: int
    rig: Rig
    model: SpatialModel
    entry: ManifestEntry
    tare: Path | None
    ac_coupled: bool
    samples_per_period: int


def _reconstruct_entry(task: _Task) -> tuple[int, RunResult, list[tuple[str, type[Warning]]]]:
    """Reconstruct one run; warnings are recorded and returned, to be re-issued by the parent
    (serial and parallel runs then warn alike)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = read_run(task.entry.run)
        tare = read_run(task.tare) if task.tare is not None else None
        estimate = reconstruct(task.rig, task.model, run, tare=tare, ac_coupled=task.ac_coupled)
        samples = run_samples(task.rig, task.model, run, estimate, tare, task.samples_per_period)
    result = RunResult(
        entry=task.entry,
        estimate=estimate,
        samples=samples,
        tare=None if task.tare is None else task.tare.stem,
    )
    return task.index, result, [(str(w.message), w.category) for w in caught]


def _tare_for(index: int, tares: list[int]) -> int | None:
    """The tare used by row ``index``: the closest preceding tare row, else the first one."""
    if not tares:
        return None
    before = [k for k in tares if k < index]
    return before[-1] if before else tares[0]


def reconstruct_campaign(
    rig: Rig,
    model: SpatialModel,
    manifest_path: str | Path,
    progress: Callable[[int, int, str], None] | None = None,
    workers: int | None = None,
    ac_coupled: bool = False,
    samples_per_period: int = DEFAULT_SAMPLES_PER_PERIOD,
) -> list[RunResult]:
    """Reconstruct every run of a campaign manifest, with its calibration samples.

    Each row's static gaps override the rig's (``gap``, ``gap_<force name>``). Rows marked
    ``tare`` are not reconstructed: every other run takes the closest tare row above it (else
    the first tare row) as its tare, which zeroes the gauges' DC and the probes.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    manifest_path : str or Path
        The campaign manifest CSV.
    progress : callable or None
        Called as ``progress(done, total, run name)`` after each run.
    workers : int or None
        Worker processes; default ``min(2, os.cpu_count())``. Campaigns of fewer than
        ``PARALLEL_MIN_RUNS`` runs, or ``workers <= 1``, run serially.
    ac_coupled : bool
        The gauges do not measure DC (piezoelectric): see :func:`forcecal.forces.reconstruct`.
    samples_per_period : int
        Calibration samples per run.

    Returns
    -------
    list of RunResult
        The non-tare runs, in manifest order.

    Raises
    ------
    InputError
        A bad manifest, a run without a static gap, a manifest with no run to reconstruct.
    """
    entries = read_manifest(manifest_path)
    tare_rows = [k for k, e in enumerate(entries) if e.tare]
    tasks = [
        _Task(
            index=k,
            rig=rig_for_entry(rig, e, manifest_path),
            model=model,
            entry=e,
            tare=None if (j := _tare_for(k, tare_rows)) is None else entries[j].run,
            ac_coupled=ac_coupled,
            samples_per_period=samples_per_period,
        )
        for k, e in enumerate(entries)
        if not e.tare
    ]
    if not tasks:
        raise InputError(f"manifest '{manifest_path}': every run is a tare; nothing to calibrate")
    for task in tasks:
        _static_gaps(task.rig)
    if workers is None:
        workers = min(2, os.cpu_count() or 1)
    total = len(tasks)
    done: dict[int, RunResult] = {}

    def finish(index: int, result: RunResult, caught: list[tuple[str, type[Warning]]]) -> None:
        for message, category in caught:
            warnings.warn(message, category, stacklevel=3)
        done[index] = result
        if progress is not None:
            progress(len(done), total, result.name)

    if workers <= 1 or total < PARALLEL_MIN_RUNS:
        for task in tasks:
            finish(*_reconstruct_entry(task))
    else:
        context = multiprocessing.get_context("spawn")
        with (
            _single_threaded_workers(),
            ProcessPoolExecutor(max_workers=min(workers, total), mp_context=context) as pool,
        ):
            futures = [pool.submit(_reconstruct_entry, task) for task in tasks]
            try:
                for future in as_completed(futures):
                    finish(*future.result())
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
    return [done[task.index] for task in tasks]


_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _single_threaded_workers() -> Iterator[None]:
    """Worker processes started inside run their linear algebra on one thread each.

    The workers are the parallelism: BLAS threads in every worker would oversubscribe the
    cores (on a busy machine by a factor of ten in time). The variables are set only where the
    user has not set them, only while the pool starts its processes, and restored after.
    """
    added = [name for name in _THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


# --------------------------------------------------------------------------------------------
# AC-only laws


@dataclass(frozen=True)
class ACOnlyLaw(Law):
    """A law seen through AC-coupled gauges: the per-run mean of the modelled force removed.

    The observations must come in contiguous blocks of ``block`` samples, one block per run,
    spread evenly over one period (as :func:`calibration_data` builds them), so that the block
    mean is the run's DC. The wrapper has the base law's name, parameters and identifiability,
    so a fit of it is a calibration of the base law: the fitted parameters predict the whole
    force, DC included, although only its harmonics were seen.

    Attributes
    ----------
    base : Law
        The law of the whole force.
    block : int
        Samples per run.
    """

    base: Law | None = None
    block: int = DEFAULT_SAMPLES_PER_PERIOD

    @classmethod
    def wrap(cls, base: Law, block: int = DEFAULT_SAMPLES_PER_PERIOD) -> ACOnlyLaw:
        """The AC-only view of ``base``."""
        return cls(
            name=base.name,
            formula=f"{base.formula} (AC part of each run)",
            param_names=base.param_names,
            param_units=base.param_units,
            needs_gaps=base.needs_gaps,
            needs_flux=base.needs_flux,
            separates=base.separates,
            base=base,
            block=block,
        )

    def _demean(self, a: np.ndarray) -> np.ndarray:
        n = a.shape[0]
        if n % self.block:
            raise FitError(
                f"law '{self.name}' (AC only): {n} observations are not whole runs of "
                f"{self.block} samples; AC-only calibration validates by leaving out whole runs"
            )
        blocks = a.reshape(n // self.block, self.block, *a.shape[1:])
        return (blocks - blocks.mean(axis=1, keepdims=True)).reshape(a.shape)

    def _value_and_jacobian(self, p, i, s, phi):
        f, jac = self.base._value_and_jacobian(p, i, s, phi)
        return self._demean(f), self._demean(jac)

    def _rescaled(self, p: np.ndarray, data: CalibrationData) -> tuple[np.ndarray, float]:
        """Parameters with the amplitude that best fits the AC force, and their weighted RSS."""
        model = self.per_pole(p, data.current, data.gaps, data.flux).sum(axis=1)
        w = data.weights
        b, y = model / w, data.force / w
        norm2 = float(b @ b)
        if not norm2 > 0:
            return p, math.inf
        c = float(b @ y) / norm2
        q = p.copy()
        if "K" in self.param_names:
            q[self.param_names.index("K")] *= c
        elif "A_eff" in self.param_names and c > 0:
            q[self.param_names.index("A_eff")] /= c
        else:
            return p, math.inf
        return q, float(np.sum((c * b - y) ** 2))

    def guess(self, data):
        if self.needs_flux:  # the base guess assumes a positive DC force; start from 1 m^2
            if data.flux is None:
                raise FitError(f"law '{self.name}' needs the flux through a pole; none given")
            p0 = np.ones(self.n_params)
        else:
            p0 = np.asarray(self.base.guess(data), dtype=float)
        grids: list[tuple[int, np.ndarray]] = []
        if "s_fe" in self.param_names:
            lo = -0.5 * float(data.gaps.min())
            grids.append((self.param_names.index("s_fe"),
                          np.linspace(lo, float(np.median(data.static_gap)), 41)))
        if "i0" in self.param_names:
            i_max = float(np.max(np.abs(data.current)))
            grids.append((self.param_names.index("i0"), np.linspace(-0.3, 0.3, 13) * i_max))
        best, best_rss = self._rescaled(p0, data)
        for _ in range(2):  # coordinate-wise grid search, twice over
            for k, grid in grids:
                for value in grid:
                    p = best.copy()
                    p[k] = value
                    q, rss = self._rescaled(p, data)
                    if rss < best_rss:
                        best, best_rss = q, rss
        return best

    def bounds(self, data):
        return self.base.bounds(data)

    def typical(self, params, data):
        return self.base.typical(params, data)


# --------------------------------------------------------------------------------------------
# Calibration of a campaign


def calibration_data(
    results: Sequence[RunResult], source: str = "total", ac_only: bool = False
) -> CalibrationData:
    """Pool the calibration samples of the runs.

    Parameters
    ----------
    results : sequence of RunResult
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
    """
    if source not in ("total", "static"):
        raise InputError(f"calibration source '{source}' is neither 'total' nor 'static'")
    if not results:
        raise InputError("no runs to calibrate")
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


@dataclass(frozen=True)
class ReactionsOnly:
    """The same candidate laws fitted to the reactions-only force.

    Attributes
    ----------
    selection : Selection or None
        None when no law could be fitted (``error`` says why).
    error : str or None
    k_total : float or None [N m^2/A^2]
        ``n_poles * K`` of the law chosen for the corrected force, fitted to the reactions only.
    k_total_error : float or None [-]
        Its relative difference from the corrected calibration's ``k_total``.
    s_fe : float or None [m]
        That law's ``s_fe`` fitted to the reactions only, when it has one.
    force_error : float or None [-]
        RMS over the campaign's samples of (reactions-only prediction - corrected prediction) /
        corrected prediction, both with the chosen law.
    """

    selection: Selection | None
    error: str | None = None
    k_total: float | None = None
    k_total_error: float | None = None
    s_fe: float | None = None
    force_error: float | None = None


@dataclass(frozen=True)
class Repeatability:
    """Spread over repeated runs (same static gap and labels but for ``repeat``).

    Attributes
    ----------
    groups : tuple of dict
        One per setpoint with two runs or more: ``key`` (labels), ``runs``, per run ``k_total``
        (the chosen law's K refitted to that run alone, its other parameters kept) ``mean_force``
        [N] and ``amplitude`` [N] (fundamental of the total), and their relative standard
        deviations.
    k_total_rel_std : float or None [-]
        Pooled relative standard deviation of the per-run K over the groups.
    mean_force_rel_std, amplitude_rel_std : float or None [-]
        Pooled relative standard deviations of the mean force and of the fundamental's
        amplitude.
    """

    groups: tuple[dict[str, Any], ...] = ()
    k_total_rel_std: float | None = None
    mean_force_rel_std: float | None = None
    amplitude_rel_std: float | None = None


@dataclass(frozen=True)
class CampaignResult:
    """The calibration of a campaign.

    Attributes
    ----------
    runs : tuple of RunResult
    selection : Selection
        The candidate laws fitted to the reconstructed force, and the one chosen.
    calibration : Calibration
        The chosen law's calibration (what ``forcecal predict`` reads).
    reactions_only : ReactionsOnly
    repeatability : Repeatability
    n_poles : int
    ideal_k : float or None [N m^2/A^2]
        ``mu0 N^2 A / 4`` from the rig, the ideal TOTAL K of ``f = K i^2 / s^2`` summed over the
        poles of a U-core.
    ac_only : bool
    samples_per_period : int
    run_k_total : (n_runs,) array [N m^2/A^2]
        The chosen law's K_total refitted to each run alone (NaN for laws without K).
    run_residual : (n_runs,) array [-]
        RMS relative residual of the chosen law on each run.
    manifest : str
    tares : tuple of str
    """

    runs: tuple[RunResult, ...]
    selection: Selection
    calibration: Calibration
    reactions_only: ReactionsOnly
    repeatability: Repeatability
    n_poles: int
    ideal_k: float | None
    ac_only: bool
    samples_per_period: int
    run_k_total: np.ndarray
    run_residual: np.ndarray
    manifest: str = "<manifest>"
    tares: tuple[str, ...] = ()

    @property
    def law(self) -> str:
        """Name of the chosen law."""
        return self.calibration.law

    @property
    def params(self) -> dict[str, float]:
        """Parameters of the chosen law by name."""
        law = self.calibration.law_object
        return {n: float(v) for n, v in zip(law.param_names, self.calibration.params, strict=True)}

    @property
    def k_total(self) -> float | None:
        """``n_poles * K`` of the chosen law [N m^2/A^2], None when its K is not of that unit."""
        return _k_total(self.calibration.law_object, self.calibration.params, self.n_poles)

    @property
    def k_total_std(self) -> float | None:
        """Standard uncertainty of :attr:`k_total` [N m^2/A^2]."""
        law = self.calibration.law_object
        if _k_total(law, self.calibration.params, self.n_poles) is None:
            return None
        return self.n_poles * float(self.calibration.stderr[law.param_names.index("K")])

    @property
    def s_fe(self) -> float | None:
        """The chosen law's iron-path offset ``s_fe`` [m], when it has one."""
        return self.params.get("s_fe")

    def to_json(self) -> dict[str, Any]:
        """The calibration file's content: :meth:`Calibration.to_json` at the top level (so
        :meth:`Calibration.load` reads it) plus the campaign's scores, comparison and runs."""
        doc = self.calibration.to_json()
        chosen = self.selection.best
        doc["chosen"] = {
            "law": self.selection.chosen,
            "reason": self.selection.reason,
            "held_out_tolerance": self.selection.tolerance,
            "held_out_scheme": chosen.held_out.scheme,
        }
        doc["k_total"] = {
            "value": self.k_total,
            "stderr": self.k_total_std,
            "ideal": self.ideal_k,
            "ratio_to_ideal": (
                None if self.k_total is None or not self.ideal_k else self.k_total / self.ideal_k
            ),
            "n_poles": self.n_poles,
            "note": "K_total = n_poles * K (K is per pole); ideal = mu0 N^2 A / 4 from the rig",
        }
        doc["reactions_only"] = _reactions_json(self.reactions_only)
        doc["repeatability"] = {
            "k_total_rel_std": self.repeatability.k_total_rel_std,
            "mean_force_rel_std": self.repeatability.mean_force_rel_std,
            "amplitude_rel_std": self.repeatability.amplitude_rel_std,
            "groups": [dict(g) for g in self.repeatability.groups],
        }
        doc["campaign"] = {
            "manifest": self.manifest,
            "n_runs": len(self.runs),
            "tares": list(self.tares),
            "ac_only": self.ac_only,
            "samples_per_period": self.samples_per_period,
            "n_observations": len(self.runs) * self.samples_per_period,
            "dc_deflection": "probes' DC (minus the tare's) fitted with Re of the fundamental's "
            "shape as a quasi-static shape",
        }
        doc["runs"] = [
            _run_json(r, k, self.run_residual[k]) for k, r in enumerate(self.runs)
        ]
        return _json_ready(doc)


def _k_total(law: Law, params: np.ndarray, n_poles: int) -> float | None:
    if "K" not in law.param_names or law.param_units[0] != "N m^2/A^2":
        return None
    return n_poles * float(params[law.param_names.index("K")])


def _reactions_json(ro: ReactionsOnly) -> dict[str, Any]:
    if ro.selection is None:
        return {"error": ro.error}
    rows = [c.row() for c in ro.selection.candidates]
    rows += [{"law": name, "skipped": why} for name, why in ro.selection.skipped]
    return {
        "chosen": ro.selection.chosen,
        "candidates": rows,
        "k_total": ro.k_total,
        "k_total_error": ro.k_total_error,
        "s_fe": ro.s_fe,
        "force_error_rms": ro.force_error,
        "note": "the candidate laws fitted to the reactions-only force (inertia ignored); "
        "k_total, s_fe and force_error_rms are those of the law chosen for the corrected force",
    }


def _run_json(r: RunResult, k: int, residual: float) -> dict[str, Any]:
    est, smp = r.estimate, r.samples
    total = smp.force
    return {
        "run": r.name,
        "file": str(r.entry.run),
        "group": k,
        "static_gap": smp.motion.static_gap.tolist(),
        "labels": dict(r.entry.labels),
        "tare": r.tare,
        "f0_hz": est.f0,
        "mean_force": float(est.total[0].real),
        "fundamental_amplitude": float(abs(est.total[1])) if est.total.size > 1 else 0.0,
        "force_range": [float(total.min()), float(total.max())],
        "inertia_share": est.inertia_share if est.total.size > 1 else 0.0,
        "current_range": [float(smp.current.min()), float(smp.current.max())],
        "gap_range": [float(smp.gaps.min()), float(smp.gaps.max())],
        "dc_deflection": smp.motion.dc.tolist(),
        "dc_misfit": smp.motion.dc_misfit,
        "residual_rms": float(residual),
        "notes": list(est.notes),
    }


def _json_ready(obj: Any) -> Any:
    """Replace non-finite floats by None and NumPy scalars by Python ones."""
    if isinstance(obj, dict):
        return {str(k): _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _json_ready(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        x = float(obj)
        return x if math.isfinite(x) else None
    return obj


def _amplitude_factor(
    law: Law, params: np.ndarray, data: CalibrationData
) -> tuple[float, float]:
    """Least-squares factor ``c`` of ``F ~ c * model`` and the RMS relative residual of the
    model itself, on one run's data."""
    model = law.per_pole(params, data.current, data.gaps, data.flux).sum(axis=1)
    w = data.weights
    b, y = model / w, data.force / w
    c = float(b @ y / (b @ b))
    residual = float(np.sqrt(np.mean(((model - data.force) / data.scale) ** 2)))
    return c, residual


def _rel_std(values: Sequence[float]) -> float:
    v = np.asarray(values, dtype=float)
    return float(np.std(v, ddof=1) / abs(np.mean(v)))


def _pooled(values: list[float]) -> float | None:
    return float(np.sqrt(np.mean(np.square(values)))) if values else None


def _setpoint(entry: ManifestEntry) -> tuple:
    """Runs sharing this key are repeats of one setpoint."""
    labels = tuple(sorted((k, v) for k, v in entry.labels.items() if k != "repeat"))
    return (entry.gap, tuple(sorted(entry.gaps.items())), labels)


def _repeatability(
    results: Sequence[RunResult], run_k: np.ndarray, ac_only: bool
) -> Repeatability:
    groups: dict[tuple, list[int]] = {}
    for k, r in enumerate(results):
        groups.setdefault(_setpoint(r.entry), []).append(k)
    rows, k_std, mean_std, amp_std = [], [], [], []
    for key, members in groups.items():
        if len(members) < 2:
            continue
        ks = [float(run_k[k]) for k in members]
        means = [float(results[k].estimate.total[0].real) for k in members]
        amps = [float(abs(results[k].estimate.total[1])) for k in members]
        row: dict[str, Any] = {
            "gap": key[0],
            "gaps": dict(key[1]),
            "labels": dict(key[2]),
            "runs": [results[k].name for k in members],
            "k_total": ks,
            "amplitude": amps,
            "amplitude_rel_std": _rel_std(amps),
        }
        amp_std.append(row["amplitude_rel_std"])
        if np.all(np.isfinite(ks)):
            row["k_total_rel_std"] = _rel_std(ks)
            k_std.append(row["k_total_rel_std"])
        if not ac_only:
            row["mean_force"] = means
            row["mean_force_rel_std"] = _rel_std(means)
            mean_std.append(row["mean_force_rel_std"])
        rows.append(row)
    return Repeatability(
        groups=tuple(rows),
        k_total_rel_std=_pooled(k_std),
        mean_force_rel_std=_pooled(mean_std),
        amplitude_rel_std=_pooled(amp_std),
    )


def calibrate_runs(
    rig: Rig,
    results: Sequence[RunResult],
    laws: Sequence[Law] | None = None,
    ac_only: bool = False,
    manifest: str = "<manifest>",
    tares: Sequence[str] = (),
) -> CampaignResult:
    """Choose and fit the actuator law to reconstructed runs (see :func:`calibrate_campaign`).

    Raises
    ------
    FitError
        When no law is identifiable from the runs (one line, each law's reason).
    """
    results = tuple(results)
    laws = tuple(CURRENT_GAP_LAWS if laws is None else laws)
    if not results:
        raise InputError(f"manifest '{manifest}': no runs to calibrate")
    block = results[0].samples.n
    if ac_only:
        if len(results) < _MIN_AC_RUNS:
            raise FitError(
                f"manifest '{manifest}': AC-only calibration needs at least {_MIN_AC_RUNS} runs "
                f"(held-out validation leaves whole runs out); the campaign has {len(results)}"
            )
        if any(r.samples.n != block for r in results):
            raise InputError("AC-only calibration needs the same number of samples in every run")
        laws = tuple(ACOnlyLaw.wrap(law, block) for law in laws)
    data = calibration_data(results, "total", ac_only)
    try:
        selection = select_law(data, laws)
    except FitError as exc:
        raise FitError(f"manifest '{manifest}': {exc}") from None
    calibration = selection.calibration()
    chosen = selection.best.fit
    law = chosen.law
    n_poles = data.n_poles

    run_k = np.full(len(results), np.nan)
    run_res = np.empty(len(results))
    for k in range(len(results)):
        c, res = _amplitude_factor(law, chosen.params, data.subset(data.group == k))
        run_res[k] = res
        kt = _k_total(law, chosen.params, n_poles)
        if kt is not None:
            run_k[k] = c * kt

    static = calibration_data(results, "static", ac_only)
    try:
        ro_sel = select_law(static, laws)
    except FitError as exc:
        reactions = ReactionsOnly(selection=None, error=str(exc))
    else:
        same = next((c for c in ro_sel.candidates if c.name == law.name), None)
        if same is None:
            reactions = ReactionsOnly(selection=ro_sel)
        else:
            kt = _k_total(law, same.fit.params, n_poles)
            k_ref = _k_total(law, chosen.params, n_poles)
            corrected = law.base if isinstance(law, ACOnlyLaw) else law
            ref = corrected.per_pole(chosen.params, data.current, data.gaps, data.flux).sum(1)
            alt = corrected.per_pole(same.fit.params, data.current, data.gaps, data.flux).sum(1)
            reactions = ReactionsOnly(
                selection=ro_sel,
                k_total=kt,
                k_total_error=None if kt is None or k_ref is None else kt / k_ref - 1.0,
                s_fe=same.fit.params_dict.get("s_fe"),
                force_error=float(np.sqrt(np.mean(((alt - ref) / ref) ** 2))),
            )
    ideal = rig.actuator.ideal_k
    return CampaignResult(
        runs=results,
        selection=selection,
        calibration=calibration,
        reactions_only=reactions,
        repeatability=_repeatability(results, run_k, ac_only),
        n_poles=n_poles,
        ideal_k=ideal,
        ac_only=ac_only,
        samples_per_period=block,
        run_k_total=run_k,
        run_residual=run_res,
        manifest=manifest,
        tares=tuple(tares),
    )


def calibrate_campaign(
    rig: Rig,
    model: SpatialModel,
    manifest_path: str | Path,
    progress: Callable[[int, int, str], None] | None = None,
    workers: int | None = None,
    laws: Sequence[Law] | None = None,
    ac_only: bool = False,
    samples_per_period: int = DEFAULT_SAMPLES_PER_PERIOD,
) -> CampaignResult:
    """Reconstruct a campaign and calibrate the actuator law on it.

    Parameters
    ----------
    rig : Rig
        ``rig.actuator`` names the current (and flux) channels; its turns and pole area give the
        ideal K reported beside the fitted one.
    model : SpatialModel
    manifest_path : str or Path
    progress, workers
        As for :func:`reconstruct_campaign`.
    laws : sequence of Law or None
        Candidate laws; default :data:`CURRENT_GAP_LAWS`.
    ac_only : bool
        The gauges are AC-coupled: the runs are reconstructed without DC and the laws fitted to
        the harmonics alone (:class:`ACOnlyLaw`); needs at least three runs.
    samples_per_period : int
        Calibration samples per run.

    Returns
    -------
    CampaignResult

    Raises
    ------
    FitError
        When no candidate law is identifiable (e.g. a single static gap and only laws with
        ``s_fe``); laws that are not identifiable are otherwise skipped, their reason kept in
        ``result.selection.skipped``.
    """
    results = reconstruct_campaign(
        rig, model, manifest_path, progress=progress, workers=workers, ac_coupled=ac_only,
        samples_per_period=samples_per_period,
    )
    tares = tuple(e.run.stem for e in read_manifest(manifest_path) if e.tare)
    return calibrate_runs(
        rig, results, laws=laws, ac_only=ac_only, manifest=str(manifest_path), tares=tares
    )


# --------------------------------------------------------------------------------------------
# Output


def write_calibration(result: CampaignResult, out_dir: str | Path) -> Path:
    """Write ``OUT/calibration.json`` atomically; returns its path.

    The file is readable by :meth:`forcecal.actuator.Calibration.load` (and
    :func:`load_calibration`): the chosen law's calibration sits at the top level, the
    campaign's scores, reactions-only comparison, repeatability and per-run summary beside it.
    """
    path = Path(out_dir) / "calibration.json"
    text = json.dumps(result.to_json(), indent=2, allow_nan=False)
    return write_text_atomic(path, text + "\n")


def load_calibration(path: str | Path) -> Calibration:
    """The calibration of a ``calibration.json`` written by :func:`write_calibration` (or by
    :meth:`Calibration.save`)."""
    return Calibration.load(path)


def report_text(result: CampaignResult) -> str:
    """A plain-text summary of a campaign's calibration, ending with a newline."""
    from .actuator import report_text as selection_text

    lines = [selection_text(result.selection).rstrip("\n")]
    if result.k_total is not None:
        kt = f"K_total = n_poles * K = {result.k_total:.6g} +/- {result.k_total_std:.2g} N m^2/A^2"
        if result.ideal_k:
            kt += (
                f"; ideal mu0 N^2 A / 4 = {result.ideal_k:.6g} "
                f"(ratio {result.k_total / result.ideal_k:.4f})"
            )
        lines.append(kt)
    if result.s_fe is not None:
        lines.append(f"s_fe = {1e6 * result.s_fe:.2f} um")
    ro = result.reactions_only
    if ro.selection is None:
        lines.append(f"reactions-only: no law could be fitted ({ro.error})")
    else:
        text = f"reactions-only (inertia ignored): chooses '{ro.selection.chosen}'"
        if ro.k_total_error is not None:
            text += f"; K_total off by {100 * ro.k_total_error:+.2f} %"
        if ro.s_fe is not None:
            text += f"; s_fe = {1e6 * ro.s_fe:.2f} um"
        if ro.force_error is not None:
            text += f"; force off by {100 * ro.force_error:.2f} % RMS"
        lines.append(text)
    rep = result.repeatability
    if rep.groups:
        parts = []
        if rep.k_total_rel_std is not None:
            parts.append(f"K {100 * rep.k_total_rel_std:.3f} %")
        if rep.mean_force_rel_std is not None:
            parts.append(f"mean force {100 * rep.mean_force_rel_std:.3f} %")
        if rep.amplitude_rel_std is not None:
            parts.append(f"amplitude {100 * rep.amplitude_rel_std:.3f} %")
        lines.append(
            f"repeatability over {len(rep.groups)} repeated setpoint(s): " + ", ".join(parts)
        )
    else:
        lines.append("repeatability: no setpoint was repeated")
    return "\n".join(lines) + "\n"
