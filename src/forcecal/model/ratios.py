"""A broadband model's operating-shape ratios a_k / a_1 over the band (METHOD.md section 7,
"any drive"): each line's from its coordinates, then smoothed over the lines by a penalised
spline (:func:`smooth_ratios`) or taken from a modal model of the scan
(:mod:`forcecal.model.modal`), as the lines' residuals favour (:func:`choose_ratios`, the
choice kept as a :class:`RatioChoice`), with their standard uncertainties and the directions
of the errors the lines share. Used by :func:`forcecal.model.broadband.build_broadband_model`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..signals.spline_smoother import SplineFamily
from .modal import PLAUSIBLE, ModalFit, identify, ratio_dof
from .ratio_errors import error_directions

__all__: list[str] = []     # used by the broadband model alone (model.broadband)


@dataclass(frozen=True)
class RatioChoice:
    """Where a broadband model's ratios a_k / a_1 come from, and the scores that chose it
    (:func:`choose_ratios`).

    Attributes
    ----------
    source : str
        "spline" (:func:`smooth_ratios`) or "modal" (:mod:`forcecal.model.modal`). A model
        written before the choice was made reads as "spline".
    aic_spline, aic_modal : float
        Each one's Akaike criterion on the lines' own ratios (NaN: not scored; the modal one
        where the stabilisation diagram held no stable pole in the band).
    modes : (n_modes, 4) array
        The modal model's natural frequencies [Hz] and their standard uncertainties, damping
        ratios [1] and theirs (none without a modal model).
    level_noise : float [1]
        The modal model's common level per line, relative (NaN without one).
    """

    source: str = "spline"
    aic_spline: float = float("nan")
    aic_modal: float = float("nan")
    modes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    level_noise: float = float("nan")

    def to_json(self) -> dict[str, Any]:
        """A JSON-able description (NaN written as null)."""
        def num(x: float) -> float | None:
            return None if np.isnan(x) else float(x)
        return {"source": self.source, "aic_spline": num(self.aic_spline),
                "aic_modal": num(self.aic_modal), "modes": self.modes.tolist(),
                "level_noise": num(self.level_noise)}

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> RatioChoice:
        """What :meth:`to_json` wrote."""
        def num(x: float | None) -> float:
            return float("nan") if x is None else float(x)
        return cls(source=str(doc["source"]), aic_spline=num(doc["aic_spline"]),
                   aic_modal=num(doc["aic_modal"]),
                   modes=np.asarray(doc["modes"], float).reshape(-1, 4),
                   level_noise=num(doc["level_noise"]))


def drive_line_ratios(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray,
                       good: np.ndarray) -> tuple[np.ndarray, np.ndarray, RatioChoice,
                                                  tuple[np.ndarray, ...] | None]:
    """:func:`choose_ratios` over the lines that carry the drive, their ratios and standard
    uncertainties interpolated onto every line: a line between the drive's holds the scan's
    noise over a reference without signal, not the structure's response to the drive (on a
    lab scan one such line's spurious first coordinate took the splines' ratio there to 4,
    where the drive's lines read 0.005)."""
    if np.all(good):
        ratios, std, choice, directions = choose_ratios(frequencies, coords, cov)
        return ratios, _holding(std, directions), choice, directions
    ratios, std, choice, directions = choose_ratios(frequencies[good], coords[:, good],
                                                    cov[good])
    at = frequencies[good]

    def onto(rows: np.ndarray) -> np.ndarray:
        return np.array([np.interp(frequencies, at, row) for row in rows]).reshape(
            len(rows), len(frequencies))

    directions = None if directions is None else tuple(onto(d) for d in directions)
    return (onto(ratios.real) + 1j * onto(ratios.imag), _holding(onto(std), directions),
            choice, directions)


def _holding(std: np.ndarray, directions: tuple[np.ndarray, ...] | None) -> np.ndarray:
    """Each ratio's standard uncertainty (n_shapes, n_lines) at least its shared errors' (the
    directions' squares summed at a line), of which it is the whole: the modal ratios'
    variance and the factor's directions are computed apart, and lines between the drive's
    are interpolated, so they can part slightly (docs/method.md, "any drive")."""
    if directions is None:
        return std
    shared = np.array([np.sqrt(np.sum(np.square(d), axis=0)) if len(d) else
                       np.zeros(std.shape[-1]) for d in directions])
    return np.maximum(std, shared)


RANK_FLOOR = 1e-12
"""The modal ratios' covariance over the lines keeps its principal directions down to this
share of its largest variance (below it, rounding)."""

