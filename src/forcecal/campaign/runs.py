"""Reconstructing the runs of a campaign, in parallel when there are many.

A campaign is a manifest (INTERFACES.md section 4) listing runs at several static gaps and
currents, and zero-current tare records. :func:`reconstruct_campaign` reconstructs every run
(:func:`forcecal.forces.steady.reconstruct`) with its calibration samples
(:func:`forcecal.campaign.run_samples`), in a ``spawn`` process pool when there are many.

A campaign is given by its manifest's path, its runs read where they are reconstructed, or as
:class:`CampaignInputs` (:func:`load_campaign`): the manifest's rows and every record it names,
read, so that a process without the files (a worker of a remote cluster) reconstructs it.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..actuator.ac_only import DEFAULT_SAMPLES_PER_PERIOD
from ..actuator.gaps import static_gaps
from ..cluster.pool import pool_map, unguarded_script
from ..errors import InputError
from ..forces.steady import ForceEstimate, reconstruct
from ..io.manifest import GAP_RATIO, ManifestEntry, read_manifest
from ..io.run_files import read_run
from ..model.broadband import STEADY_HARMONICS, BroadbandModel, steady_model
from ..model.spatial import SpatialModel
from ..records import Run
from ..rig import Rig
from ..signals.checks import check_run_for_rig
from .samples import CalibrationSamples, run_samples

__all__ = ["RunResult", "load_campaign", "reconstruct_campaign", "rig_for_entry"]

PARALLEL_MIN_RUNS = 3
"""Campaigns with fewer runs than this are reconstructed serially whatever ``workers`` says."""

_Caught = list[tuple[str, type[Warning]]]
"""Warnings recorded in a worker: ``(message, category)``."""


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
    """The rig with the static gaps of a manifest row (``gap``, then ``gap_<force name>``).

    Parameters
    ----------
    rig : Rig
        The rig file's rig.
    entry : ManifestEntry
        The manifest row.
    manifest : str or Path
        The manifest's name, for the messages.

    Returns
    -------
    Rig
        A copy of ``rig`` whose force points carry the row's static gaps.

    Raises
    ------
    InputError
        When a ``gap_<name>`` column names no force point of the rig, or a gap lies more than
        :data:`forcecal.io.manifest.GAP_RATIO` times off the rig's static gap at that point
        (a gap in mm, or a typing slip).
    """
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
        if gap is not None and f.gap is not None and not (
                1.0 / GAP_RATIO < gap / f.gap < GAP_RATIO):
            column = f"gap_{f.name}" if f.name in entry.gaps else "gap"
            raise InputError(
                f"manifest '{manifest}' row {entry.row}: {column} {gap:g} m at force point "
                f"'{f.name}' is more than {GAP_RATIO:g} times off the rig's static gap "
                f"{f.gap:g} m (rig '{rig.source}'); probably not in m (0.0008 for 0.8 mm)")
        forces.append(replace(f, gap=gap))
    return replace(rig, forces=tuple(forces))


@dataclass(frozen=True)
class CampaignInputs:
    """A campaign's manifest and records, read (:func:`load_campaign`): all that a calibration
    needs besides the rig and the model, with no file left to open (picklable).

    Attributes
    ----------
    manifest : str
        The manifest's path as given, for the messages and the result.
    entries : tuple of ManifestEntry
        Its rows, in file order.
    records : mapping str -> Run
        Every run and tare file the rows name (``str(entry.run)``), read with the rig.
    """

    manifest: str
    entries: tuple[ManifestEntry, ...]
    records: Mapping[str, Run]


def load_campaign(manifest_path: str | Path, rig: Rig) -> CampaignInputs:
    """Read a campaign's manifest and every run and tare file it names, each once.

    Parameters
    ----------
    manifest_path : str or Path
        The campaign manifest CSV.
    rig : Rig
        The rig: its channel map, scales and TDMS group, as the runs are read with.

    Returns
    -------
    CampaignInputs
        What :func:`reconstruct_campaign` reconstructs as it would the manifest's path.

    Raises
    ------
    InputError, DataError
        A bad manifest, a missing or unreadable record (as :func:`forcecal.io.read_run`).
    """
    entries = tuple(read_manifest(manifest_path))
    records: dict[str, Run] = {}
    for entry in entries:
        if str(entry.run) not in records:
            records[str(entry.run)] = read_run(entry.run, rig)
    return CampaignInputs(str(manifest_path), entries, records)


@dataclass(frozen=True)
class _Task:
    """One run to reconstruct, as sent to a worker process (picklable): its records read
    already (``record``, ``tare_record``), or read from their paths by the worker."""

    index: int
    rig: Rig
    model: SpatialModel | BroadbandModel
    entry: ManifestEntry
    tare: Path | None
    ac_coupled: bool
    samples_per_period: int
    record: Run | None = None
    tare_record: Run | None = None


def _reconstruct_entry(task: _Task) -> tuple[int, RunResult, _Caught]:
    """Reconstruct one run; warnings are recorded and returned, to be re-issued by the parent
    (serial and parallel runs then warn alike)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rig, model = _entry_model(task)
        run = task.record if task.record is not None else read_run(task.entry.run, rig)
        check_run_for_rig(rig, run)
        tare = task.tare_record
        if tare is None and task.tare is not None:
            tare = read_run(task.tare, rig)
        estimate = reconstruct(rig, model, run, tare=tare, ac_coupled=task.ac_coupled)
        samples = run_samples(rig, model, run, estimate, tare, task.samples_per_period,
                              tare_name=None if task.tare is None else task.tare.stem)
    result = RunResult(
        entry=task.entry,
        estimate=estimate,
        samples=samples,
        tare=None if task.tare is None else task.tare.stem,
    )
    return task.index, result, [(str(w.message), w.category) for w in caught]


