"""The uncertainty of a campaign's calibration parameters: :func:`parameter_uncertainty`
(METHOD.md sections 5 and 7, "the whole uncertainty").

The law is fitted to the runs' calibration samples (:mod:`forcecal.campaign.calibrate`), but
the samples of one run are not independent observations: they are a Fourier series of the
run's force, current and pole-displacement phasors, and some errors are common to every run.
The parameters' covariance is therefore not the fit's residual one, ``s^2 (J^T J)^-1``, but
propagated from the errors of the phasors (:mod:`forcecal.actuator.propagation`): a
statistical part from every run's noise (:func:`noise_columns`) and a type-B part from the
rig's systematic errors, each refitted; the residual covariance and the run-clustered
sandwich are kept beside. :func:`parameter_uncertainty` tells how.

Shapes: ``n_params`` parameters of the law, ``n_obs`` pooled samples. SI units throughout.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..actuator import CalibrationData, LawFit
from ..actuator.propagation import (
    NoiseColumns,
    column_effects,
    covariance_of,
    run_scatter,
    systematic_effect,
)
from ..forces.budget import SOURCES as FORCE_TYPE_B_SOURCES
from ..rig import Rig, TypeB
from .noise import SharedEffect

if TYPE_CHECKING:
    from .runs import RunResult

__all__ = ["COVERAGE_FACTOR", "TYPE_B_SOURCES", "noise_columns", "parameter_uncertainty"]

COVERAGE_FACTOR = 2.0
"""k of the expanded uncertainties (about 95 % for a normal distribution)."""

STATISTICAL_SOURCES = ("gauge noise", "probe noise", "unresolved harmonics", "current noise",
                       "tare record", "scan shapes")
"""The statistical budget's sources, in the order reported."""

TYPE_B_SOURCES = ("current scale", "static gaps", *FORCE_TYPE_B_SOURCES)
"""The type-B budget's sources, in the order reported."""

METHOD = (
    "statistical: the noise of every run's force, current and pole-displacement phasors "
    "(and of the shared tare record and scan shapes, common to the runs that used them) "
    "propagated through the fit's Jacobian, d theta = -(J^T J)^-1 J^T D / w per independent "
    "source; the samples of one run are a Fourier series of those phasors, not independent "
    "observations. type B: current scale, static gaps (all together) and every type-B "
    "parameter of the force estimate applied to all runs at once by +-1 standard uncertainty, "
    "the law refitted, central differences. Variances add; expanded = k u with k = 2."
)
"""What ``calibration.json`` says of the method."""


