"""The drive as a type (METHOD.md sections 3 and 7): a steady periodic drive, whose runs give
harmonic estimates, or any drive (sweeps, chirps, random), whose runs give forces sample by
sample. :func:`drive_of` reads the rig's ``acquisition`` table once and picks the class; every
command asks the drive, never which drive it is."""

from __future__ import annotations

from ..rig import Rig
from .any import AnyDrive
from .base import Drive
from .steady import SteadyDrive

DRIVES: dict[str, type[SteadyDrive] | type[AnyDrive]] = {"steady": SteadyDrive, "any": AnyDrive}
"""``acquisition.drive`` -> the class that answers for it."""


def drive_of(rig: Rig) -> Drive:
    """The drive of a rig's runs, as its ``acquisition`` table declares it."""
    return DRIVES[rig.drive](rig)


__all__ = ["drive_of"]