def _entry_model(task: _Task) -> tuple[Rig, SpatialModel]:
    """The rig and the harmonic model of a row: from a broadband model, the harmonics of the
    row's nominal frequency (its ``frequency`` column, else the rig's)."""
    if isinstance(task.model, SpatialModel):
        return task.rig, task.model
    label = task.entry.labels.get("frequency")
    try:
        nominal = float(label) if label is not None else task.rig.drive_frequency
    except ValueError:
        raise InputError(f"manifest row {task.entry.row}: frequency {label!r} is not a number "
                         "(Hz)") from None
    if not (np.isfinite(nominal) and nominal > 0):
        raise InputError(f"manifest row {task.entry.row}: frequency {label!r} is not a "
                         "positive frequency (Hz)")
    rig = replace(task.rig, frequency=nominal)
    return rig, steady_model(task.model, rig, nominal, STEADY_HARMONICS)


def _tare_for(index: int, tares: list[int]) -> int | None:
    """The tare used by row ``index``: the closest preceding tare row, else the first one."""
    if not tares:
        return None
    before = [k for k in tares if k < index]
    return before[-1] if before else tares[0]


def campaign_entries(manifest: str | Path | CampaignInputs) -> list[ManifestEntry]:
    """The rows of a campaign given by its manifest's path or read (:class:`CampaignInputs`).

    Raises
    ------
    InputError
        A bad manifest.
    """
    if isinstance(manifest, CampaignInputs):
        return list(manifest.entries)
    return read_manifest(manifest)


def _campaign_tasks(
    rig: Rig,
    model: SpatialModel | BroadbandModel,
    manifest: str | Path | CampaignInputs,
    ac_coupled: bool,
    samples_per_period: int,
) -> list[_Task]:
    """The non-tare rows of the manifest as tasks, each with its rig and tare (and, for a
    campaign read already, with their records).

    Raises
    ------
    InputError
        A bad manifest, a run without a static gap, a manifest with no run to reconstruct.
    """
    entries = campaign_entries(manifest)
    name = manifest.manifest if isinstance(manifest, CampaignInputs) else manifest
    records = manifest.records if isinstance(manifest, CampaignInputs) else {}
    tare_rows = [k for k, e in enumerate(entries) if e.tare]
    tasks = []
    for k, e in enumerate(entries):
        if e.tare:
            continue
        tare = None if (j := _tare_for(k, tare_rows)) is None else entries[j].run
        tasks.append(_Task(index=k, rig=rig_for_entry(rig, e, name), model=model, entry=e,
                           tare=tare, ac_coupled=ac_coupled,
                           samples_per_period=samples_per_period,
                           record=records.get(str(e.run)),
                           tare_record=None if tare is None else records.get(str(tare))))
    if not tasks:
        raise InputError(f"manifest '{name}': every run is a tare; nothing to calibrate")
    for task in tasks:
        static_gaps(task.rig)
    return tasks


def _run_tasks(
    tasks: list[_Task], workers: int, finish: Callable[[int, RunResult, _Caught], None]
) -> None:
    """Reconstruct the tasks, serially or in a ``spawn`` pool, calling ``finish`` on each
    result as it comes (in the parent process)."""
    if workers <= 1 or len(tasks) < PARALLEL_MIN_RUNS:
        for task in tasks:
            finish(*_reconstruct_entry(task))
        return
    for result in pool_map(_reconstruct_entry, tasks, workers):
        finish(*result)


def reconstruct_campaign(
    rig: Rig,
    model: SpatialModel | BroadbandModel,
    manifest_path: str | Path | CampaignInputs,
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
        The rig; each row's gaps replace its static gaps.
    model : SpatialModel
        The harmonic shapes.
    manifest_path : str, Path or CampaignInputs
        The campaign manifest CSV, or the campaign read (:func:`load_campaign`).
    progress : callable or None
        Called as ``progress(done, total, run name)`` after each run.
    workers : int or None
        Worker processes; default ``min(2, os.cpu_count())``, or 1 when called from the top
        level of a script without ``if __name__ == "__main__":``. Campaigns of fewer than
        ``PARALLEL_MIN_RUNS`` runs, or ``workers <= 1``, run serially.
    ac_coupled : bool
        The gauges do not measure DC (piezoelectric): see
        :func:`forcecal.forces.steady.reconstruct`.
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

    Notes
    -----
    With ``workers`` > 1 and at least ``PARALLEL_MIN_RUNS`` runs, the runs are reconstructed in
    a ``spawn`` process pool: every worker starts a fresh interpreter that imports the calling
    script's main module. A script that calls this function must therefore guard its top level
    with ``if __name__ == "__main__":``, else each worker runs the script again: such a script
    asking for workers is refused with an InputError naming its line
    (:func:`forcecal.cluster.pool.check_main_guard`). The workers end with the call (on an
    error or Ctrl-C they are terminated; each also exits by itself when its parent process
    dies).
    """
    tasks = _campaign_tasks(rig, model, manifest_path, ac_coupled, samples_per_period)
    if workers is None:      # serially in a script that every worker would run again
        workers = 1 if unguarded_script() else min(2, os.cpu_count() or 1)
    done: dict[int, RunResult] = {}

    def finish(index: int, result: RunResult, caught: _Caught) -> None:
        for message, category in caught:
            # finish <- _run_tasks <- reconstruct_campaign <- its caller
            warnings.warn(message, category, stacklevel=4)
        done[index] = result
        if progress is not None:
            progress(len(done), len(tasks), result.name)

    _run_tasks(tasks, workers, finish)
    return [done[task.index] for task in tasks]
