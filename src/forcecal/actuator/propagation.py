"""Parameter covariance of a fitted law by propagation, not from the residuals (METHOD.md
sections 5 and 7, "the whole uncertainty").

The residual covariance ``s^2 (J^T J)^-1`` of :func:`forcecal.actuator.fit_law` takes every
observation as an independent draw. The samples of a campaign are not: each run's samples are a
Fourier series of a few harmonic phasors (at most ``2 H + 1`` independent values), and some
errors are common to every run (a shared tare record, the scan's shapes, a sensor's scale).
Here the errors are described explicitly:

- *noise columns* (:class:`NoiseColumns`), independent unit sources that move the force, the
  current and the gaps, propagated linearly through the fit (:func:`column_effects`);
- *run scatter* (:func:`run_scatter`), the covariance clustered by run (a sandwich
  estimator), which needs no noise model;
- *systematic effects* (:func:`systematic_effect`), type-B errors applied by +-1 standard
  uncertainty and refitted.

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law, ``n_cols``
noise columns. SI units throughout.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import DimensionError
from .ac_only import ACOnlyLaw
from .data import CalibrationData
from .fitting import fit_law
from .laws import Law

__all__ = ["NoiseColumns", "column_effects", "covariance_of", "run_scatter", "systematic_effect"]


@dataclass(frozen=True)
class NoiseColumns:
    """The observations' errors as independent unit sources.

    The errors are written as a sum of independent unit normal variables ``z_c``: column ``c``
    moves the force, the current and the gaps of every observation together by
    ``(F_c, i_c, s_c)`` per unit of ``z_c``. A column may touch one run (a harmonic of its
    force, of its current, a coordinate of its probes) or every run (the tare's DC, the scan's
    shapes), which is how correlation is expressed.

    Attributes
    ----------
    force : (n_obs, n_cols) array [N]
        Change of each observed total force per unit of each source.
    current : (n_obs, n_cols) array [A] or None
        Change of each observed current (None: the sources do not touch the current).
    gaps : (n_obs, n_poles, n_cols) array [m] or None
        Change of each observed pole gap (None: the sources do not touch the gaps).
    labels : tuple of str
        The budget source of every column (``n_cols`` entries).
    """

    force: np.ndarray
    current: np.ndarray | None = None
    gaps: np.ndarray | None = None
    labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        force = np.asarray(self.force, dtype=float)
        if force.ndim != 2:
            raise DimensionError(f"noise columns: 'force' has shape {force.shape}; "
                                 "expected (n_obs, n_cols)")
        n, m = force.shape
        current = None if self.current is None else np.asarray(self.current, dtype=float)
        gaps = None if self.gaps is None else np.asarray(self.gaps, dtype=float)
        if current is not None and current.shape != (n, m):
            raise DimensionError(f"noise columns: 'current' has shape {current.shape}; "
                                 f"expected ({n}, {m})")
        if gaps is not None and (gaps.ndim != 3 or gaps.shape[0] != n or gaps.shape[2] != m):
            raise DimensionError(f"noise columns: 'gaps' has shape {gaps.shape}; "
                                 f"expected ({n}, n_poles, {m})")
        labels = tuple(self.labels) if self.labels else ("noise",) * m
        if len(labels) != m:
            raise DimensionError(f"noise columns: {len(labels)} labels for {m} columns")
        object.__setattr__(self, "force", force)
        object.__setattr__(self, "current", current)
        object.__setattr__(self, "gaps", gaps)
        object.__setattr__(self, "labels", labels)

    @property
    def n_cols(self) -> int:
        """Number of sources."""
        return int(self.force.shape[1])


def _pointwise_derivatives(law: Law, params: np.ndarray, data: CalibrationData
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives of the pointwise model of the total force (for an AC-only law, of its base
    law) with respect to the current and to every pole's gap, by central differences.

    Returns
    -------
    d_current : (n_obs,) array [N/A]
    d_gaps : (n_obs, n_poles) array [N/m]
    """
    base = law.base if isinstance(law, ACOnlyLaw) else law
    i, s, phi = data.current, data.gaps, data.flux

    def total(ii: np.ndarray, ss: np.ndarray) -> np.ndarray:
        out: np.ndarray = base.per_pole(params, ii, ss, phi).sum(axis=1)
        return out

    h_i = 1e-6 * max(float(np.max(np.abs(i))), 1e-12)
    d_current = (total(i + h_i, s) - total(i - h_i, s)) / (2 * h_i)
    h_s = 1e-6 * float(np.min(s))
    d_gaps = np.empty_like(s)
    for p in range(s.shape[1]):
        step = np.zeros_like(s)
        step[:, p] = h_s
        d_gaps[:, p] = (total(i, s + step) - total(i, s - step)) / (2 * h_s)
    return d_current, d_gaps