@dataclass(frozen=True)
class ParameterUncertainty:
    """The uncertainty of a calibration's parameters, with its budget.

    Attributes
    ----------
    param_names : tuple of str
        The law's parameters.
    statistical : (n_params, n_params) array
        Covariance from the noise (sum of the statistical sources).
    type_b : (n_params, n_params) array
        Covariance from the type-B (systematic) sources.
    budget : dict str -> (n_params,) array
        Every source's standard uncertainty of each parameter (its covariance's diagonal
        root), in the order of :data:`STATISTICAL_SOURCES` then :data:`TYPE_B_SOURCES`, only
        the sources present.
    residual : (n_params, n_params) array
        The fit's residual covariance ``s^2 (J^T J)^-1`` (every sample taken as independent).
    run_scatter : (n_params, n_params) array or None
        The covariance clustered by run (None with fewer than two runs).
    n_runs : int
        Runs of the campaign.
    type_b_used : TypeB
        The rig's type-B standard uncertainties used.
    propagated : bool
        False when some run has no noise description: the statistical part is then the
        residual covariance.
    coverage_factor : float
        k of the expanded uncertainties.
    """

    param_names: tuple[str, ...]
    statistical: np.ndarray
    type_b: np.ndarray
    budget: dict[str, np.ndarray]
    residual: np.ndarray
    run_scatter: np.ndarray | None
    n_runs: int
    type_b_used: TypeB
    propagated: bool = True
    coverage_factor: float = COVERAGE_FACTOR
    kinds: dict[str, str] = field(default_factory=dict)

    @property
    def covariance(self) -> np.ndarray:
        """The combined covariance, statistical plus type B."""
        out: np.ndarray = self.statistical + self.type_b
        return out

    @property
    def stderr(self) -> np.ndarray:
        """Combined standard uncertainties (n_params,)."""
        return _std(self.covariance)

    @property
    def expanded(self) -> np.ndarray:
        """Expanded uncertainties ``k u`` (n_params,)."""
        out: np.ndarray = self.coverage_factor * self.stderr
        return out

    @property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the combined covariance (n_params, n_params) [-]."""
        return _correlation(self.covariance)

    def to_json(self, n_poles: int | None = None) -> dict[str, Any]:
        """The ``uncertainty`` block of ``calibration.json``.

        Parameters
        ----------
        n_poles : int or None
            With it, ``K`` is also given as ``K_total = n_poles K``.

        Returns
        -------
        dict
            JSON-ready.
        """
        def named(values: np.ndarray, factor: dict[str, float] | None = None) -> dict[str, float]:
            f = factor or {}
            return {n: float(v) * f.get(n, 1.0) for n, v in zip(self.param_names, values,
                                                                 strict=True)}

        doc: dict[str, Any] = {
            "method": METHOD if self.propagated else (
                "residual covariance (some run has no noise description); type B as "
                "documented"),
            "coverage_factor": self.coverage_factor,
            "param_names": list(self.param_names),
            "stderr": named(self.stderr),
            "expanded": named(self.expanded),
            "correlation": self.correlation.tolist(),
            "statistical": {"stderr": named(_std(self.statistical)),
                            "covariance": self.statistical.tolist()},
            "type_b": {"stderr": named(_std(self.type_b)),
                       "covariance": self.type_b.tolist(),
                       "declared": self.type_b_used.declared,
                       "standard_uncertainties": {k: getattr(self.type_b_used, k)
                                                  for k in TypeB.KEYS}},
            "budget": {src: {"kind": self.kinds.get(src, ""), **named(std)}
                       for src, std in self.budget.items()},
            "residual_stderr": named(_std(self.residual)),
            "run_scatter_stderr": None if self.run_scatter is None else named(
                _std(self.run_scatter)),
            "n_runs": self.n_runs,
        }
        if n_poles is not None and "K" in self.param_names:
            k = self.param_names.index("K")
            doc["k_total"] = {
                "stderr": n_poles * float(self.stderr[k]),
                "expanded": n_poles * float(self.expanded[k]),
                "statistical": n_poles * float(_std(self.statistical)[k]),
                "type_b": n_poles * float(_std(self.type_b)[k]),
                "budget": {src: n_poles * float(std[k]) for src, std in self.budget.items()},
            }
        return doc


def _std(cov: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return out


def _correlation(cov: np.ndarray) -> np.ndarray:
    std = _std(cov)
    norm = np.outer(std, std)
    corr = np.divide(cov, norm, out=np.zeros_like(cov), where=norm > 0)
    np.fill_diagonal(corr, 1.0)
    out: np.ndarray = corr
    return out


# --------------------------------------------------------------------------------------------
# Noise columns


class _Columns:
    """Noise columns under construction: dense (n_obs, ...) arrays, one per column."""

    def __init__(self, n_obs: int, n_poles: int) -> None:
        self.n_obs, self.n_poles = n_obs, n_poles
        self.force: list[np.ndarray] = []
        self.current: list[np.ndarray] = []
        self.gaps: list[np.ndarray] = []
        self.labels: list[str] = []
        self.shared: dict[tuple[Any, ...], int] = {}

    def column(self, label: str, key: tuple[Any, ...] | None = None) -> int:
        """A new column (or the shared one called ``key``); its index."""
        if key is not None and key in self.shared:
            return self.shared[key]
        self.force.append(np.zeros(self.n_obs))
        self.current.append(np.zeros(self.n_obs))
        self.gaps.append(np.zeros((self.n_obs, self.n_poles)))
        self.labels.append(label)
        if key is not None:
            self.shared[key] = len(self.labels) - 1
        return len(self.labels) - 1

    def build(self) -> NoiseColumns:
        if not self.labels:
            return NoiseColumns(force=np.zeros((self.n_obs, 0)), labels=())
        return NoiseColumns(force=np.column_stack(self.force),
                            current=np.column_stack(self.current),
                            gaps=np.stack(self.gaps, axis=2), labels=tuple(self.labels))


def _basis(f0: float, t: np.ndarray, h: int) -> np.ndarray:
    """``exp(j n w0 t)`` (H+1, n_t): the sample of a unit phasor X is Re(X basis[n])."""
    n = np.arange(h + 1)
    cycles = np.mod(np.multiply.outer(n * f0, np.asarray(t, dtype=float)), 1.0)
    out: np.ndarray = np.exp(2j * np.pi * cycles)
    return out


def _effect_series(effect: SharedEffect, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A run's force samples (n_t,) [N] and gaps (n_t, n_poles) [m] moved by an effect."""
    return np.real(effect.total @ basis), -np.real(effect.motion @ basis).T


