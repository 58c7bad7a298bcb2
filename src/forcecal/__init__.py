"""forcecal: external forces on a vibrating structure from reactions and inertia.

The public names are re-exported here; internals live in the stage modules.
"""

from ._version import __version__
from .errors import (
    ConditioningError,
    DataError,
    DimensionError,
    FitError,
    ForcecalError,
    InputError,
    RigError,
)
from .records import Run, Scan
from .rig import Rig, load_rig

__all__ = [
    "ConditioningError",
    "DataError",
    "DimensionError",
    "FitError",
    "ForcecalError",
    "InputError",
    "Rig",
    "RigError",
    "Run",
    "Scan",
    "__version__",
    "load_rig",
]
