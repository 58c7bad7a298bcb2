"""Choosing a law: held-out validation (:func:`held_out_error`) and :func:`select_law`.

Laws are compared by BIC and by the error of the predicted total on held-out runs, and the
simplest law that predicts held-out runs as well as the best one is chosen (METHOD.md
section 5). :func:`report_text` prints the comparison.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import FitError, InputError
from .data import CalibrationData
from .fitting import LawFit, check_identifiable, fit_law
from .laws import ALL_LAWS, Law
from .prediction import Calibration

__all__ = ["Candidate", "Selection", "held_out_error", "report_text", "select_law"]

N_FOLDS = 5
"""Folds of the k-fold scheme used when the campaign has fewer than three groups."""

HELD_OUT_ABS_TOL = 1.0e-4
"""Absolute held-out error margin (relative force units) for preferring a simpler law."""
HELD_OUT_REL_TOL = 0.10
"""Relative held-out error margin for preferring a simpler law."""


# --------------------------------------------------------------------------------------------
# Held-out validation


@dataclass(frozen=True)
class HeldOutError:
    """RMS relative error of the predicted total on held-out data.

    Attributes
    ----------
    rms : float [-]
        RMS over the held-out groups of ``per_group``.
    labels : (n_groups,) array
        The held-out group labels (run indices), or fold numbers for k-fold.
    per_group : (n_groups,) array [-]
        RMS relative error of the predicted total on each held-out group.
    scheme : str
        ``"leave-one-group-out"`` or ``"k-fold"``.
    """

    rms: float
    labels: np.ndarray
    per_group: np.ndarray
    scheme: str

    def __float__(self) -> float:
        return self.rms


def _held_out_sets(data: CalibrationData) -> tuple[str, np.ndarray, list[np.ndarray]]:
    """The validation scheme, the labels of the held-out sets and their boolean masks.

    Returns
    -------
    scheme : str
        ``"leave-one-group-out"`` with three groups or more, else ``"k-fold"``.
    labels : (n_sets,) array
        Group labels, or fold numbers.
    masks : list of (n_obs,) bool arrays
        The observations of each held-out set.
    """
    group = data.group
    assert group is not None  # set by CalibrationData.__post_init__
    labels = np.unique(group)
    if labels.size >= 3:
        return "leave-one-group-out", labels, [group == g for g in labels]
    k = min(N_FOLDS, data.n_obs)
    return "k-fold", np.arange(k), [np.arange(data.n_obs) % k == j for j in range(k)]


def held_out_error(law: Law, data: CalibrationData) -> HeldOutError:
    """Error of the law's prediction on data left out of the fit.

    With three groups (runs) or more, each group is left out in turn (leave-one-group-out);
    otherwise the observations are split into ``N_FOLDS`` interleaved folds (every
    ``N_FOLDS``-th sample), so that every training set keeps every static gap. For each held-out
    set the law is fitted on the rest and the RMS relative error ``(F_pred - F) / max(|F|,
    floor)`` of the predicted total is taken.

    Parameters
    ----------
    law : Law
        The law to validate.
    data : CalibrationData
        The observations, ``group`` giving the run of each.

    Returns
    -------
    HeldOutError
        Its ``rms`` (also ``float(result)``) is the RMS over the held-out sets [-].

    Raises
    ------
    FitError
        When the law is not identifiable from the data, or from a training set.
    """
    check_identifiable(law, data)
    scheme, labels, masks = _held_out_sets(data)
    errors = np.empty(len(masks))
    for j, (label, test) in enumerate(zip(labels, masks, strict=True)):
        try:
            fit = fit_law(law, data.subset(~test), checked=False)
            held = data.subset(test)
            pred = fit.total(held)
        except (FitError, InputError) as exc:
            raise FitError(f"held-out set {label} ({scheme}): {exc}") from exc
        errors[j] = np.sqrt(np.mean(held.relative_residual(pred) ** 2))
    return HeldOutError(
        rms=float(np.sqrt(np.mean(errors**2))), labels=labels, per_group=errors, scheme=scheme
    )


# --------------------------------------------------------------------------------------------
# Selection


def finite_or_none(x: float) -> float | None:
    """``x`` as a float, or None when it is not finite (JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class Candidate:
    """One fitted law of a selection, with its scores.

    Attributes
    ----------
    fit : LawFit
        The law fitted to the whole campaign.
    held_out : HeldOutError
        Its error on held-out runs.
    """

    fit: LawFit
    held_out: HeldOutError

    @property
    def name(self) -> str:
        """Name of the law."""
        return self.fit.law.name

    @property
    def n_params(self) -> int:
        """Number of parameters of the law."""
        return self.fit.law.n_params

    def row(self) -> dict[str, Any]:
        """The JSON-ready summary of the candidate.

        Returns
        -------
        dict
            Name, formula, parameters, uncertainties and scores (None where not finite).
        """
        law = self.fit.law
        return {
            "law": law.name,
            "formula": law.formula,
            "params": self.fit.params_dict,
            "stderr": {
                n: finite_or_none(v) for n, v in zip(law.param_names, self.fit.stderr, strict=True)
            },
            "aic": finite_or_none(self.fit.aic),
            "bic": finite_or_none(self.fit.bic),
            "held_out": finite_or_none(self.held_out.rms),
            "rms_residual": finite_or_none(self.fit.rms_residual),
        }


@dataclass(frozen=True)
class Selection:
    """The laws fitted to a campaign and the one chosen.

    Attributes
    ----------
    candidates : tuple of Candidate
        Every law that could be fitted and validated, in the order tried.
    skipped : tuple of (str, str)
        ``(law name, reason)`` for every law left out (not identifiable, fit failed).
    chosen : str
        Name of the chosen law.
    reason : str
        Why it was chosen.
    tolerance : float [-]
        Held-out error margin within which a simpler law is preferred.
    """

    candidates: tuple[Candidate, ...]
    skipped: tuple[tuple[str, str], ...]
    chosen: str
    reason: str
    tolerance: float

    @property
    def best(self) -> Candidate:
        """The chosen candidate."""
        return next(c for c in self.candidates if c.name == self.chosen)

    def calibration(self) -> Calibration:
        """The calibration of the chosen law.

        Returns
        -------
        Calibration
            The chosen law's calibration, carrying the table of every candidate (and of the
            laws skipped, with their reason).
        """
        rows = [c.row() for c in self.candidates]
        rows += [{"law": name, "skipped": why} for name, why in self.skipped]
        return Calibration.from_fit(self.best.fit, candidates=tuple(rows))


def _candidates(
    data: CalibrationData, laws: Sequence[Law]
) -> tuple[list[Candidate], list[tuple[str, str]]]:
    """Fit and validate every law; the candidates and the ``(name, reason)`` of those skipped."""
    candidates: list[Candidate] = []
    skipped: list[tuple[str, str]] = []
    for law in laws:
        try:
            fit = fit_law(law, data)
            held = held_out_error(law, data)
        except FitError as exc:
            skipped.append((law.name, str(exc)))
            continue
        candidates.append(Candidate(fit=fit, held_out=held))
    return candidates, skipped


def select_law(data: CalibrationData, laws: Sequence[Law] = ALL_LAWS) -> Selection:
    """Fit every identifiable law and choose the simplest one that predicts held-out runs well.

    Each law is fitted (:func:`fit_law`) and validated (:func:`held_out_error`). The chosen law
    is the one with the fewest parameters whose held-out error is within ``max(HELD_OUT_ABS_TOL,
    HELD_OUT_REL_TOL * best)`` of the best held-out error; ties go to the lowest BIC.

    Parameters
    ----------
    data : CalibrationData
        The observations.
    laws : sequence of Law
        The candidate laws, in the order tried.

    Returns
    -------
    Selection
        Every candidate with its scores, the laws skipped, and the one chosen.

    Raises
    ------
    FitError
        When no law can be fitted; the message gives each law's reason.
    """
    candidates, skipped = _candidates(data, laws)
    if not candidates:
        raise FitError("no actuator law can be fitted: " + "; ".join(why for _, why in skipped))
    best = min(candidates, key=lambda c: c.held_out.rms)
    tol = max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL * best.held_out.rms)
    good = [c for c in candidates if c.held_out.rms <= best.held_out.rms + tol]
    chosen = min(good, key=lambda c: (c.n_params, c.fit.bic))
    reason = (
        f"'{chosen.name}' is the simplest law ({chosen.n_params} parameter"
        f"{'s' if chosen.n_params > 1 else ''}) whose held-out "
        f"error {100 * chosen.held_out.rms:.3f} % is within {100 * tol:.3f} % of the best "
        f"({100 * best.held_out.rms:.3f} %, '{best.name}')"
    )
    return Selection(
        candidates=tuple(candidates),
        skipped=tuple(skipped),
        chosen=chosen.name,
        reason=reason,
        tolerance=tol,
    )


