"""The jobs the commands spread over workers (:func:`forcecal.cluster.run_jobs`).

Each is a module-level function of one picklable tuple, pure in it, so a worker process (local
or on another machine) computes what the command would have computed itself:

- :func:`reconstruct_job`: one run's estimate, with a Monte Carlo of its inputs when asked;
- :func:`calibrate_job`: one campaign's calibration, its runs reconstructed one after the other.

:func:`campaign_folders` names the output folder of each of several campaigns.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    from ..campaign import CampaignResult
    from ..forces.estimate import ForceEstimate
    from ..model.spatial import SpatialModel
    from ..records import Run
    from ..rig import Rig

__all__ = ["MONTE_CARLO_SEED", "calibrate_job", "campaign_folders", "reconstruct_job",
           "with_monte_carlo"]

MONTE_CARLO_SEED = 20260101
"""Seed of ``reconstruct --monte-carlo``: the same draws on every run and every worker."""


def reconstruct_job(job: tuple[Any, ...]) -> ForceEstimate:
    """One run's estimate: ``job`` is ``(rig, model, run, tare, ac_coupled, monte_carlo
    draws)`` (0 draws: none)."""
    from ..forces.steady import reconstruct

    rig, model, run, tare, ac_coupled, n_draws = job
    from ..model.spatial import SpatialModel

    if not isinstance(model, SpatialModel):                # a broadband model: a steady run
        from ..model.broadband import STEADY_HARMONICS, steady_model

        model = steady_model(model, rig, rig.drive_frequency, STEADY_HARMONICS)
    est = reconstruct(rig, model, run, tare=tare, ac_coupled=ac_coupled)
    return with_monte_carlo(rig, model, run, est, tare, n_draws) if n_draws else est


def with_monte_carlo(rig: Rig, model: SpatialModel, run: Run, est: ForceEstimate,
                     tare: Run | None, n_draws: int) -> ForceEstimate:
    """The estimate with the standard deviations of a Monte Carlo of its inputs (GUM S1)."""
    from ..forces.budget import draw_std, monte_carlo
    from ..forces.steady import solve_inputs

    rng = np.random.default_rng(MONTE_CARLO_SEED)
    draws = monte_carlo(rig, model, solve_inputs(rig, model, run, est, tare), n_draws, rng)
    return dataclasses.replace(est, monte_carlo_std=draw_std(draws), monte_carlo_draws=n_draws)


def calibrate_job(job: tuple[Any, ...]) -> CampaignResult:
    """One campaign's calibration: ``job`` is ``(rig, model, manifest, ac_only)``."""
    from ..campaign import calibrate_campaign

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