def _demean_blocks(a: np.ndarray, block: int) -> np.ndarray:
    """``a`` (n_obs, ...) with the mean of every block of ``block`` rows removed."""
    n = a.shape[0]
    blocks = a.reshape(n // block, block, *a.shape[1:])
    out: np.ndarray = (blocks - blocks.mean(axis=1, keepdims=True)).reshape(a.shape)
    return out


def _gain(law: Law, params: np.ndarray, data: CalibrationData) -> np.ndarray:
    """``-(J^T J)^+ J^T / w``, (n_params, n_obs): the parameters' change per unit change of the
    model minus the force at every observation, for the fitted residuals ``(m - F) / w``."""
    w = data.weights
    jac = law.jacobian(params, data.current, data.gaps, data.flux).sum(axis=1) / w[:, None]
    col = np.linalg.norm(jac, axis=0)
    col = np.where(col > 0, col, 1.0)
    pinv = np.linalg.pinv(jac / col, rcond=1e-12)          # (n_params, n_obs)
    out: np.ndarray = -(pinv / col[:, None]) / w[None, :]
    return out


def column_effects(law: Law, params: np.ndarray, data: CalibrationData,
                   columns: NoiseColumns) -> np.ndarray:
    """The fitted parameters' change per unit of every noise column (linear propagation).

    The fit's linear response to a column is

        d theta_c = -(J^T J)^-1 J^T D_c / w,   D_c = dm/di i_c + sum_p dm/ds_p s_c,p - F_c

    with ``J`` the Jacobian of the fitted residuals ``(m - F) / w``, ``m`` the model of the
    total force and ``w`` the residual's denominator; the parameters' covariance is
    ``sum_c d theta_c d theta_c^T`` (:func:`covariance_of`). For an AC-only law the model and
    the measured force are zero-mean per run, and so is ``D_c``.

    Parameters
    ----------
    law : Law
        The fitted law.
    params : (n_params,) array
        Its fitted parameters.
    data : CalibrationData
        The observations it was fitted to.
    columns : NoiseColumns
        The observations' errors.

    Returns
    -------
    (n_params, n_cols) array
        ``d theta_c`` of every column, in the parameters' units.

    Raises
    ------
    DimensionError
        When the columns do not have one row per observation and one gap per pole.
    """
    n = data.n_obs
    if columns.force.shape[0] != n:
        raise DimensionError(f"noise columns have {columns.force.shape[0]} rows for {n} "
                             "observations")
    if columns.gaps is not None and columns.gaps.shape[1] != data.n_poles:
        raise DimensionError(f"noise columns have {columns.gaps.shape[1]} gaps for "
                             f"{data.n_poles} poles")
    d_current, d_gaps = _pointwise_derivatives(law, params, data)
    moved = -columns.force
    if columns.current is not None:
        moved = moved + d_current[:, None] * columns.current
    if columns.gaps is not None:
        moved = moved + np.einsum("np,npc->nc", d_gaps, columns.gaps)
    if isinstance(law, ACOnlyLaw):
        moved = _demean_blocks(moved, law.block)
    out: np.ndarray = _gain(law, params, data) @ moved
    return out


def covariance_of(effects: np.ndarray) -> np.ndarray:
    """The covariance ``sum_c d theta_c d theta_c^T`` of independent effects.

    Parameters
    ----------
    effects : (n_params, n_effects) array
        Each effect's change of the parameters per standard uncertainty.

    Returns
    -------
    (n_params, n_params) array
    """
    e = np.asarray(effects, dtype=float)
    out: np.ndarray = e @ e.T
    return out


def systematic_effect(law: Law, params: np.ndarray,
                      move: Callable[[float], CalibrationData]) -> np.ndarray:
    """The parameters' change per standard uncertainty of a systematic effect, by refitting.

    A type-B error (a sensor's scale, the static gaps) moves all the data at once, possibly
    nonlinearly: the data are moved by +1 and by -1 standard uncertainty of the effect, the
    law is refitted from the fitted parameters each time, and the central difference is the
    effect's contribution; its outer product is its covariance.

    Parameters
    ----------
    law : Law
        The fitted law.
    params : (n_params,) array
        Its fitted parameters (the refits start there).
    move : callable
        ``move(d)`` is the data with the effect at ``d`` standard uncertainties (``d = +-1``).

    Returns
    -------
    (n_params,) array
        ``(theta(+1) - theta(-1)) / 2``, in the parameters' units.

    Raises
    ------
    FitError
        When a refit fails.
    """
    ends = [fit_law(law, move(d), start=params).params for d in (1.0, -1.0)]
    out: np.ndarray = 0.5 * (ends[0] - ends[1])
    return out


def run_scatter(law: Law, params: np.ndarray, data: CalibrationData) -> np.ndarray | None:
    """The parameters' covariance clustered by group (run): a sandwich estimator.

    Each run's residuals are pushed through the fit, ``d theta_g = -(J^T J)^-1 J_g^T r_g``. It
    needs no noise model but counts a misfit of the law as scatter, and with few runs it is
    itself uncertain.

    Parameters
    ----------
    law : Law
        The fitted law.
    params : (n_params,) array
        Its fitted parameters.
    data : CalibrationData
        The observations it was fitted to; ``group`` gives the run of each.

    Returns
    -------
    (n_params, n_params) array or None
        ``G / (G - 1) sum_g d theta_g d theta_g^T``; None with fewer than two groups.
    """
    group = data.group
    assert group is not None  # set by CalibrationData.__post_init__
    labels = np.unique(group)
    if labels.size < 2:
        return None
    gain = _gain(law, params, data)
    resid = law.per_pole(params, data.current, data.gaps, data.flux).sum(axis=1) - data.force
    per_group = np.column_stack([gain[:, group == g] @ resid[group == g] for g in labels])
    out: np.ndarray = labels.size / (labels.size - 1) * (per_group @ per_group.T)
    return out
