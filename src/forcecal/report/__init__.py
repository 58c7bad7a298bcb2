"""Figures and an HTML report of forcecal's results (INTERFACES.md section 5; METHOD.md
section 6: every estimate beside the reactions-only baseline and the truth).

The core stages never import this package; it draws their results. Every figure function is
pure, ``(data...) -> matplotlib.figure.Figure``, built without pyplot (no global figure state),
and :func:`build_report` assembles one self-contained HTML page. A campaign's calibration
certificate is :func:`forcecal.report.certificate.calibration_certificate`, rendered from the
package's Jinja2 templates (``templates/``) with the same style sheet; the reports of the user's
data are assembled in :mod:`forcecal.report.pipeline`. The names below are imported on first
use: :mod:`forcecal.report.cells` (numbers as the reports write them) comes without matplotlib.
"""

import importlib

__all__ = [
    "CalibrationPoints",
    "Image",
    "Preformatted",
    "Section",
    "Table",
    "build_report",
    "estimate_table",
    "fig_calibration",
    "fig_coordinates",
    "fig_forces",
    "fig_residuals",
    "fig_shapes",
    "fig_signals",
    "law_harmonics",
    "save_png",
    "write_report",
]

_HOME = {name: ".html" for name in ("Image", "Preformatted", "Section", "Table", "build_report",
                                    "estimate_table", "write_report")}
"""Where each public name lives; the others are the figures' (:mod:`.figures`)."""


def __getattr__(name: str) -> object:
    """A public name, from its module on first use (figures import matplotlib)."""
    if name not in __all__:
        raise AttributeError(f"module 'forcecal.report' has no attribute {name!r}")
    found = getattr(importlib.import_module(_HOME.get(name, ".figures"), __name__), name)
    globals()[name] = found
    return found
