"""Any drive: sweeps, chirps, random (METHOD.md section 7, "any drive"): a broadband model
from the scan's band, and forces sample by sample, batch (Kalman smoother, Wiener gains) or in
real time."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..forces.transient import TransientEstimate, reconstruct_any
from ..io.blocks import RunBlocks
from ..model.broadband import BroadbandModel, build_broadband_model
from ..realtime.any_drive import stream_any, stream_any_table
from ..records import Run
from ..rig import Rig
from .base import Note, refuse_report, refuse_scans
from .steady import band_line

__all__ = ["AnyDrive"]


class AnyDrive:
    """Runs under any drive within ``acquisition.band``."""

    name = "any"

    def __init__(self, rig: Rig) -> None:
        self.band = rig.band

    def build_model(self, rig: Rig, scan: Any, *, n_harmonics: int = 6,
                    criterion: str = "gcv", basis: str = "polynomial") -> BroadbandModel:
        """The broadband model of the scan over its band."""
        return build_broadband_model(rig, scan, criterion=criterion)

    def streams_harmonics(self, model: Any) -> bool:
        """False: forces sample by sample, with a fixed latency."""
        return False

    def check_scans(self, rig: Rig, n_scans: int) -> None:
        """A broadband model is built from one scan."""
        refuse_scans(rig, n_scans)

    def merge_models(self, rig: Rig, models: list[Any]) -> BroadbandModel:
        """Refused: a broadband model is built from one scan."""
        refuse_scans(rig, len(models))
        return models[0]

    def model_lines(self, model: Any, output: str, n_scans: int) -> list[str]:
        """What ``scan`` prints: the band and the shapes."""
        return [band_line(model, output)]

    def check_options(self, rig: Rig, *, n_harmonics: int | None = None,
                      ac_coupled: bool = False, monte_carlo: int = 0,
                      fmt: str = "csv") -> None:
        """Refuse the options of the harmonic estimate: forces sample by sample have no
        harmonics to drop the DC of, and no Monte Carlo of their inputs."""
        if fmt not in TransientEstimate.formats:
            raise InputError(f"rig '{rig.source}': --format {fmt} holds a steady drive's "
                             "phasors; under acquisition.drive = 'any' the forces sample by "
                             f"sample are written as {' or '.join(TransientEstimate.formats)}")
        for given, option in ((n_harmonics is not None, "n_harmonics"),
                              (ac_coupled, "--ac-coupled"), (monte_carlo, "--monte-carlo")):
            if given:
                raise InputError(f"rig '{rig.source}': {option} serves a steady drive's harmonic "
                                 "estimate; under acquisition.drive = 'any' the forces come "
                                 "sample by sample with their stated uncertainty")

    def reconstruct(self, rig: Rig, model: Any, run: Run, *, n_harmonics: int | None = None,
                    tare: Run | None = None, ac_coupled: bool = False,
                    monte_carlo: int = 0) -> TransientEstimate:
        """The batch estimate of a run's forces, sample by sample."""
        self.check_options(rig, n_harmonics=n_harmonics, ac_coupled=ac_coupled,
                           monte_carlo=monte_carlo)
        return reconstruct_any(rig, _broadband(rig, model), run, tare)

    def stream_run(self, rig: Rig, model: Any, run: Run, tare: Run | None = None
                   ) -> TransientEstimate:
        """The real-time estimate of a run held in memory."""
        return stream_any(rig, _broadband(rig, model), run, tare)

    def zeroed_channels(self, rig: Rig, model: Any) -> list[str]:
        """The gauges and the probes: a tare's means are their zero."""
        return [*rig.gauge_names, *rig.sensor_names]

    def stream(self, rig: Rig, model: Any, blocks: RunBlocks, output: str | Path, *,
               check: Callable[..., None] | None = None, note: Note | None = None,
               tare: Run | None = None, block: int = 256,
               forgetting: float | None = None) -> int:
        """The real-time estimator, sample by sample."""
        return stream_any_table(rig, _broadband(rig, model), blocks, output, check=check,
                                note=note, tare=tare)

    def check_report(self, rig: Rig) -> None:
        """``report`` draws a harmonic model: refused."""
        raise refuse_report(rig)

    def run_lines(self, est: TransientEstimate, series: Path, verbose: bool) -> list[str]:
        """The band, the total's AC RMS, the RMS uncertainty of a sample, the inertia share
        and the notes."""
        ac = float(np.std(est.total))
        quad = float(np.sqrt(np.mean(est.total_std**2)))
        return [f"{series}: any drive, band {est.band[0]:g}-{est.band[1]:g} Hz, total AC RMS "
                f"{ac:.4g} N, uncertainty of a sample (RMS) {quad:.3g} N (k = 2: "
                f"{2 * quad:.3g} N), inertia share {est.inertia_share:.1%}",
                *(f"note: {note}" for note in est.notes)]


def _broadband(rig: Rig, model: Any) -> BroadbandModel:
    """The model, which under any drive must be a broadband one."""
    if not isinstance(model, BroadbandModel):
        raise InputError(f"rig '{rig.source}': acquisition.drive = 'any' needs a broadband "
                         "model (a scan under a broadband drive, with acquisition.band)")
    return model
