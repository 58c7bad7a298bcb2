"""Choosing and fitting the actuator's law on a campaign: :func:`calibrate_campaign`.

The samples of all runs are pooled in a :class:`forcecal.actuator.CalibrationData` (``group`` =
run index, ``static_gap`` = the run's static gap) and :func:`forcecal.actuator.select_law`
chooses the law. The same candidate laws are fitted to the reactions-only force, to show how far
off a calibration that ignores the inertia would be.

AC-coupled (piezoelectric) gauges do not measure the DC force. With ``ac_only=True`` every law
is wrapped in :class:`forcecal.actuator.ACOnlyLaw`, which removes the per-run mean of the
modelled total force (each run's samples form one block of ``samples_per_period`` instants over
one period, so the block mean is the DC part exactly); the measured force of every run is also
made zero-mean. The law's parameters are thus fitted to the harmonics alone and still predict
the full force, DC included.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..actuator import (
    K_I0_SFE2,
    K_I2_S2,
    K_I2_SFE2,
    POWER,
    ACOnlyLaw,
    Calibration,
    CalibrationData,
    Law,
    LawFit,
    Selection,
    select_law,
)
from ..actuator.ac_only import DEFAULT_SAMPLES_PER_PERIOD
from ..actuator.frequency import SteadyRecord
from ..actuator.frequency_fit import STEP_TOLERANCE, fit_frequency_law
from ..actuator.laws import SATURATING
from ..actuator.propagation import NoiseColumns, column_effects, covariance_of
from ..errors import FitError, InputError
from ..model.broadband import BroadbandModel
from ..model.spatial import SpatialModel
from ..rig import Rig
from .repeatability import repeatability
from .result import CampaignResult, ReactionsOnly, k_total_of
from .runs import CampaignInputs, RunResult, campaign_entries, reconstruct_campaign
from .samples import calibration_data
from .statistics import ParameterUncertainty, noise_columns, parameter_uncertainty

__all__ = ["calibrate_campaign", "calibrate_runs"]

CURRENT_GAP_LAWS: tuple[Law, ...] = (K_I2_S2, K_I2_SFE2, K_I0_SFE2, POWER, SATURATING)
"""The laws tried by default: those predicting from (current, gap), which is what
``forcecal predict --current --gap`` needs. The flux law is fitted only when asked for."""

_MIN_AC_RUNS = 3


def _ac_only_laws(
    results: tuple[RunResult, ...], laws: tuple[Law, ...], block: int, manifest: str
) -> tuple[Law, ...]:
    """The laws wrapped for AC-coupled gauges, after checking the runs allow it.

    Raises
    ------
    FitError
        With fewer than three runs.
    InputError
        When the runs do not all have ``block`` samples.
    """
    if len(results) < _MIN_AC_RUNS:
        raise FitError(
            f"manifest '{manifest}': AC-only calibration needs at least {_MIN_AC_RUNS} runs "
            f"(held-out validation leaves whole runs out); the campaign has {len(results)}"
        )
    if any(r.samples.n != block for r in results):
        raise InputError("AC-only calibration needs the same number of samples in every run")
    return tuple(ACOnlyLaw.wrap(law, block) for law in laws)


def _amplitude_factor(law: Law, params: np.ndarray, data: CalibrationData) -> tuple[float, float]:
    """Least-squares factor ``c`` of ``F ~ c * model`` and the RMS relative residual of the
    model itself, on one run's data."""
    model = law.per_pole(params, data.current, data.gaps, data.flux).sum(axis=1)
    w = data.weights
    b, y = model / w, data.force / w
    c = float(b @ y / (b @ b))
    residual = float(np.sqrt(np.mean(data.relative_residual(model) ** 2)))
    return c, residual


def _per_run(chosen: LawFit, data: CalibrationData, n_runs: int) -> tuple[np.ndarray, np.ndarray]:
    """The chosen law on each run alone.

    Returns
    -------
    run_k : (n_runs,) array [N m^2/A^2]
        K_total refitted to each run, the other parameters kept (NaN for laws without K).
    run_res : (n_runs,) array [-]
        RMS relative residual of the chosen law on each run.
    """
    law = chosen.law
    group = data.group
    assert group is not None  # set by CalibrationData.__post_init__
    run_k = np.full(n_runs, np.nan)
    run_res = np.empty(n_runs)
    for k in range(n_runs):
        c, res = _amplitude_factor(law, chosen.params, data.subset(group == k))
        run_res[k] = res
        kt = k_total_of(law, chosen.params, data.n_poles)
        if kt is not None:
            run_k[k] = c * kt
    return run_k, run_res


