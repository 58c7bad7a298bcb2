"""A steady periodic drive (METHOD.md section 3): harmonic shapes from the scan, harmonic
estimates of every run. The scan itself may be steady or broadband (``acquisition.band``):
a broadband model gives each run the harmonic shapes of the run's own frequency."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..forces.budget import draw_std, monte_carlo
from ..forces.estimate import ForceEstimate
from ..forces.steady import reconstruct as reconstruct_steady
from ..forces.steady import solve_inputs
from ..forces.transient import TransientEstimate
from ..io.blocks import RunBlocks
from ..model.broadband import BroadbandModel, build_broadband_model
from ..model.spatial import SpatialModel, build_spatial_model, merge_models
from ..realtime.any_drive import stream_any, stream_any_table
from ..realtime.replay import StreamedForces, stream_steady, stream_table
from ..records import Run
from ..rig import Rig
from .base import Note, refuse_report, refuse_scans

__all__ = ["SteadyDrive"]

MONTE_CARLO_SEED = 20260101
"""Seed of ``reconstruct --monte-carlo``: the same draws on every run and every worker."""


class SteadyDrive:
    """Runs under a steady periodic drive at ``acquisition.frequency``."""

    name = "steady"

    def __init__(self, rig: Rig) -> None:
        self.band = rig.band
        """The broadband scan's band [Hz], or None for a steady scan."""

    def build_model(self, rig: Rig, scan: Any, *, n_harmonics: int = 6,
                    criterion: str = "gcv", basis: str = "polynomial"
                    ) -> SpatialModel | BroadbandModel:
        """The harmonic model of a steady scan, or the broadband model of a broadband one."""
        if self.band is not None:
            return build_broadband_model(rig, scan, criterion=criterion)
        return build_spatial_model(rig, scan, n_harmonics=n_harmonics, criterion=criterion,
                                   basis=basis)

    def streams_harmonics(self, model: Any) -> bool:
        """True, but for a broadband model, which streams sample by sample."""
        return not isinstance(model, BroadbandModel)

    def check_scans(self, rig: Rig, n_scans: int) -> None:
        """Several steady scans make a span of shapes; a broadband model takes one."""
        if self.band is not None:
            refuse_scans(rig, n_scans)

    def merge_models(self, rig: Rig, models: list[Any]) -> SpatialModel:
        """A span of shapes per harmonic from the models of several steady scans."""
        self.check_scans(rig, len(models))
        return merge_models(rig, models)

    def model_lines(self, model: Any, output: str, n_scans: int) -> list[str]:
        """What ``scan`` prints: the fundamental, harmonics and orders, or the band."""
        if isinstance(model, BroadbandModel):
            return [band_line(model, output)]
        lines = [f"{output}: fundamental {model.f0:.6g} Hz, harmonics "
                 f"{', '.join(str(n) for n in model.harmonics)} (orders "
                 f"{', '.join(str(s.order) for s in model.shapes)}); lowest MAC between "
                 f"harmonics {model.similarity.min():.5f}: "
                 f"{'one shape serves all' if model.one_shape else 'shapes differ'}"]
        if n_scans > 1:
            lines.append(f"{n_scans} scans: shapes per harmonic "
                         + ", ".join(f"{int(n)}: {len(model.members(k))}"
                                     for k, n in enumerate(model.harmonics)))
        return lines + [f"note: {note}" for note in model.notes]

    def check_options(self, rig: Rig, *, n_harmonics: int | None = None,
                      ac_coupled: bool = False, monte_carlo: int = 0,
                      fmt: str = "csv") -> None:
        """Every option serves a steady drive."""

    def reconstruct(self, rig: Rig, model: Any, run: Run, *, n_harmonics: int | None = None,
                    tare: Run | None = None, ac_coupled: bool = False,
                    monte_carlo: int = 0) -> ForceEstimate:
        """A run's harmonic estimate, with a Monte Carlo of its inputs when ``monte_carlo``
        draws are asked (GUM S1)."""
        harmonic = model.harmonic(rig, rig.drive_frequency)
        est = reconstruct_steady(rig, harmonic, run, n_harmonics=n_harmonics, tare=tare,
                                 ac_coupled=ac_coupled)
        return with_monte_carlo(rig, harmonic, run, est, tare, monte_carlo) if monte_carlo \
            else est

    def zeroed_channels(self, rig: Rig, model: Any) -> list[str]:
        """The gauges (and the probes, for a broadband model streamed sample by sample): a
        tare's means are their zero."""
        if isinstance(model, BroadbandModel):
            return [*rig.gauge_names, *rig.sensor_names]
        return list(rig.gauge_names)

    def stream_run(self, rig: Rig, model: Any, run: Run, tare: Run | None = None
                   ) -> StreamedForces | TransientEstimate:
        """The real-time estimate of a run held in memory: the recursive harmonic estimator,
        or for a broadband model the one sample by sample."""
        if isinstance(model, BroadbandModel):
            return stream_any(rig, model, run, tare)
        return stream_steady(rig, model, run, tare)

    def stream(self, rig: Rig, model: Any, blocks: RunBlocks, output: str | Path, *,
               check: Callable[..., None] | None = None, note: Note | None = None,
               tare: Run | None = None, block: int = 256,
               forgetting: float | None = None) -> int:
        """The harmonic recursive estimator; a broadband model streams sample by sample."""
        if isinstance(model, BroadbandModel):
            return stream_any_table(rig, model, blocks, output, check=check, note=note,
                                    tare=tare)
        return stream_table(rig, model, blocks, output, block=block, check=check,
                            forgetting=forgetting, note=note)

    def check_report(self, rig: Rig) -> None:
        """``report`` draws a harmonic model: a broadband scan's rig is refused."""
        if self.band is not None:
            raise refuse_report(rig)

    def run_lines(self, est: ForceEstimate, series: Path, verbose: bool) -> list[str]:
        """The fundamental, the total's uncertainty and its largest source, the inertia
        share, the notes (and with ``verbose`` the budget)."""
        lines = [f"{series}: f0 {est.f0:.6g} Hz, total AC uncertainty {est.waveform_std:.3g} N "
                 f"(k = 2: {2 * est.waveform_std:.3g} N; largest source {_largest(est)}), "
                 f"inertia share {est.inertia_share:.1%}"]
        lines += [f"note: {note}" for note in est.notes]
        return lines + (_budget_lines(est) if verbose else [])


