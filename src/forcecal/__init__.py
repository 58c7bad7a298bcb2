"""forcecal: external forces on a vibrating structure from reactions and inertia.

The public names are re-exported here; internals live in the stage modules. The method's steps
(:mod:`forcecal.api`) are imported on first use, so that ``import forcecal`` stays light::

    import forcecal

    rig = forcecal.load_rig("rig.toml")
    model = forcecal.build_spatial_model(rig, forcecal.read_scan("scan.uff", rig=rig))
    est = forcecal.reconstruct(rig, model, forcecal.read_run("runs/r01.csv"))
    print(est)                      # run, f0, the forces' fundamentals, the inertia share
    est.to_dataframe()              # the force series (pandas)
    live = forcecal.stream(rig, model, forcecal.read_run("runs/r01.csv"))   # in real time

``reconstruct`` and ``stream`` answer for the rig's drive (:mod:`forcecal.drives`): harmonic
estimates under a steady drive, forces sample by sample under any drive.
"""

import typing as _typing

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
from .records import Run, Scan, ScanFRF, ScanSpectra
from .rig import Rig, load_rig

if _typing.TYPE_CHECKING:
    from .api import (
        build_spatial_model,
        calibrate,
        load_calibration,
        load_model,
        predict,
        predict_flux,
        read_run,
        read_scan,
        reconstruct,
        stream,
        threads,
        write_calibration,
    )

_LAZY = ("build_spatial_model", "calibrate", "load_calibration", "load_model", "predict",
         "predict_flux", "read_run", "read_scan", "reconstruct", "stream", "threads",
         "write_calibration")
"""Names of :mod:`forcecal.api` imported on first use (they import SciPy's statistics)."""

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
    "ScanFRF",
    "ScanSpectra",
    "__version__",
    "build_spatial_model",
    "calibrate",
    "load_calibration",
    "load_model",
    "load_rig",
    "predict",
    "predict_flux",
    "read_run",
    "read_scan",
    "reconstruct",
    "stream",
    "threads",
    "write_calibration",
]


def __getattr__(name: str) -> object:
    """The method's steps of :mod:`forcecal.api`, imported on first use."""
    if name in _LAZY:
        from . import api

        value = getattr(api, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'forcecal' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names (``__all__``) and the module's own dunder attributes: what a user
    completes ``forcecal.`` to. The subpackages are imported by name (``forcecal.actuator``)."""
    return sorted({*__all__, *(n for n in globals() if n.startswith("__"))})