def _units(n: int) -> tuple[complex, ...]:
    """The phasor components of harmonic n: the DC is real, the others have Re and Im."""
    return (1.0,) if n == 0 else (1.0, 1j)


def noise_columns(results: Sequence[RunResult], n_poles: int) -> NoiseColumns:
    """The noise columns of a campaign's pooled samples (in the order of ``results``).

    Parameters
    ----------
    results : sequence of RunResult
        The runs, each with its noise description (``samples.noise``).
    n_poles : int
        Poles of the actuator.

    Returns
    -------
    NoiseColumns
        Labelled by :data:`STATISTICAL_SOURCES`.
    """
    cols = _Columns(sum(r.samples.n for r in results), n_poles)
    start = 0
    for r in results:
        nz, smp = r.samples.noise, r.samples
        rows = slice(start, start + smp.n)
        start += smp.n
        if nz is None:
            continue
        h = len(nz.current_std) - 1
        e = _basis(r.estimate.f0, smp.time, h)
        for label, std in (*nz.force_std.items(), ("current noise", nz.current_std)):
            for n in np.flatnonzero(std > 0):
                for u in _units(int(n)):
                    c = cols.column(label)
                    values = std[n] * np.real(u * e[n])
                    (cols.current if label == "current noise" else cols.force)[c][rows] = values
        for cn in nz.coordinates:
            vals, vecs = np.linalg.eigh(cn.cov)
            for lam, vec in zip(vals, vecs.T, strict=True):
                for u in _units(cn.harmonic):
                    dq = u * np.sqrt(max(lam, 0.0)) * vec
                    c = cols.column("probe noise")
                    cols.force[c][rows] = np.real((cn.force @ dq) * e[cn.harmonic])
                    cols.gaps[c][rows] = -np.real(np.outer(e[cn.harmonic], cn.motion @ dq))
        if nz.dc_std > 0:
            cols.gaps[cols.column("probe noise")][rows] = -nz.dc_shape * nz.dc_std
        for eff in nz.shared:
            c = cols.column(eff.source, ("shared", eff.name))
            cols.force[c][rows], cols.gaps[c][rows] = _effect_series(eff, e)
    return cols.build()


# --------------------------------------------------------------------------------------------
# Systematic effects


def _series_effects(results: Sequence[RunResult]
                    ) -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """Every type-B parameter of the force estimates: its source and its change of the pooled
    force samples (n_obs,) [N] and gaps (n_obs, n_poles) [m] per standard uncertainty."""
    n_obs = sum(r.samples.n for r in results)
    n_poles = results[0].samples.gaps.shape[1]
    out: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    start = 0
    for r in results:
        smp = r.samples
        rows = slice(start, start + smp.n)
        start += smp.n
        if smp.noise is None:
            continue
        for eff in smp.noise.type_b:
            if eff.name not in out:
                out[eff.name] = (eff.source, np.zeros(n_obs), np.zeros((n_obs, n_poles)))
            e = _basis(r.estimate.f0, smp.time, len(eff.total) - 1)
            out[eff.name][1][rows], out[eff.name][2][rows] = _effect_series(eff, e)
    return out


def _moves(data: CalibrationData, results: Sequence[RunResult], type_b: TypeB
           ) -> list[tuple[str, Callable[[float], CalibrationData]]]:
    """``(source, move)`` of every systematic effect with a non-zero standard uncertainty;
    ``move(d)`` is the data with the effect at ``d`` standard uncertainties."""
    moves: list[tuple[str, Callable[[float], CalibrationData]]] = []
    if type_b.current_scale > 0:
        moves.append(("current scale", lambda d: dataclasses.replace(
            data, current=data.current * (1.0 + d * type_b.current_scale))))
    if type_b.gap > 0:
        moves.append(("static gaps", lambda d: dataclasses.replace(
            data, gaps=data.gaps + d * type_b.gap, static_gap=data.static_gap + d * type_b.gap)))
    for source, force, gaps in _series_effects(results).values():
        def move(d: float, force: np.ndarray = force, gaps: np.ndarray = gaps
                 ) -> CalibrationData:
            return dataclasses.replace(data, force=data.force + d * force,
                                       gaps=data.gaps + d * gaps)
        moves.append((source, move))
    return moves


