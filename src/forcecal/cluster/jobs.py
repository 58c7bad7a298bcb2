"""The jobs the commands spread over workers (:func:`forcecal.cluster.run_jobs`).

Each is a module-level function of one picklable tuple, pure in it, so a worker process (local
or on another machine) computes what the command would have computed itself. A job carries
its inputs read, never a path: a worker needs none of the client's files.

- :func:`reconstruct_job`: one run's estimate, with a Monte Carlo of its inputs when asked;
- :func:`calibrate_job`: one campaign's calibration, its runs reconstructed one after the other
  (:func:`calibrate_jobs` reads each campaign's manifest and records for it).

:func:`campaign_folders` names the output folder of each of several campaigns.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, overload

from ..actuator.laws import get_law
from ..campaign import CampaignResult, calibrate_campaign
from ..campaign.runs import load_campaign
from ..drives import drive_of
from ..errors import InputError
from ..forces.estimate import Estimate
from ..io.manifest import read_manifest
from ..model.broadband import BroadbandModel
from ..model.spatial import SpatialModel
from ..rig import Rig

__all__ = ["calibrate_job", "calibrate_jobs", "campaign_folders", "reconstruct_job"]


def reconstruct_job(job: tuple[Any, ...]) -> Estimate:
    """One run's estimate, as the rig's drive gives it: ``job`` is ``(rig, model, run, tare,
    ac_coupled, monte_carlo draws)`` (0 draws: none)."""
    rig, model, run, tare, ac_coupled, n_draws = job
    return drive_of(rig).reconstruct(rig, model, run, tare=tare, ac_coupled=ac_coupled,
                                     monte_carlo=n_draws)


def calibrate_job(job: tuple[Any, ...]) -> CampaignResult:
    """One campaign's calibration: ``job`` is ``(rig, model, campaign, ac_only, laws)``, the
    campaign read (:class:`forcecal.campaign.runs.CampaignInputs`): no file is opened; ``laws``
    the candidate laws' names, or None for the default candidates."""
    rig, model, campaign, ac_only, laws = job
    return calibrate_campaign(rig, model, campaign, workers=1, ac_only=ac_only,
                              laws=None if laws is None else [get_law(n) for n in laws])


class CalibrateJobs(Sequence[tuple[Any, ...]]):
    """The :func:`calibrate_job` of each manifest (:func:`calibrate_jobs`), a campaign's
    records read in this process when its job is taken (``jobs[k]``)."""

    def __init__(self, rig: Rig, model: SpatialModel | BroadbandModel,
                 manifests: list[str], ac_only: bool,
                 laws: tuple[str, ...] | None = None) -> None:
        self.rig, self.model, self.manifests, self.ac_only = rig, model, manifests, ac_only
        self.laws = laws

    def __len__(self) -> int:
        return len(self.manifests)

    @overload
    def __getitem__(self, k: int) -> tuple[Any, ...]: ...

    @overload
    def __getitem__(self, k: slice) -> list[tuple[Any, ...]]: ...

    def __getitem__(self, k: int | slice) -> tuple[Any, ...] | list[tuple[Any, ...]]:
        if isinstance(k, slice):
            return [self[j] for j in range(len(self))[k]]
        return (self.rig, self.model, load_campaign(self.manifests[k], self.rig), self.ac_only,
                self.laws)


def calibrate_jobs(rig: Rig, model: SpatialModel | BroadbandModel, manifests: list[str],
                   ac_only: bool, laws: tuple[str, ...] | None = None) -> CalibrateJobs:
    """The :func:`calibrate_job` of each manifest: ``(rig, model, campaign, ac_only, laws)``, the
    campaign's manifest and records read in this process (a worker needs none of its files).

    Each campaign is read when its job is taken (:class:`CalibrateJobs`), so that
    :func:`.pool.run_jobs` reads the next campaigns while the workers compute and holds a few
    at once; the manifests are read here, a bad one refused before any job runs. Every job
    holds the same ``rig`` and ``model`` objects, which :func:`.pool.run_jobs` sends to a
    cluster once for all the jobs.

    Raises
    ------
    InputError
        A bad manifest (a missing or unreadable record: when its job is taken).
    """
    for m in manifests:
        read_manifest(m)
    return CalibrateJobs(rig, model, manifests, ac_only, laws)


def campaign_folders(output: str | Path, manifests: list[str]) -> list[Path]:
    """``OUT/NAME`` for each of several manifests, NAME the manifest's file name without its
    suffix.

    Raises
    ------
    InputError
        Two manifests of one NAME (their outputs would overwrite each other).
    """
    seen: dict[str, str] = {}
    for m in manifests:
        name = Path(m).stem
        if name in seen:
            raise InputError(f"manifest '{m}': its calibration would be written to "
                             f"{Path(output) / name} like that of manifest '{seen[name]}'; "
                             "rename one of them")
        seen[name] = m
    return [Path(output) / Path(m).stem for m in manifests]
