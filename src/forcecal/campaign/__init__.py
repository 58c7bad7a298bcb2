"""Calibration of the electromagnet over a campaign of runs (METHOD.md section 5).

A campaign is a manifest (INTERFACES.md section 4) listing runs at several static gaps and
currents, and zero-current tare records. Every run is reconstructed (:func:`forcecal.forces.
reconstruct`, in parallel when there are many), and each run contributes *calibration samples*:
``samples_per_period`` instants spread over one period of its fitted Fourier series, holding

- the coil current ``i(t)`` [A], from the harmonic fit of the current channel;
- the instantaneous air gap of every pole, ``s_p(t) = s_0,p - w(x_p, t)`` [m], where the
  displacement at the pole comes from the spatial model and the run's generalized coordinates,
  ``w(x_p, t) = w_dc(x_p) + sum_n Re(phi_n(x_p) Q_n exp(j n w0 t))`` (not the mean gap; the DC
  deflection and the limits of its quasi-static approximation are described in
  :mod:`forcecal.actuator.gaps`);
- the reconstructed total actuator force (reactions plus inertia) [N], and beside it the
  reactions-only total, both evaluated from their phasors;
- the flux through a pole [Wb], when the rig names a flux channel.

The samples of all runs are pooled and :func:`forcecal.actuator.select_law` chooses the law
(see :mod:`forcecal.campaign.calibrate`, also for AC-coupled gauges). The samples of one run are
a Fourier series of a few phasors, not independent observations: the parameters' uncertainty
is propagated from the noise of those phasors and from the rig's type-B uncertainties
(:mod:`forcecal.campaign.statistics`).

The modules of the package:

runs
    Reconstructing the runs of a manifest (:func:`reconstruct_campaign`), the worker pool.
samples
    The calibration samples of a run (:func:`run_samples`) and their pooling
    (:func:`calibration_data`).
noise
    What a run's errors do to its samples, per source (:class:`RunNoise`).
statistics
    The parameters' statistical and type-B uncertainty with its budget
    (:func:`parameter_uncertainty`).
repeatability
    The spread over repeated setpoints.
calibrate
    :func:`calibrate_runs` and :func:`calibrate_campaign`.
result
    :class:`CampaignResult`, ``calibration.json`` and the text report.

Shapes: ``n_poles`` force points of the actuator, ``n`` samples. SI units throughout.
"""

from __future__ import annotations

from ..actuator import ACOnlyLaw
from ..actuator.gaps import PoleMotion, pole_motion, quasi_static_shape
from .calibrate import CURRENT_GAP_LAWS, calibrate_campaign, calibrate_runs
from .noise import RunNoise, run_noise
from .repeatability import Repeatability
from .result import CampaignResult, ReactionsOnly, load_calibration, report_text, write_calibration
from .runs import PARALLEL_MIN_RUNS, RunResult, reconstruct_campaign, rig_for_entry
from .samples import DEFAULT_SAMPLES_PER_PERIOD, CalibrationSamples, calibration_data, run_samples
from .statistics import ParameterUncertainty, noise_columns, parameter_uncertainty

__all__ = [
    "CURRENT_GAP_LAWS",
    "DEFAULT_SAMPLES_PER_PERIOD",
    "PARALLEL_MIN_RUNS",
    "ACOnlyLaw",
    "CalibrationSamples",
    "CampaignResult",
    "ParameterUncertainty",
    "PoleMotion",
    "ReactionsOnly",
    "Repeatability",
    "RunNoise",
    "RunResult",
    "calibrate_campaign",
    "calibrate_runs",
    "calibration_data",
    "load_calibration",
    "noise_columns",
    "parameter_uncertainty",
    "pole_motion",
    "quasi_static_shape",
    "reconstruct_campaign",
    "report_text",
    "rig_for_entry",
    "run_noise",
    "run_samples",
    "write_calibration",
]
