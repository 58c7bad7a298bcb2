"""Calibration of the electromagnet over a campaign of runs (METHOD.md section 5).

A campaign is a manifest (INTERFACES.md section 4) listing runs at several static gaps and
currents, and zero-current tare records. Every run is reconstructed and contributes
*calibration samples*, instants over one period of its fitted Fourier series: the coil
current, the instantaneous air gap of every pole (:mod:`forcecal.actuator.gaps`), the
reconstructed total force beside the reactions-only one, and the flux when the rig names a
flux channel. The samples of all runs are pooled and :func:`forcecal.actuator.select_law`
chooses the law. The samples of one run are a Fourier series of a few phasors, not
independent observations: the parameters' uncertainty is propagated from the noise of those
phasors and from the rig's type-B uncertainties.

The modules: :mod:`.runs` (:func:`reconstruct_campaign`), :mod:`.samples` (:func:`run_samples`,
:func:`calibration_data`), :mod:`.noise` (:class:`RunNoise`, what a run's errors do to its
samples), :mod:`.statistics` (:func:`parameter_uncertainty`), :mod:`.repeatability`,
:mod:`.calibrate` (:func:`calibrate_runs`, :func:`calibrate_campaign`) and :mod:`.result`
(:class:`CampaignResult`, ``calibration.json`` and the text report).

Shapes: ``n_poles`` force points of the actuator, ``n`` samples. SI units throughout.
"""

from __future__ import annotations

from ..actuator import ACOnlyLaw
from ..actuator.gaps import pole_motion
from .calibrate import calibrate_campaign, calibrate_runs
from .noise import RunNoise
from .result import CampaignResult, load_calibration, report_text, write_calibration
from .runs import RunResult, reconstruct_campaign, rig_for_entry
from .samples import CalibrationSamples, calibration_data
from .statistics import noise_columns, parameter_uncertainty

__all__ = [
    "ACOnlyLaw",
    "CalibrationSamples",
    "CampaignResult",
    "RunNoise",
    "RunResult",
    "calibrate_campaign",
    "calibrate_runs",
    "calibration_data",
    "load_calibration",
    "noise_columns",
    "parameter_uncertainty",
    "pole_motion",
    "reconstruct_campaign",
    "report_text",
    "rig_for_entry",
    "write_calibration",
]
