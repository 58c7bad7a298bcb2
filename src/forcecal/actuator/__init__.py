"""Calibration of the electromagnetic actuator: force against current, air gap and flux.

The observations are pooled from several runs (METHOD.md section 5). For observation ``k`` we
know the coil current ``i_k`` [A], the instantaneous air gap at every pole ``s_{k,p}`` [m], maybe
the flux through one pole ``phi_k`` [Wb], and the reconstructed TOTAL actuator force ``F_k`` [N]
(the sum over the poles, which the reconstruction determines best). A *law* gives the force of
one pole; the model of the total is the sum of the law over the poles.

Every law is fitted by nonlinear least squares on relative residuals
``(F_model - F) / max(|F|, floor)``; laws are compared by BIC and by the error of the predicted
total on held-out runs, and the simplest law that predicts held-out runs as well as the best one
is chosen. The product is a :class:`Calibration` that predicts the total force, with its
standard uncertainty, from (current, gap) or from flux.

The modules: :mod:`.laws` (the :class:`Law` protocol, every law, :func:`get_law`,
:func:`ideal_k`), :mod:`.ac_only` (:class:`ACOnlyLaw`), :mod:`.data`
(:class:`CalibrationData`), :mod:`.fitting` (:func:`fit_law`, :class:`LawFit`,
:func:`check_identifiable`), :mod:`.propagation` (the covariance propagated from described
errors), :mod:`.selection` (:func:`held_out_error`, :func:`select_law`, :func:`report_text`),
:mod:`.prediction` (:class:`Calibration`, :func:`predict`, :func:`predict_flux`),
:mod:`.frequency` and :mod:`.frequency_fit` (the law over frequency, :class:`FrequencyLaw`).

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

from .ac_only import ACOnlyLaw
from .data import FLOOR_FRACTION, GAP_TOLERANCE, CalibrationData
from .fitting import LawFit, check_identifiable, fit_law
from .frequency import FrequencyLaw, FrequencyStep, SteadyRecord
from .frequency_fit import STEP_TOLERANCE, fit_frequency_law
from .laws import (
    ALL_LAWS,
    FLUX,
    K_I0_SFE2,
    K_I2_S2,
    K_I2_SFE2,
    LAWS,
    MU0,
    POWER,
    Law,
    get_law,
    ideal_k,
)
from .prediction import (
    FREQUENCY_EXTRAPOLATION,
    Calibration,
    ExtrapolationWarning,
    Prediction,
    predict,
    predict_flux,
)
from .selection import (
    HELD_OUT_ABS_TOL,
    HELD_OUT_REL_TOL,
    N_FOLDS,
    Candidate,
    HeldOutError,
    Selection,
    held_out_error,
    report_text,
    select_law,
)

__all__ = [
    "ALL_LAWS",
    "FLOOR_FRACTION",
    "FLUX",
    "FREQUENCY_EXTRAPOLATION",
    "GAP_TOLERANCE",
    "HELD_OUT_ABS_TOL",
    "HELD_OUT_REL_TOL",
    "K_I0_SFE2",
    "K_I2_S2",
    "K_I2_SFE2",
    "LAWS",
    "MU0",
    "N_FOLDS",
    "POWER",
    "STEP_TOLERANCE",
    "ACOnlyLaw",
    "Calibration",
    "CalibrationData",
    "Candidate",
    "ExtrapolationWarning",
    "FrequencyLaw",
    "FrequencyStep",
    "HeldOutError",
    "Law",
    "LawFit",
    "Prediction",
    "Selection",
    "SteadyRecord",
    "check_identifiable",
    "fit_frequency_law",
    "fit_law",
    "get_law",
    "held_out_error",
    "ideal_k",
    "predict",
    "predict_flux",
    "report_text",
    "select_law",
]
