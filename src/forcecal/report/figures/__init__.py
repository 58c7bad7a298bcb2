"""Figures of the method's stages (METHOD.md sections 3, 5 and 6), after the reference paper's
figures 3 and 6 to 9.

Every function is pure: it takes the stage objects (SI units) and returns a new
:class:`matplotlib.figure.Figure` built without pyplot, so no global figure state is created
and nothing needs closing. Axes show readable units (:mod:`._common`); every label names its
unit. The figures, one module per family:

- :mod:`.shapes` (paper fig. 3): :func:`fig_shapes` a beam's measured harmonic shapes with
  their fitted curves and MAC values, :func:`fig_shapes_2d` a plate's, :func:`fig_shapes_body`
  a body's records against the vector model;
- :mod:`.signals`: :func:`fig_signals` (fig. 6), current and probe displacements with their
  Fourier series; :func:`fig_coordinates` (fig. 7), generalized coordinates, inertia terms;
- :mod:`.forces`: :func:`fig_forces` (fig. 8), inertia and reactions, reconstructed forces
  beside the reactions-only estimate and the truth;
- :mod:`.residuals`: :func:`fig_residuals`, fit residuals, sensor-fit chi-square, force
  amplitudes per harmonic;
- :mod:`.calibration`: :func:`fig_calibration` (fig. 9), the calibrated law per gap.

:func:`save_png` writes a figure atomically; :func:`png_bytes` renders it in memory.
"""

from .calibration import CalibrationPoints, fig_calibration, law_harmonics
from .forces import fig_forces
from .output import png_bytes, save_png
from .residuals import fig_residuals
from .shapes import fig_shapes, fig_shapes_2d, fig_shapes_body
from .signals import fig_coordinates, fig_signals

__all__ = [
    "CalibrationPoints",
    "fig_calibration",
    "fig_coordinates",
    "fig_forces",
    "fig_residuals",
    "fig_shapes",
    "fig_shapes_2d",
    "fig_shapes_body",
    "fig_signals",
    "law_harmonics",
    "png_bytes",
    "save_png",
]