WEIGHT_RANGE = 1e8
"""A line's ratio variance is held within this factor of the lines' median either way before
it weighs the spline: a line whose noise reads zero took the whole fit (its ratio 1e132) and
one of no weight overflowed the penalties tried."""


def smooth_ratios(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The ratios a_k / a_1 smoothed over the lines, and their standard uncertainty.

    Parameters
    ----------
    frequencies : (n_lines,) array [Hz]
    coords : (n_shapes, n_lines) complex array
        Every line's coordinates.
    cov : (n_lines, n_shapes, n_shapes) array
        Their covariance, of Re and of Im each.

    Returns
    -------
    ratios : (n_shapes, n_lines) complex array
        The first row 1.
    std : (n_shapes, n_lines) array
        Of Re and of Im each (the first row 0): the lines' noise through the smoother,
        sum_j S_ij^2 var_j (S the spline's linear map from the lines to its values), and its
        bias as the smoother's own estimate shows it, |(S - I) S r|^2 / 2, in quadrature.

    Every ratio's Re and Im get a cubic smoothing spline (:class:`forcecal.signals.spline_smoother.
    SplineFamily`) weighted by the inverse variance of the line's ratio, to first order
    (var(a_k) + |r|^2 var(a_1) - 2 Re(r) cov(a_k, a_1)) / |a_1|^2, with the roughness penalty
    of least estimated risk (Mallows' C_p; none, or the weighted straight line, where either
    serves best). The largest penalty whose residuals stay within the noise (Morozov's
    discrepancy principle) smoothed too far: on the FE beam's chirp scan the ratios' error at
    10 and 30 Hz was 3-5 times their stated uncertainty, a bias the same in every draw of the
    scan's noise, and what that noise moved the total force by 2.1 times its statement.
    """
    out, std, _, _, _ = _spline_ratios(frequencies, coords, cov)
    return out, std


def _line_ratios(coords: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every line's own ratios a_k / a_1 (n_shapes, n_lines), the first row 1, and the
    variance of Re and of Im of each to first order, (var(a_k) + |r|^2 var(a_1) - 2 Re(r)
    cov(a_k, a_1)) / |a_1|^2, held within :data:`WEIGHT_RANGE` of its median where five or more
    lines are smoothed (the first row 1)."""
    tiny = np.finfo(float).tiny
    first = np.where(np.abs(coords[0]) > tiny, coords[0], tiny)
    ratios = coords / first
    var = np.ones(ratios.shape)
    for k in range(1, coords.shape[0]):
        r = ratios[k]
        v = np.maximum((cov[:, k, k] + np.abs(r) ** 2 * cov[:, 0, 0]
                        - 2.0 * r.real * cov[:, k, 0]) / np.abs(first) ** 2, tiny)
        typical = float(np.median(v))        # a line "without noise", or without signal,
        var[k] = (np.clip(v, typical / WEIGHT_RANGE, WEIGHT_RANGE * typical)  # no outlier
                  if r.size >= 5 else v)
    return ratios, var


def _spline_ratios(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, tuple[np.ndarray, ...]]:
    """:func:`smooth_ratios`, with the lines' own ratios' variances (:func:`_line_ratios`),
    the splines' degrees of freedom, sum_k 2 tr S_k (Re and Im), and each ratio's error
    directions over the lines (:func:`~forcecal.model.ratio_errors.error_directions` of
    S_k diag(var_k) S_k^T: the lines' noise through the smoother, which every line's ratio
    shares with its neighbours)."""
    ratios, var = _line_ratios(coords, cov)
    out, std = np.ones_like(ratios), np.zeros(ratios.shape)
    dof = 0.0
    directions = [np.zeros((0, ratios.shape[1]))]
    for k in range(1, coords.shape[0]):
        r = ratios[k]
        if r.size < 5:                        # too few lines to smooth
            out[k], std[k] = r, np.sqrt(var[k])
            dof += 2.0 * r.size
            directions.append(np.zeros((0, r.size)))
            continue
        family = SplineFamily.over(frequencies, 1.0 / var[k])
        smoother = family.matrix(family.least_risk(r))
        out[k] = smoother @ r
        bias = smoother @ out[k] - out[k]     # the smoother's bias on its own estimate
        std[k] = np.sqrt(smoother**2 @ var[k] + np.abs(bias) ** 2 / 2.0)
        dof += 2.0 * float(np.trace(smoother))
        directions.append(error_directions((smoother * var[k]) @ smoother.T))
    return out, std, var, dof, tuple(directions)


def choose_ratios(frequencies: np.ndarray, coords: np.ndarray, cov: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, RatioChoice, tuple[np.ndarray, ...] | None]:
    """The ratios a_k / a_1 at the lines and their standard uncertainty (of Re and of Im
    each), from the splines (:func:`smooth_ratios`) or from the modal model of the
    coordinates (:func:`forcecal.model.modal.identify`) where its Akaike criterion on the lines'
    own ratios leaves the splines' implausible (their weight exp(-dAIC / 2) below
    :data:`forcecal.model.modal.PLAUSIBLE` of its own), and the record of the choice.

    Both are estimators of the lines' own ratios r_kl (:func:`_line_ratios`), of known variance
    v_kl: AIC = sum_kl |r_kl - fitted_kl|^2 / v_kl + 2 dof (with the variances known, Mallows'
    C_p, the risk the splines' penalty is chosen by), dof the trace of each one's map from the
    lines' ratios to its own (the splines' 2 tr S; the modal model's linearized,
    :func:`forcecal.model.modal.ratio_dof`). The level of each line is no evidence: the
    coordinates share the drive's own distortion on the reference's lines (the modal model
    takes it as a common level, its ratios do not see it). Without a stable pole in the band,
    or with one shape, the splines' are kept.

    Parameters
    ----------
    frequencies : (n_lines,) array [Hz]
    coords : (n_shapes, n_lines) complex array
    cov : (n_lines, n_shapes, n_shapes) array
        The coordinates' covariance, of Re and of Im each.

    Returns
    -------
    ratios, std, choice
        As the module's model keeps them.
    directions : tuple of (n_dirs, n_lines) arrays, or None
        The ratios' error directions per shape: the splines' (:func:`_spline_ratios`), or the
        modal model's, whose few parameters move every line at once
        (:meth:`~forcecal.model.modal.ModalFit.ratio_errors`).
    """
    spline, spline_std, var, spline_dof, directions = _spline_ratios(frequencies, coords, cov)
    if coords.shape[0] < 2:
        return spline, spline_std, RatioChoice(), directions
    own = coords / np.where(coords[0] != 0, coords[0], np.finfo(float).tiny)

    def aic(fitted: np.ndarray, dof: float) -> float:
        return float(np.sum(np.abs(own[1:] - fitted[1:]) ** 2 / var[1:]) + 2.0 * dof)

    aic_spline = aic(spline, spline_dof)
    fit = identify(frequencies, coords, cov)
    if fit is None:
        return spline, spline_std, RatioChoice(aic_spline=aic_spline), directions
    modal, modal_std = fit.ratios(frequencies)
    aic_modal = aic(modal, ratio_dof(fit, frequencies, coords, cov))
    # the splines stay unless the modal model makes them implausible (their Akaike weight
    # below PLAUSIBLE of its own): on the FE beam's chirp scan the two scored within 3, and
    # the modal ratios' statement was the more cautious
    better = aic_spline - aic_modal > 2.0 * np.log(1.0 / PLAUSIBLE)
    chosen = RatioChoice(source="modal" if better else "spline",
                         aic_spline=aic_spline, aic_modal=aic_modal, modes=_modes(fit),
                         level_noise=fit.level_noise)
    if chosen.source == "modal":
        return modal, modal_std, chosen, (np.zeros((0, len(frequencies))), *(
            _factor_directions(f) for f in fit.ratio_errors(frequencies)[1:]))
    return spline, spline_std, chosen, directions


def _factor_directions(factor: np.ndarray) -> np.ndarray:
    """(n_dirs, n_lines): the principal directions of the covariance A A^T of a factor A
    (n_lines, k), each scaled by its standard deviation, down to :data:`RANK_FLOOR` of the
    strongest: all of its rank (the modal ratios' far lines, of large variance, would leave
    the mode's lines out of a share of the trace)."""
    u, sv, _ = np.linalg.svd(factor, full_matrices=False)
    keep = sv > np.sqrt(RANK_FLOOR) * float(np.max(sv, initial=0.0))
    out: np.ndarray = (u[:, keep] * sv[keep]).T
    return out


def _modes(fit: ModalFit) -> np.ndarray:
    """(n_modes, 4): the fit's natural frequencies [Hz], their standard uncertainties, its
    damping ratios and theirs."""
    f_std, z_std = fit.mode_std()
    return np.column_stack([fit.frequencies, f_std, fit.damping, z_std])