def _reactions_only(
    results: tuple[RunResult, ...],
    laws: tuple[Law, ...],
    chosen: LawFit,
    data: CalibrationData,
    ac_only: bool,
) -> ReactionsOnly:
    """The candidate laws fitted to the reactions-only force, compared with the chosen law."""
    static = calibration_data(results, "static", ac_only)
    try:
        ro_sel = select_law(static, laws)
    except FitError as exc:
        return ReactionsOnly(selection=None, error=str(exc))
    law, n_poles = chosen.law, data.n_poles
    same = next((c for c in ro_sel.candidates if c.name == law.name), None)
    if same is None:
        return ReactionsOnly(selection=ro_sel)
    kt = k_total_of(law, same.fit.params, n_poles)
    k_ref = k_total_of(law, chosen.params, n_poles)
    corrected = law.base if isinstance(law, ACOnlyLaw) else law
    ref = corrected.per_pole(chosen.params, data.current, data.gaps, data.flux).sum(1)
    alt = corrected.per_pole(same.fit.params, data.current, data.gaps, data.flux).sum(1)
    return ReactionsOnly(
        selection=ro_sel,
        k_total=kt,
        k_total_error=None if kt is None or k_ref is None else kt / k_ref - 1.0,
        s_fe=same.fit.params_dict.get("s_fe"),
        force_error=float(np.sqrt(np.mean(((alt - ref) / ref) ** 2))),
    )


def _calibration(selection: Selection, uncertainty: ParameterUncertainty,
                 data: CalibrationData, columns: NoiseColumns | None) -> Calibration:
    """The chosen law's calibration with the propagated covariance (statistical plus type B);
    every candidate's row also gets its statistical standard uncertainties
    (``stderr_statistical``) beside the residual ones (``stderr``)."""
    rows: list[dict[str, Any]] = []
    for c in selection.candidates:
        row = c.row()
        if columns is not None:
            effects = column_effects(c.fit.law, c.fit.params, data, columns)
            std = np.sqrt(np.diag(covariance_of(effects)))
            row["stderr_statistical"] = dict(zip(c.fit.law.param_names, std.tolist(),
                                                 strict=True))
        rows.append(row)
    rows += [{"law": name, "skipped": why} for name, why in selection.skipped]
    return dataclasses.replace(Calibration.from_fit(selection.best.fit),
                               covariance=uncertainty.covariance, candidates=tuple(rows))


def _with_static_gaps(calibration: Calibration, results: Sequence[RunResult]) -> Calibration:
    """The calibration whose gap range (and its frequency law's) spans the runs' static gaps
    as well as their instantaneous ones: an attracting force keeps a run's instantaneous gaps
    below its static gap, yet a campaign's own gap is no extrapolation."""
    static = np.concatenate([np.ravel(r.samples.motion.static_gap) for r in results])

    def span(lo_hi: tuple[float, float]) -> tuple[float, float]:
        return min(lo_hi[0], float(static.min())), max(lo_hi[1], float(static.max()))

    fl = calibration.frequency_law
    if fl is not None:
        fl = dataclasses.replace(fl, gap_range=span(fl.gap_range))
    return dataclasses.replace(calibration, gap_range=span(calibration.gap_range),
                               frequency_law=fl)


FREQUENCY_STEPS = 3
"""Fundamentals (1 % apart) a campaign needs for the law over frequency (K, s_fe and the
eddy-current time constant tau, :func:`forcecal.actuator.fit_frequency_law`)."""


def _frequency_steps(results: Sequence[RunResult]) -> int:
    """How many fundamentals, 1 % apart, the runs were driven at."""
    steps: list[float] = []
    for f0 in sorted(r.estimate.f0 for r in results):
        if not steps or f0 > steps[-1] * (1 + STEP_TOLERANCE):
            steps.append(f0)
    return len(steps)


def _select(data: CalibrationData, laws: tuple[Law, ...], manifest: str) -> Selection:
    """:func:`forcecal.actuator.select_law`, its failure naming the manifest."""
    try:
        return select_law(data, laws)
    except FitError as exc:
        raise FitError(f"manifest '{manifest}': {exc}") from None


