"""Fitting one law to the observations: :func:`fit_law` and its result :class:`LawFit`.

Every law is fitted by nonlinear least squares on relative residuals
``(F_model - F) / max(|F|, floor)`` (METHOD.md section 5), the model of the total force being
the law summed over the poles.

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..errors import FitError
from .data import CalibrationData
from .laws import Law

__all__ = ["LawFit", "fit_law"]


def _total(law: Law, params: np.ndarray, data: CalibrationData) -> np.ndarray:
    """Model of the total force, the law summed over the poles.

    Parameters
    ----------
    law : Law
        The law of one pole.
    params : (n_params,) array
        Its parameters.
    data : CalibrationData
        The currents, gaps and fluxes.

    Returns
    -------
    (n_obs,) array [N]
    """
    return law.per_pole(params, data.current, data.gaps, data.flux).sum(axis=1)


def _format_gaps(gaps: np.ndarray) -> str:
    """Gaps [m] as a comma-separated list in mm."""
    return ", ".join(f"{1e3 * g:.3f}" for g in gaps) + " mm"


def check_identifiable(law: Law, data: CalibrationData) -> None:
    """Raise FitError, in one line, when ``data`` cannot identify the parameters of ``law``.

    Checks the flux (flux law), the number of distinct static gaps (``law.needs_gaps``; two
    suffice in principle to separate K from s_fe, but the two are strongly correlated and
    METHOD.md section 5 asks a campaign for at least three) and the number of observations.

    Parameters
    ----------
    law : Law
        The law to fit.
    data : CalibrationData
        The observations.

    Raises
    ------
    FitError
        Saying what is missing.
    """
    if law.needs_flux and data.flux is None:
        raise FitError(f"law '{law.name}' needs the flux through a pole; the campaign has none")
    gaps = data.distinct_static_gaps()
    if gaps.size < law.needs_gaps:
        raise FitError(
            f"law '{law.name}' needs at least {law.needs_gaps} distinct static gaps "
            f"{law.separates}; the campaign has {gaps.size} ({_format_gaps(gaps)})"
        )
    if data.n_obs <= law.n_params:
        raise FitError(
            f"law '{law.name}' has {law.n_params} parameters; the campaign has only "
            f"{data.n_obs} observations"
        )


@dataclass(frozen=True)
class LawFit:
    """The result of fitting one law.

    Attributes
    ----------
    law : Law
        The fitted law.
    params : (n_params,) array
        Fitted parameters, units as ``law.param_units``.
    covariance : (n_params, n_params) array
        Parameter covariance, ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance.
    stderr : (n_params,) array
        Standard uncertainties, the square roots of the covariance diagonal.
    correlation : (n_params, n_params) array [-]
        Parameter correlation matrix.
    residuals : (n_obs,) array [-]
        Relative residuals ``(F_model - F) / max(|F|, floor)``.
    rss : float
        Sum of squares of the fitted (weighted) residuals.
    aic : float
        Gaussian Akaike information criterion, ``n ln(rss/n) + 2 p``.
    bic : float
        Gaussian Bayesian information criterion, ``n ln(rss/n) + p ln n``.
    rms_residual : float [-]
        RMS relative residual.
    n_obs : int
        Number of observations fitted.
    n_poles : int
        Number of poles.
    current_range : (float, float) [A]
        Smallest and largest current fitted.
    gap_range : (float, float) [m]
        Smallest and largest pole gap fitted.
    flux_range : (float, float) [Wb] or None
        Smallest and largest flux fitted, when measured.
    nfev : int
        Number of model evaluations.
    """

    law: Law
    params: np.ndarray
    covariance: np.ndarray
    stderr: np.ndarray
    correlation: np.ndarray
    residuals: np.ndarray
    rss: float
    aic: float
    bic: float
    rms_residual: float
    n_obs: int
    n_poles: int
    current_range: tuple[float, float]
    gap_range: tuple[float, float]
    flux_range: tuple[float, float] | None
    nfev: int

    @property
    def params_dict(self) -> dict[str, float]:
        """Parameters by name."""
        return {n: float(v) for n, v in zip(self.law.param_names, self.params, strict=True)}

    def total(self, data: CalibrationData) -> np.ndarray:
        """The fitted model's total force.

        Parameters
        ----------
        data : CalibrationData
            The currents, gaps and fluxes to evaluate at.

        Returns
        -------
        (n_obs,) array [N]
            The law summed over the poles.

        Raises
        ------
        InputError
            When a gap plus ``s_fe`` is not positive.
        """
        self.law.check_gap_offset(self.params, data.gaps)
        return _total(self.law, self.params, data)


@dataclass(frozen=True)
class _Problem:
    """The least-squares problem of :func:`fit_law`, in the normalised variables
    ``x = params / scale``."""

    law: Law
    data: CalibrationData
    scale: np.ndarray
    weights: np.ndarray

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Weighted residuals (n_obs,) [-]."""
        return (_total(self.law, x * self.scale, self.data) - self.data.force) / self.weights

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Derivatives of :meth:`residual` with respect to ``x``, (n_obs, n_params)."""
        data = self.data
        jac = self.law.jacobian(x * self.scale, data.current, data.gaps, data.flux).sum(axis=1)
        return jac / self.weights[:, None] * self.scale


def _start(
    law: Law, data: CalibrationData, start: np.ndarray | None = None
) -> tuple[_Problem, np.ndarray, np.ndarray, np.ndarray]:
    """The normalised problem, its start point and its bounds.

    ``start`` (parameters in the law's units) replaces the law's guess from the data.

    Returns
    -------
    problem : _Problem
        Residual and Jacobian in normalised variables.
    x0 : (n_params,) array
        Start point, strictly inside the bounds.
    lo, hi : (n_params,) array
        Bounds of the normalised variables.

    Raises
    ------
    FitError
        When the law's start values are not usable.
    """
    p0 = np.asarray(law.guess(data) if start is None else start, dtype=float)
    scale = np.asarray(law.typical(p0, data), dtype=float)
    if not np.all(np.isfinite(p0)) or not np.all(scale > 0):
        raise FitError(f"law '{law.name}': no usable start values from the data ({p0})")
    lo, hi = law.bounds(data)
    lo_x, hi_x = lo / scale, hi / scale
    margin = 1e-6 * np.maximum(np.abs(p0 / scale), 1.0)
    x0 = np.clip(p0 / scale, lo_x + margin, hi_x - margin)
    return _Problem(law=law, data=data, scale=scale, weights=data.weights), x0, lo_x, hi_x


def _solve(problem: _Problem, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> Any:
    """Run ``scipy.optimize.least_squares`` (trust region, analytic Jacobian).

    Returns
    -------
    scipy.optimize.OptimizeResult

    Raises
    ------
    FitError
        When the fit does not converge.
    """
    sol = least_squares(
        problem.residual,
        x0,
        jac=problem.jacobian,
        bounds=(lo, hi),
        method="trf",
        x_scale="jac",
        ftol=1e-14,
        xtol=1e-14,
        gtol=1e-14,
        max_nfev=200 * problem.law.n_params,
    )
    if sol.status <= 0:
        raise FitError(f"law '{problem.law.name}': the fit did not converge ({sol.message})")
    return sol


def _normalised_svd(law: Law, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column norms and SVD of the Jacobian with unit columns, after checking its rank.

    Returns
    -------
    col : (n_params,) array
        Norms of the Jacobian's columns.
    sv : (n_params,) array
        Singular values of ``jac / col``.
    vt : (n_params, n_params) array
        Its right singular vectors.

    Raises
    ------
    FitError
        When a parameter does not act on the residuals, or the parameters cannot be separated.
    """
    col = np.linalg.norm(jac, axis=0)
    if not np.all(col > 0):
        raise FitError(
            f"law '{law.name}': the data do not constrain "
            + ", ".join(n for n, c in zip(law.param_names, col, strict=True) if not c > 0)
        )
    _, sv, vt = np.linalg.svd(jac / col, full_matrices=False)
    if sv[-1] < 1e-10 * sv[0]:
        raise FitError(
            f"law '{law.name}': the data cannot separate its parameters "
            f"(condition number {sv[0] / sv[-1]:.1e})"
        )
    return col, sv, vt


def _law_fit(
    law: Law, data: CalibrationData, params: np.ndarray, cov: np.ndarray, rss: float, nfev: int
) -> LawFit:
    """Assemble the :class:`LawFit` of fitted parameters and their covariance."""
    n, p = data.n_obs, law.n_params
    stderr = np.sqrt(np.diag(cov))
    norm = np.outer(stderr, stderr)
    corr = np.divide(cov, norm, out=np.zeros_like(cov), where=norm > 0)
    np.fill_diagonal(corr, 1.0)
    rel = data.relative_residual(_total(law, params, data))
    log_l = n * math.log(max(rss, np.finfo(float).tiny) / n)
    flux_range = None
    if data.flux is not None:
        flux_range = (float(data.flux.min()), float(data.flux.max()))
    return LawFit(
        law=law,
        params=params,
        covariance=cov,
        stderr=stderr,
        correlation=corr,
        residuals=rel,
        rss=rss,
        aic=log_l + 2 * p,
        bic=log_l + p * math.log(n),
        rms_residual=float(np.sqrt(np.mean(rel**2))),
        n_obs=n,
        n_poles=data.n_poles,
        current_range=(float(data.current.min()), float(data.current.max())),
        gap_range=(float(data.gaps.min()), float(data.gaps.max())),
        flux_range=flux_range,
        nfev=nfev,
    )


def fit_law(law: Law, data: CalibrationData, start: np.ndarray | None = None,
            checked: bool = True) -> LawFit:
    """Fit a law to the total force by nonlinear least squares on relative residuals.

    The residual of observation k is ``(F_model_k - F_k) / w_k`` with ``w_k = max(|F_k|, floor)``
    (or ``sigma_k`` when the data carry uncertainties); the model of the total is the law summed
    over the poles. The fit runs on parameters normalised by their typical magnitude, with
    ``scipy.optimize.least_squares`` (trust region, analytic Jacobian, ``x_scale='jac'``).

    Parameters
    ----------
    law : Law
        The law of one pole.
    data : CalibrationData
        The observations.
    start : (n_params,) array or None
        Start parameters; default the law's guess from the data (a refit after a small change
        of the data starts from the parameters fitted before it).
    checked : bool
        Refuse parameters the data do not determine (:meth:`Law.check_fitted`); a fit to part
        of the data, to predict the rest, is not refused (its prediction is what is judged).

    Returns
    -------
    LawFit
        Parameters, covariance, residuals and information criteria. The covariance is the
        residual one, ``s^2 (J^T J)^-1``, which takes every observation as independent; a
        campaign's calibration replaces it with a propagated one
        (:mod:`forcecal.actuator.propagation`).

    Raises
    ------
    FitError
        When the data cannot identify the law (too few distinct static gaps, no flux for the flux
        law, too few observations, parameters the data cannot separate) or the fit fails.
    """
    check_identifiable(law, data)
    problem, x0, lo, hi = _start(law, data, start)
    sol = _solve(problem, x0, lo, hi)
    params = sol.x * problem.scale
    if checked:
        law.check_fitted(params, data)
    col, sv, vt = _normalised_svd(law, problem.jacobian(sol.x))
    r = problem.residual(sol.x)
    n, p = data.n_obs, law.n_params
    rss = float(r @ r)
    cov_x = (vt.T / sv**2) @ vt / np.outer(col, col) * (rss / (n - p))
    cov = cov_x * np.outer(problem.scale, problem.scale)
    return _law_fit(law, data, params, cov, rss, int(sol.nfev))
