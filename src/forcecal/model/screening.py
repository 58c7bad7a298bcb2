"""A robust scan: every record judged against its neighbours and the fitted shape (METHOD.md
section 7, "A robust scan").

A scan record is evidence about the shape at its point only if it agrees with its neighbours.
Three things go wrong on real rigs, and each is handled here before the shapes are kept:

- **Weights.** A record's weight is its inverse noise variance, and a laser dropout (a record
  near zero) has almost no noise: left alone it would pull the shape through itself. Every
  record's noise std is floored at ``NOISE_FLOOR`` times the median over the scan
  (:func:`record_weights`), per harmonic and per record, never pooled.
- **Records that cannot be used at all**: a reference that shows no drive, a response that is
  clipped or not finite, set aside with their reason before any fit (:func:`unusable_records`).
- **Records that contradict the shape**: after a fit, a record whose leave-one-out residual
  exceeds ``OUTLIER`` robust scales in a harmonic the scan resolves, and which misses the
  shape by ``MIN_RELATIVE`` of its RMS amplitude, is set aside, the worst first, and the
  shapes are refit (:func:`screen_records`); at most ``MAX_SET_ASIDE`` of the records go.

Every record set aside is listed with its reason: on the terminal, in the model's JSON and on
the report's shape figure.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..records import Scan
from ..signals.checks import check_clipping
from .basis import ShapeFit
from .vector_basis import VectorShapeFit

__all__: list[str] = []

NOISE_FLOOR = 0.3
"""A record's noise std is taken as at least this fraction of the scan's median."""
OUTLIER = 8.0
"""Leave-one-out residual, in robust scales, beyond which a record contradicts the shape...
For Gaussian noise a residual's modulus is Rayleigh distributed: P(> 8 scales) ~ 1e-14 per
record, so a clean scan loses nothing."""
MIN_RELATIVE = 0.2
"""...and by more than this fraction of the shape's RMS amplitude over the records: a clean
scan's polynomial shapes miss a record by a few % of it where the shape bends sharply, a
dropout by about 100 %."""
MAX_SET_ASIDE = 0.2
"""Largest fraction of the records that may be set aside."""
MODEL_ERROR_SHARE = 0.05
"""When more than this fraction of the records (and more than 3) contradict the shapes one
after another, the basis misses the shape (model error, e.g. a mode-shape basis on a plate),
not a few bad records: none is set aside for it, and a note says so."""
_RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))
"""Median of a Rayleigh variable of unit scale: |Re + j Im| with Re, Im ~ N(0, 1)."""

Fit = ShapeFit | VectorShapeFit


@dataclass(frozen=True)
class Screening:
    """What the screening kept and set aside.

    Attributes
    ----------
    keep : (n_records,) bool ndarray
        Records used for the shapes.
    reasons : dict
        Record index (0-based) -> why it was set aside.
    note : str
        Why no record was set aside for contradicting the shapes, when many did ("" else).
    """

    keep: np.ndarray
    reasons: dict[int, str]
    note: str = ""


def record_weights(std: np.ndarray) -> np.ndarray:
    """Relative weights 1 / std^2 of the records, each std floored at ``NOISE_FLOOR`` times
    the median, scaled to mean 1 (equal weights for noise-free data). Per harmonic and per
    record, never pooled, so that one spiky record does not lower the others' weights.

    Parameters
    ----------
    std : (n_records,) ndarray
        [m] each record's standard uncertainty at one harmonic.

    Returns
    -------
    (n_records,) ndarray
    """
    s = np.asarray(std, dtype=float)
    floor = NOISE_FLOOR * float(np.median(s)) if s.size else 0.0
    if floor <= 0:
        return np.ones_like(s)
    w = 1.0 / np.maximum(s, floor) ** 2
    weights: np.ndarray = w / w.mean()
    return weights


def unusable_records(scan: Scan, reference_ok: np.ndarray) -> dict[int, str]:
    """Records set aside before any fit: no drive in the reference, a clipped or non-finite
    response.

    Parameters
    ----------
    scan : Scan
    reference_ok : (n_records,) bool ndarray
        Whether each record's reference shows the drive.

    Returns
    -------
    dict
        Record index -> reason.
    """
    reasons: dict[int, str] = {}
    for weak in np.flatnonzero(~np.asarray(reference_ok)):
        reasons[int(weak)] = "its reference shows no drive (the record's phase is unknown)"
    for k, rec in enumerate(scan.response):
        if k in reasons:
            continue
        if not np.all(np.isfinite(rec)):
            reasons[k] = "its response holds non-finite samples"
            continue
        try:
            check_clipping(rec, "response", scan.source, scan.fs)
        except DataError:
            reasons[k] = "its response is clipped (saturated)"
    return reasons


def loo_scores(fit: Fit, points: np.ndarray, values: np.ndarray,
               weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out residuals of a fit in robust scales and relative to the shape.

    Parameters
    ----------
    fit : ShapeFit or VectorShapeFit
        Fitted over ``points`` with ``weights``.
    points : ndarray
        Structure coordinates of the records.
    values : (n_records,) complex ndarray
        The measured values.
    weights : (n_records,) ndarray
        The fit's weights.

    Returns
    -------
    scores : (n_records,) ndarray
        |r_k| sqrt(w_k) / sqrt(1 - h_kk), divided by its median over the Rayleigh median.
    relative : (n_records,) ndarray
        |r_k| / sqrt(1 - h_kk) over the RMS of the measured values.
    """
    b = fit.fitted_basis.evaluate(points)                       # (n, p)
    gram = b.T @ (weights[:, None] * b)
    hat = weights * np.einsum("kp,pq,kq->k", b, np.linalg.pinv(gram), b)
    leave_out = np.abs(values - fit.evaluate(points)) / np.sqrt(np.clip(1.0 - hat, 1e-6, None))
    loo = leave_out * np.sqrt(weights)
    rms = float(np.sqrt(np.mean(np.abs(values) ** 2)))
    relative = leave_out / rms if rms > 0 else np.zeros_like(leave_out)
    scale = float(np.median(loo)) / _RAYLEIGH_MEDIAN
    scores = loo / scale if scale > 0 else np.zeros_like(loo)
    return scores, relative


