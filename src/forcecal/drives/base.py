"""What every drive answers: the model from a scan, a run's estimate, its stream, its files and
its lines on the console (:class:`Drive`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from ..errors import InputError
from ..records import Run
from ..rig import Rig

__all__ = ["Drive"]

Note = Callable[[str], None]
"""Where a note is said (the command line prints it)."""


class Drive(Protocol):
    """A drive: steady (:class:`~forcecal.drives.SteadyDrive`) or any
    (:class:`~forcecal.drives.AnyDrive`)."""

    name: str
    """``acquisition.drive``: "steady" or "any"."""

    def build_model(self, rig: Rig, scan: Any, *, n_harmonics: int = 6,
                    criterion: str = "gcv", basis: str = "polynomial") -> Any:
        """The model of one scan."""
        ...

    def streams_harmonics(self, model: Any) -> bool:
        """Whether ``stream`` tracks harmonics with a memory to set (``--memory``,
        ``--steady``), rather than forces sample by sample with a fixed latency."""
        ...

    def check_scans(self, rig: Rig, n_scans: int) -> None:
        """Refuse more scans than its model is built from."""
        ...

    def merge_models(self, rig: Rig, models: list[Any]) -> Any:
        """The model of several scans under different loads."""
        ...

    def model_lines(self, model: Any, output: str, n_scans: int) -> list[str]:
        """What ``scan`` prints of the model it wrote to ``output``."""
        ...

    def reconstruct(self, rig: Rig, model: Any, run: Run, *, n_harmonics: int | None = None,
                    tare: Run | None = None, ac_coupled: bool = False, monte_carlo: int = 0) -> Any:
        """A run's estimate (an :class:`~forcecal.forces.estimate.Estimate`)."""
        ...

    def check_options(self, rig: Rig, *, n_harmonics: int | None = None,
                      ac_coupled: bool = False, monte_carlo: int = 0,
                      fmt: str = "csv") -> None:
        """Refuse the options this drive has no use for."""
        ...

    def zeroed_channels(self, rig: Rig, model: Any) -> list[str]:
        """The channels whose tare mean is their zero."""
        ...

    def stream_run(self, rig: Rig, model: Any, run: Run, tare: Run | None = None) -> Any:
        """The real-time estimate of a run held in memory (an
        :class:`~forcecal.forces.estimate.Estimate`)."""
        ...

    def stream(self, rig: Rig, model: Any, blocks: Any, output: str | Path, *,
               check: Callable[..., None] | None = None, note: Note | None = None,
               tare: Run | None = None, block: int = 256,
               forgetting: float | None = None) -> int:
        """Stream an open run into ``output``; the rows written."""
        ...

    def check_report(self, rig: Rig) -> None:
        """Refuse ``report`` where it has no harmonic model to draw."""
        ...

    def run_lines(self, est: Any, series: Path, verbose: bool) -> list[str]:
        """What ``reconstruct`` prints of a run's estimate written to ``series``."""
        ...


def refuse_report(rig: Rig) -> InputError:
    """The refusal of ``report`` on a broadband scan's rig, which has no harmonic model."""
    return InputError(
        f"rig '{rig.source}': 'report' draws a steady drive's harmonic report from a harmonic "
        "model, and this rig's 'acquisition.band' makes its scan a broadband one; its runs' "
        "forces come from 'reconstruct' (their summary JSON and series), a stepped-sine "
        "campaign's report from 'calibrate'")


def refuse_scans(rig: Rig, n_scans: int) -> None:
    """Refuse several scans for a broadband model."""
    if n_scans > 1:
        raise InputError(f"rig '{rig.source}': a broadband model is built from one scan")
