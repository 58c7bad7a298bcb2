"""The jobs the commands spread over workers (:func:`forcecal.cluster.run_jobs`).

Each is a module-level function of one picklable tuple, pure in it, so a worker process (local
or on another machine) computes what the command would have computed itself:

- :func:`reconstruct_job`: one run's estimate, with a Monte Carlo of its inputs when asked;
- :func:`calibrate_job`: one campaign's calibration, its runs reconstructed one after the other.

:func:`campaign_folders` names the output folder of each of several campaigns.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..campaign import CampaignResult, calibrate_campaign
from ..drives import drive_of
from ..errors import InputError
from ..forces.estimate import Estimate

__all__ = ["calibrate_job", "campaign_folders", "reconstruct_job"]


def reconstruct_job(job: tuple[Any, ...]) -> Estimate:
    """One run's estimate, as the rig's drive gives it: ``job`` is ``(rig, model, run, tare,
    ac_coupled, monte_carlo draws)`` (0 draws: none)."""
    rig, model, run, tare, ac_coupled, n_draws = job
    return drive_of(rig).reconstruct(rig, model, run, tare=tare, ac_coupled=ac_coupled,
                                     monte_carlo=n_draws)


def calibrate_job(job: tuple[Any, ...]) -> CampaignResult:
    """One campaign's calibration: ``job`` is ``(rig, model, manifest, ac_only)``."""
    rig, model, manifest, ac_only = job
    return calibrate_campaign(rig, model, manifest, workers=1, ac_only=ac_only)


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