def band_line(model: BroadbandModel, output: str) -> str:
    """What ``scan`` prints of a broadband model."""
    return (f"{output}: band {model.band[0]:g}-{model.band[1]:g} Hz, {model.n_shapes} "
            f"shape(s) span the deflections (order {model.shapes[0].order})")


def with_monte_carlo(rig: Rig, model: SpatialModel, run: Run, est: ForceEstimate,
                     tare: Run | None, n_draws: int) -> ForceEstimate:
    """The estimate with the standard deviations of a Monte Carlo of its inputs (GUM S1)."""
    rng = np.random.default_rng(MONTE_CARLO_SEED)
    draws = monte_carlo(rig, model, solve_inputs(rig, model, run, est, tare), n_draws, rng)
    return dataclasses.replace(est, monte_carlo_std=draw_std(draws), monte_carlo_draws=n_draws)


def _budget_lines(est: ForceEstimate) -> list[str]:
    """Every force's and the total's standard uncertainty at the DC and the fundamental,
    source by source: a table, a row per source, two aligned columns per force."""
    names = [*est.force_names, "total"]
    rows = [*est.budget.items(), ("combined", est.combination_std),
            ("expanded k = 2", est.expanded())]
    cells = []
    for _src, std in rows:
        assert std is not None
        cells.append([f"{std[est.combination_names.index(n), h]:.3g}" for n in names
                      for h in (0, 1)])
    width = max(9, *(len(c) for row in cells for c in row), *((len(n) - 1) // 2 for n in names))
    label = max(len(src) for src, _ in rows)
    lines = ["  uncertainty budget [N]: standard uncertainty of every force at DC and at the "
             "fundamental",
             f"    {'':<{label}}" + "".join(f"  {n:>{2 * width + 2}}" for n in names),
             f"    {'source':<{label}}" + "  ".join(["", *(f"{h:>{width}}" for _ in names
                                                         for h in ("DC", "n = 1"))])]
    lines += [f"    {src:<{label}}" + "  ".join(["", *(f"{c:>{width}}" for c in row)])
              for (src, _), row in zip(rows, cells, strict=True)]
    return lines


def _largest(est: ForceEstimate) -> str:
    """The budget source with the largest part in the total's AC harmonics."""
    k = est.combination_names.index("total")
    return max(est.budget, key=lambda src: float(np.sum(est.budget[src][k, 1:] ** 2)))