def calibrate_runs(
    rig: Rig,
    results: Sequence[RunResult],
    laws: Sequence[Law] | None = None,
    ac_only: bool = False,
    manifest: str = "<manifest>",
    tares: Sequence[str] = (),
) -> CampaignResult:
    """Choose and fit the actuator law to reconstructed runs (see :func:`calibrate_campaign`).

    Parameters
    ----------
    rig : Rig
        ``rig.actuator`` gives the ideal K reported beside the fitted one.
    results : sequence of RunResult
        The reconstructed runs.
    laws : sequence of Law or None
        Candidate laws; default :data:`CURRENT_GAP_LAWS`.
    ac_only : bool
        Fit the laws to the harmonics alone (:class:`forcecal.actuator.ACOnlyLaw`).
    manifest : str
        The manifest's name, for the messages and the file.
    tares : sequence of str
        Names of the tare records, for the file.

    Returns
    -------
    CampaignResult
        The chosen law's calibration with the campaign's scores and comparisons. Its
        covariance is propagated (:func:`forcecal.campaign.statistics.parameter_uncertainty`):
        the noise of every run's phasors (the samples of a run are not independent) plus the
        rig's type-B uncertainties applied to all runs at once. Its ``gap_range`` spans the
        runs' instantaneous and static gaps (the manifest's), so that none of the campaign's
        own gaps is an extrapolation.

    Raises
    ------
    FitError
        When no law is identifiable from the runs (one line, each law's reason).
    InputError
        When there is no run.
    """
    results = tuple(results)
    candidates = tuple(CURRENT_GAP_LAWS if laws is None else laws)
    if not results:
        raise InputError(f"manifest '{manifest}': no runs to calibrate")
    block = results[0].samples.n
    if ac_only:
        candidates = _ac_only_laws(results, candidates, block, manifest)
    data = calibration_data(results, "total", ac_only)
    selection = _select(data, candidates, manifest)
    chosen = selection.best.fit
    columns = (noise_columns(results, data.n_poles)
               if all(r.samples.noise is not None for r in results) else None)
    uncertainty = parameter_uncertainty(chosen, data, results, rig, columns)
    calibration = _calibration(selection, uncertainty, data, columns)
    if not ac_only and _frequency_steps(results) >= FREQUENCY_STEPS:
        records = [SteadyRecord.from_samples(r.samples, f0=r.estimate.f0, name=r.name)
                   for r in results]
        if any(rec.force_std is None for rec in records):      # then weighted by the residual
            records = [dataclasses.replace(rec, force_std=None) for rec in records]
        calibration = calibration.with_frequency_law(fit_frequency_law(records))
    calibration = _with_static_gaps(calibration, results)
    run_k, run_res = _per_run(chosen, data, len(results))
    return CampaignResult(
        runs=results,
        selection=selection,
        calibration=calibration,
        reactions_only=_reactions_only(results, candidates, chosen, data, ac_only),
        repeatability=repeatability(results, run_k, ac_only),
        n_poles=data.n_poles,
        ideal_k=rig.actuator.ideal_k,
        ac_only=ac_only,
        samples_per_period=block,
        run_k_total=run_k,
        run_residual=run_res,
        manifest=manifest,
        tares=tuple(tares),
        uncertainty=uncertainty,
    )


def calibrate_campaign(
    rig: Rig,
    model: SpatialModel | BroadbandModel,
    manifest_path: str | Path | CampaignInputs,
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
        The harmonic shapes.
    manifest_path : str, Path or CampaignInputs
        The campaign manifest CSV, or the campaign read
        (:func:`forcecal.campaign.load_campaign`: no file is opened then).
    progress : callable or None
        As for :func:`forcecal.campaign.reconstruct_campaign`.
    workers : int or None
        As for :func:`forcecal.campaign.reconstruct_campaign`.
    laws : sequence of Law or None
        Candidate laws; default :data:`CURRENT_GAP_LAWS`.
    ac_only : bool
        The gauges are AC-coupled: the runs are reconstructed without DC and the laws fitted to
        the harmonics alone (:class:`forcecal.actuator.ACOnlyLaw`); needs at least three runs.
    samples_per_period : int
        Calibration samples per run.

    Returns
    -------
    CampaignResult
        The runs and the chosen law's calibration with the campaign's scores and comparisons.

    Raises
    ------
    FitError
        When no candidate law is identifiable (e.g. a single static gap and only laws with
        ``s_fe``); laws that are not identifiable are otherwise skipped, their reason kept in
        ``result.selection.skipped``.

    Notes
    -----
    With ``workers`` > 1 and at least ``PARALLEL_MIN_RUNS`` runs, the runs are reconstructed in
    a ``spawn`` process pool: every worker starts a fresh interpreter that imports the calling
    script's main module. A script that calls this function must therefore guard its top level
    with ``if __name__ == "__main__":``, else each worker runs the script again: without the
    guard the default is serial, and workers asked for are refused with an InputError naming
    the script's line. The workers end with the call (on an error or Ctrl-C they are
    terminated; each also exits by itself when its parent process dies).
    """
    results = reconstruct_campaign(
        rig,
        model,
        manifest_path,
        progress=progress,
        workers=workers,
        ac_coupled=ac_only,
        samples_per_period=samples_per_period,
    )
    tares = tuple(e.run.stem for e in campaign_entries(manifest_path) if e.tare)
    name = (manifest_path.manifest if isinstance(manifest_path, CampaignInputs)
            else str(manifest_path))
    return calibrate_runs(rig, results, laws=laws, ac_only=ac_only, manifest=name, tares=tares)
