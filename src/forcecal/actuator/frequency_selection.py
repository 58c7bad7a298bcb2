"""Choosing the core's response over frequency: held-out steps and an information criterion.

Every model of :mod:`.frequency_models` fitted to a stepped-sine campaign is scored
(:class:`ModelScore`) by its AIC and BIC and by its error on frequency steps left out of its
fit (:func:`.frequency_fit.fit_frequency_law`). As the static laws are chosen
(:func:`.selection.select_law`), :func:`choose_model` takes the simplest model whose held-out
error is within ``max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL * best)`` of the best one: a lumped
eddy-current loop (first order) before a distributed one (half order), then the lowest BIC.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .frequency_models import FrequencyModel
from .selection import HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL, finite_or_none

__all__: list[str] = []

_NAMES = ("K", "s_fe", "tau")


@dataclass(frozen=True)
class ModelScore:
    """One model of the core's response fitted to a campaign, with its scores.

    Attributes
    ----------
    model : FirstOrder or HalfOrder
        The model.
    params : (3,) array
        K [N m^2/A^2], s_fe [m], tau [s].
    cov : (3, 3) array
        Their covariance.
    chi2 : float
        The fit's chi-square (weighted residuals).
    dof : int
        Its degrees of freedom.
    n_obs : int
        The harmonic values fitted.
    held_out_steps : (n_steps,) array or None
        The relative error of the force's phasors of every frequency step left out of the
        fit, by frequency; None when there were too few steps to leave one out.
    """

    model: FrequencyModel
    params: np.ndarray
    cov: np.ndarray
    chi2: float
    dof: int
    n_obs: int
    held_out_steps: np.ndarray | None = None

    @property
    def name(self) -> str:
        """The model's name."""
        return self.model.name

    @property
    def held_out(self) -> float | None:
        """RMS over the steps of :attr:`held_out_steps` [-], None without them."""
        if self.held_out_steps is None:
            return None
        return float(np.sqrt(np.mean(np.square(self.held_out_steps))))

    @property
    def aic(self) -> float:
        """``n ln(chi2 / n) + 2 p`` (n harmonic values, p = 3 parameters)."""
        n = self.n_obs
        return n * math.log(max(self.chi2, np.finfo(float).tiny) / n) + 2 * len(_NAMES)

    @property
    def bic(self) -> float:
        """``n ln(chi2 / n) + p ln n``."""
        n = self.n_obs
        return self.aic - 2 * len(_NAMES) + len(_NAMES) * math.log(n)

    def row(self) -> dict[str, Any]:
        """The candidate as the calibration file's ``frequency_law.selection.candidates``
        row: model, formula, parameters, uncertainties and scores (None where not finite)."""
        std = np.sqrt(np.maximum(np.diag(self.cov), 0.0))
        return {
            "model": self.name, "formula": self.model.formula,
            "params": dict(zip(_NAMES, map(float, self.params), strict=True)),
            "stderr": dict(zip(_NAMES, map(float, std), strict=True)),
            "chi2": finite_or_none(self.chi2), "dof": int(self.dof),
            "aic": finite_or_none(self.aic), "bic": finite_or_none(self.bic),
            "held_out": None if self.held_out is None else finite_or_none(self.held_out),
            "held_out_steps": [] if self.held_out_steps is None else
            [finite_or_none(e) for e in self.held_out_steps],
        }


def choose_model(scores: Sequence[ModelScore]) -> tuple[str, str]:
    """The model to keep, and why.

    Parameters
    ----------
    scores : sequence of ModelScore
        At least one.

    Returns
    -------
    name, reason : str
        With held-out errors, the simplest model (fewest parameters, then first order before
        half order) whose held-out error is within ``max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL *
        best)`` of the best, ties to the lowest BIC; without them (fewer than three steps),
        the lowest BIC.
    """
    if any(s.held_out is None for s in scores):
        best = min(scores, key=lambda s: s.bic)
        return best.name, (f"'{best.name}' has the lowest BIC ({best.bic:.1f}); too few "
                           "frequency steps to leave one out")
    errors = {s.name: float(s.held_out or 0.0) for s in scores}
    top = min(scores, key=lambda s: errors[s.name])
    tol = max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL * errors[top.name])
    good = [s for s in scores if errors[s.name] <= errors[top.name] + tol]
    chosen = min(good, key=lambda s: (len(_NAMES), s.model.rank, s.bic))
    return chosen.name, (
        f"'{chosen.name}' is the simplest model of the core whose held-out error "
        f"{100 * errors[chosen.name]:.3f} % is within {100 * tol:.3f} % of the best "
        f"({100 * errors[top.name]:.3f} %, '{top.name}')")


def candidate_rows(scores: Sequence[ModelScore], skipped: Sequence[tuple[str, str]]
                   ) -> tuple[dict[str, Any], ...]:
    """Every model's row (:meth:`ModelScore.row`), then ``{"model", "skipped"}`` for each one
    that could not be fitted."""
    return (*(s.row() for s in scores),
            *({"model": name, "skipped": why} for name, why in skipped))