def report_text(selection: Selection, k_ideal: float | None = None) -> str:
    """A plain-text table of the candidates of a selection.

    Parameters
    ----------
    selection : Selection
        The fitted laws and the one chosen.
    k_ideal : float or None [N m^2/A^2]
        The ideal K (:func:`forcecal.actuator.ideal_k`), printed beside the fitted K when given.

    Returns
    -------
    str
        Lines separated by newlines, ending with a newline.
    """
    head = f"{'law':<13} {'n_par':>5} {'rms res %':>10} {'held-out %':>11} {'AIC':>11} {'BIC':>11}"
    lines = ["Actuator law selection", head, "-" * len(head)]
    for c in selection.candidates:
        mark = "  <- chosen" if c.name == selection.chosen else ""
        lines.append(
            f"{c.name:<13} {c.n_params:>5d} {100 * c.fit.rms_residual:>10.4f} "
            f"{100 * c.held_out.rms:>11.4f} {c.fit.aic:>11.1f} {c.fit.bic:>11.1f}{mark}"
        )
    lines.append("")
    for c in selection.candidates:
        law = c.fit.law
        parts = [
            f"{n} = {v:.6g} +/- {e:.2g} {u}"
            for n, v, e, u in zip(
                law.param_names, c.fit.params, c.fit.stderr, law.param_units, strict=True
            )
        ]
        lines.append(f"{c.name}: {law.formula}; " + "; ".join(parts))
    for name, why in selection.skipped:
        lines.append(f"{name}: skipped, {why}")
    if k_ideal is not None:
        lines.append(f"ideal K = mu0 N^2 A / 4 = {k_ideal:.6g} N m^2/A^2")
    lines.append(f"chosen: {selection.reason}")
    return "\n".join(lines) + "\n"
