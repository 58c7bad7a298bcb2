"""Calibration of the electromagnetic actuator: force against current, air gap and flux.

The observations are pooled from several runs (METHOD.md section 5): the coil current ``i_k``
[A], the instantaneous air gap at every pole ``s_{k,p}`` [m], maybe the flux through one pole
``phi_k`` [Wb], and the reconstructed TOTAL actuator force ``F_k`` [N] (which the
reconstruction determines best). A *law* gives the force of one pole, the model of the total
sums it over the poles. Every law is fitted by nonlinear least squares on relative residuals
``(F_model - F) / max(|F|, floor)``; laws are compared by BIC and by the error on held-out
runs, and the simplest that predicts them as well as the best one is chosen. The product is a
:class:`Calibration`: the total force, with its standard uncertainty, from (current, gap) or
from flux.

The modules: :mod:`.laws` (:class:`Law`, every law, :func:`get_law`), :mod:`.ac_only`,
:mod:`.data` (:class:`CalibrationData`), :mod:`.fitting` (:func:`fit_law`), :mod:`.propagation`
(the covariance from described errors), :mod:`.selection` (:func:`select_law`),
:mod:`.prediction` (:class:`Calibration`, :func:`predict`), :mod:`.frequency`,
:mod:`.frequency_models`, :mod:`.frequency_fit` and :mod:`.frequency_selection` (the law over
frequency: the core's response, first or half order, fitted and chosen). Shapes: ``n_obs``
observations, ``n_poles`` poles, ``n_params`` parameters of a law; SI units throughout.
"""

from __future__ import annotations

from .ac_only import ACOnlyLaw
from .data import CalibrationData
from .fitting import LawFit, fit_law
from .frequency import FrequencyLaw, SteadyRecord
from .frequency_fit import fit_frequency_law
from .laws import ALL_LAWS, FLUX, K_I0_SFE2, K_I2_S2, K_I2_SFE2, LAWS, MU0, POWER, Law, ideal_k
from .prediction import Calibration, ExtrapolationWarning, predict, predict_flux
from .selection import Candidate, Selection, report_text, select_law

__all__ = [
    "ALL_LAWS",
    "FLUX",
    "K_I0_SFE2",
    "K_I2_S2",
    "K_I2_SFE2",
    "LAWS",
    "MU0",
    "POWER",
    "ACOnlyLaw",
    "Calibration",
    "CalibrationData",
    "Candidate",
    "ExtrapolationWarning",
    "FrequencyLaw",
    "Law",
    "LawFit",
    "Selection",
    "SteadyRecord",
    "fit_frequency_law",
    "fit_law",
    "ideal_k",
    "predict",
    "predict_flux",
    "report_text",
    "select_law",
]