# --------------------------------------------------------------------------------------------
# The parameters' uncertainty


def parameter_uncertainty(fit: LawFit, data: CalibrationData, results: Sequence[RunResult],
                          rig: Rig, columns: NoiseColumns | None = None
                          ) -> ParameterUncertainty:
    """The statistical and type-B covariance of a campaign's fitted parameters, with budget.

    Parameters
    ----------
    fit : LawFit
        The law fitted to ``data``.
    data : CalibrationData
        The pooled samples of ``results``, in their order (:func:`forcecal.campaign.
        calibration_data`).
    results : sequence of RunResult
        The runs, with their noise descriptions.
    rig : Rig
        Its ``type_b`` gives the current scale's and the static gaps' standard uncertainties.
    columns : NoiseColumns or None
        :func:`noise_columns` of ``results``, when already built.

    Returns
    -------
    ParameterUncertainty

    Raises
    ------
    FitError
        When a refit of a type-B effect fails.

    Notes
    -----
    *Statistical part* (noise; what a repeated campaign would scatter by). Every error of a run
    (:class:`forcecal.campaign.noise.RunNoise`) becomes one or more *noise columns*, each
    moving that run's samples as the Fourier series of a unit change of one phasor component
    (Re or Im of one harmonic of the force, of the current, of a coordinate of the probes, the
    DC of the quasi-static deflection) times its standard uncertainty. Errors shared by runs
    are columns that move every such run at once: the tare record's gauge and probe means
    (every run that subtracted that tare) and the scan's shapes (a common complex fraction of
    every run's inertia phasor at each harmonic). The parameters move by
    ``d theta_c = -(J^T J)^-1 J^T D_c / w`` per column (``D_c`` the column's change of the
    model minus the force, linearized), and the statistical covariance is
    ``sum_c d theta_c d theta_c^T``, grouped by source for the budget.

    *Type-B part* (systematic; the same in every run of the campaign, so never averaged down by
    the number of runs). Each effect is applied to every run at once by +-1 standard
    uncertainty, the law refitted from the fitted parameters, and the central difference
    taken: the current sensor's scale (``rig.type_b.current_scale``, relative), every static
    gap shifted together (``rig.type_b.gap``), and each of the force estimate's type-B
    parameters (each gauge's and each probe's sensitivity, every position, every mass:
    :func:`forcecal.forces.budget.parameters`) as its signed change of every run's force and
    pole displacement. Their covariances add to the statistical one (the effects are
    independent); the budget groups them by source.

    Beside them: the residual covariance (as if every sample were independent; what a fit of
    the pooled samples reports) and the run-clustered sandwich
    ``sum_runs (d theta_r)(d theta_r)^T`` with ``d theta_r`` each run's residuals pushed
    through the fit (it also sees a misfit of the law, which no repetition of the campaign
    would average out).
    """
    law, params = fit.law, fit.params
    p = law.n_params
    budget: dict[str, np.ndarray] = {}
    kinds: dict[str, str] = {}
    propagated = all(r.samples.noise is not None for r in results)
    statistical = np.zeros((p, p))
    if propagated:
        if columns is None:
            columns = noise_columns(results, data.n_poles)
        effects = column_effects(law, params, data, columns)
        labels = np.array(columns.labels)
        for source in STATISTICAL_SOURCES:
            chosen = labels == source
            if np.any(chosen):
                cov = covariance_of(effects[:, chosen])
                statistical += cov
                budget[source], kinds[source] = _std(cov), "statistical"
    else:
        statistical = fit.covariance.copy()
        budget["residual"], kinds["residual"] = _std(statistical), "statistical"
    type_b = np.zeros((p, p))
    by_source: dict[str, np.ndarray] = {}
    for source, move in _moves(data, results, rig.type_b):
        cov = covariance_of(systematic_effect(law, params, move)[:, None])
        by_source[source] = by_source.get(source, np.zeros((p, p))) + cov
    for source in TYPE_B_SOURCES:
        if source in by_source:
            type_b += by_source[source]
            budget[source], kinds[source] = _std(by_source[source]), "type B"
    return ParameterUncertainty(
        param_names=law.param_names,
        statistical=statistical,
        type_b=type_b,
        budget=budget,
        residual=fit.covariance.copy(),
        run_scatter=run_scatter(law, params, data),
        n_runs=len(results),
        type_b_used=rig.type_b,
        propagated=propagated,
        kinds=kinds,
    )
