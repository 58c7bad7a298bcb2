"""Figures of the method's stages (METHOD.md sections 3, 5 and 6), after the reference paper's
figures 3 and 6 to 9.

Every function is pure: it takes the stage objects (SI units) and returns a new
:class:`matplotlib.figure.Figure` built without pyplot, so no global figure state is created
and nothing needs closing. Axes show readable units (:mod:`._common`); every label names its
unit. The figures, one module per family:

- :mod:`.shapes` (paper fig. 3): :func:`fig_shapes` a beam's measured harmonic shapes with
  their fitted curves and MAC values, :func:`fig_shapes_2d` a plate's, :func:`fig_shapes_body`
  a body's records against the vector model;
- :mod:`.signals`: :func:`fig_signals` (fig. 6), current and each probe with their Fourier
  series; :func:`fig_coordinates` (fig. 7), the coordinates' amplitudes, inertia per harmonic;
- :mod:`.forces`: :func:`fig_forces` (fig. 8), inertia, reactions, each force beside the
  reactions-only estimate and the truth, and its error with the +-2 sigma band;
- :mod:`.residuals`: :func:`fig_residuals`, fit residuals, chi-square, force amplitudes;
- :mod:`.calibration`: :func:`fig_calibration` (fig. 9), the law at the samples' own conditions.

:func:`figure_bytes` renders a figure as PNG, SVG or PDF; :func:`save_png` writes a PNG.
"""

from .calibration import CalibrationPoints, fig_calibration, law_harmonics
from .forces import fig_forces
from .output import figure_bytes, save_png
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
    "figure_bytes",
    "law_harmonics",
    "save_png",
]