def screen_records(points: np.ndarray, values: np.ndarray, std: np.ndarray,
                   resolved: Sequence[tuple[int, int]],
                   fit: Callable[[np.ndarray, np.ndarray, int], Fit],
                   reasons: dict[int, str]) -> Screening:
    """Set aside, one at a time, the records that contradict the fitted shapes.

    After a fit, every record's leave-one-out residual (the residual divided by
    sqrt(1 - h_kk), h the fit's hat matrix, so that a record cannot hide by pulling the fit
    through itself) is compared with the robust scale of all of them (their median over the
    Rayleigh median); a record beyond ``OUTLIER`` such scales in a harmonic the scan resolves,
    which also misses the shape by ``MIN_RELATIVE`` of its RMS amplitude, is set aside, the
    worst first, and the shapes are refit. At most ``MAX_SET_ASIDE`` of the records go, so that
    a scan that is wrong everywhere is not quietly thinned out.

    Parameters
    ----------
    points : ndarray
        Structure coordinates of every record.
    values : (n_harm, n_records) complex ndarray
        [m] the measured harmonic shapes.
    std : (n_harm, n_records) ndarray
        [m] their standard uncertainties.
    resolved : sequence of (int, int)
        (row of ``values``, harmonic number) of every harmonic the scan resolves.
    fit : callable
        ``fit(selection, weights, row)`` fits harmonic row ``row`` over the records
        ``selection`` (an index array) with those weights.
    reasons : dict
        Records already set aside (:func:`unusable_records`), extended here.

    Returns
    -------
    Screening
    """
    reasons = dict(reasons)
    n = values.shape[1]
    budget = int(MAX_SET_ASIDE * n)
    keep = np.ones(n, dtype=bool)
    keep[list(reasons)] = False
    given = dict(reasons)
    limit = max(3, int(MODEL_ERROR_SHARE * n))
    while len(reasons) < budget:
        if len(reasons) - len(given) > limit:
            keep = np.ones(n, dtype=bool)
            keep[list(given)] = False
            return Screening(keep=keep, reasons=given, note=(
                f"more than {limit} of {n} records miss the fitted shapes by more than "
                f"{OUTLIER:g} robust scales and {MIN_RELATIVE:.0%} of their amplitude, one "
                "after another: the basis cannot follow the shape (model error, not bad "
                "records); none is set aside for it (try the polynomial basis)"))
        idx = np.flatnonzero(keep)
        worst, where, score, share = -1, -1, OUTLIER, 0.0
        for row, harmonic in resolved:
            w = record_weights(std[row, idx])
            shape = fit(idx, w, row)
            z, relative = loo_scores(shape, points[idx], values[row, idx], w)
            z = np.where(relative > MIN_RELATIVE, z, 0.0)
            j = int(np.argmax(z))
            if z[j] > score:
                worst, where, score = int(idx[j]), harmonic, float(z[j])
                share = float(relative[j])
        if worst < 0:
            break
        keep[worst] = False
        reasons[worst] = (f"it contradicts the fitted shape of harmonic {where}: its "
                          f"leave-one-out residual is {score:.3g} robust scales, {share:.0%} of "
                          "the shape's RMS amplitude (a dropout, a spike or a misplaced point)")
    return Screening(keep=keep, reasons=reasons)
