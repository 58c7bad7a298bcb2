"""The validity domain a calibration certificate states: where the law was checked and how well.

:func:`validity_domain` gives the certificate's section as formatted tables: the ranges the law
was checked over (coil current, each pole's air gap, the frequency when the calibration has a
law over frequency, the flux when the law is flux-based) with what ``forcecal predict`` does
outside them; the chosen law's departure from the calibration samples at the domain's edges
(the lowest and highest tenth of the samples by current, by each pole's gap, by frequency and by
flux); and the candidate laws (and the core's frequency models) not chosen, with why.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..actuator.frequency import MATCHED
from ..actuator.prediction import EXTRAPOLATION, FREQUENCY_EXTRAPOLATION
from ..actuator.selection import HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL
from ..campaign.samples import calibration_data
from .cells import NONE, Grid, lab_unit, num, pct

if TYPE_CHECKING:
    from ..actuator import Candidate, Selection
    from ..actuator.frequency import FrequencyLaw
    from ..campaign import CampaignResult

__all__: list[str] = []

EDGE_FRACTION = 0.1
"""The share of the calibration samples each edge of the domain holds (a decile)."""


def _axes(result: CampaignResult) -> list[tuple[str, str, np.ndarray, float, str]]:
    """(quantity, symbol, per-sample values in SI, factor to the unit shown, unit) of every axis
    of the domain, the samples in the order of :func:`forcecal.campaign.calibration_data`."""
    runs = result.runs
    axes = [("coil current", "i", np.concatenate([r.samples.current for r in runs]), 1.0, "A")]
    gaps = np.concatenate([r.samples.gaps for r in runs])
    for p in range(gaps.shape[1]):
        axes.append((f"air gap of pole {p + 1}", f"s{p + 1}", gaps[:, p], 1e3, "mm"))
    if result.calibration.frequency_law is not None:
        f0 = np.concatenate([np.full(r.samples.n, r.estimate.f0) for r in runs])
        axes.append(("drive frequency", "f", f0, 1.0, "Hz"))
    if result.calibration.law_object.needs_flux and all(r.samples.flux is not None
                                                        for r in runs):
        phi = np.concatenate([r.samples.flux for r in runs if r.samples.flux is not None])
        factor, unit = lab_unit(float(np.max(np.abs(phi))), "Wb")
        axes.append(("flux through one pole", "φ", phi, factor, unit))
    return axes


def sample_residuals(result: CampaignResult) -> np.ndarray:
    """The chosen law's relative residual at every calibration sample.

    Parameters
    ----------
    result : CampaignResult

    Returns
    -------
    (n_obs,) array [-]
        :meth:`~forcecal.actuator.CalibrationData.relative_residual` of the chosen law, as the
        campaign's per-run residuals (``result.run_residual`` is the RMS of each run's share).
    """
    fit = result.selection.best.fit
    data = calibration_data(result.runs, "total", result.ac_only)
    return data.relative_residual(
        fit.law.per_pole(fit.params, data.current, data.gaps, data.flux).sum(axis=1))


def _ranges(result: CampaignResult) -> Grid:
    """The ranges checked, in the units a laboratory writes, and what a prediction does
    beyond."""
    cal = result.calibration
    beyond = {
        "i": f"warns; refuses beyond {EXTRAPOLATION:g} × the largest |i|",
        "f": f"warns; refuses above {FREQUENCY_EXTRAPOLATION:g} × the highest",
        "φ": f"warns; refuses beyond {EXTRAPOLATION:g} × the largest |φ|",
    }
    gap_rule = (f"warns; refuses below 1/{EXTRAPOLATION:g} of the smallest or above "
                f"{EXTRAPOLATION:g} × the largest")
    if cal.law_object.needs_flux:               # the current and gaps are not the law's inputs
        beyond["i"] = gap_rule = "not an input: the law predicts from the flux φ"
    rows = []
    for label, symbol, values, factor, unit in _axes(result):
        lo, hi = float(np.min(values)), float(np.max(values))
        if symbol == "i":
            lo, hi = cal.current_range
        elif symbol == "f" and cal.frequency_law is not None:
            lo, hi = cal.frequency_law.frequency_range
        rows.append((f"{label} {symbol}", num(factor * lo), num(factor * hi), unit,
                     beyond.get(symbol, gap_rule)))
    return Grid(caption="Domain checked (the calibration samples' minimum and maximum)",
                header=("quantity", "minimum", "maximum", "unit", "a prediction outside"),
                rows=tuple(rows))


def _edge_rows(label: str, symbol: str, values: np.ndarray, factor: float, unit: str,
               residual: np.ndarray) -> list[tuple[str, ...]]:
    """The departure over the lowest and the highest tenth of the samples along one axis."""
    n = max(1, int(np.ceil(EDGE_FRACTION * values.size)))
    order = np.argsort(values, kind="stable")
    rows: list[tuple[str, ...]] = []
    for edge, idx in (("lowest", order[:n]), ("highest", order[-n:])):
        v, r = values[idx], residual[idx]
        rows.append((f"{edge} tenth of {label}",
                     f"{symbol} {num(factor * float(v.min()))} to {num(factor * float(v.max()))}"
                     f" {unit}", str(idx.size), pct(float(np.sqrt(np.mean(r ** 2))), 3),
                     pct(float(r[np.argmax(np.abs(r))]), 3, sign=True)))
    return rows


def _edges(result: CampaignResult) -> Grid:
    """The law's departure from the samples at the edges of every axis, and over them all."""
    residual = sample_residuals(result)
    rows: list[tuple[str | tuple[str, ...], ...]] = [
        ("every calibration sample", NONE, str(residual.size),
         pct(float(np.sqrt(np.mean(residual ** 2))), 3),
         pct(float(residual[np.argmax(np.abs(residual))]), 3, sign=True))]
    for axis in _axes(result):
        rows.extend(_edge_rows(*axis, residual))
    return Grid(caption="Departure of the law from the data at the domain's edges",
                header=("samples", "span", "count", "RMS relative residual",
                        "largest relative residual"),
                rows=tuple(rows), marks=("total",) + ("",) * (len(rows) - 1))


def _why_law(c: Candidate, chosen: Candidate, best: Candidate, tol: float) -> str:
    """Why a candidate law was not chosen (:func:`forcecal.actuator.select_law`'s rule)."""
    if c.held_out.rms > best.held_out.rms + tol:
        return (f"held-out error above the best's ({pct(best.held_out.rms)}, "
                f"'{best.name}') by more than the tolerance {pct(tol)}")
    if c.n_params > chosen.n_params:
        return (f"held-out error within the tolerance, but {c.n_params} parameters against "
                f"the chosen law's {chosen.n_params}")
    return f"as simple and as good, but a higher BIC ({c.fit.bic:.1f} against {chosen.fit.bic:.1f})"


def _rejected_laws(selection: Selection) -> list[tuple[str, ...]]:
    """(law, parameters, held-out error, why) of every candidate law not chosen."""
    best = min(selection.candidates, key=lambda c: c.held_out.rms)
    chosen = selection.best
    rows: list[tuple[str, ...]] = [
        (c.name, str(c.n_params), pct(c.held_out.rms),
         _why_law(c, chosen, best, selection.tolerance))
        for c in selection.candidates if c.name != selection.chosen]
    rows += [(name, NONE, NONE, f"not fitted: {why}") for name, why in selection.skipped]
    return rows


def _why_model(row: Mapping[str, Any], fl: FrequencyLaw, errors: Sequence[float]) -> str:
    """Why a frequency model of the calibration file's table was not chosen."""
    if "skipped" in row:
        return f"not fitted: {row['skipped']}"
    chosen = next((r for r in fl.candidates if r.get("model") == fl.model), {})
    held = row.get("held_out")
    if held is None or not errors:
        return f"a higher BIC ({num(row.get('bic'), 4)} against {num(chosen.get('bic'), 4)})"
    best = min(errors)
    tol = max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL * best)
    if float(held) > best + tol:
        return (f"held-out error above the best's ({pct(best)}) by more than the tolerance "
                f"{pct(tol)}")
    return f"within the tolerance; {fl.reason}"


def _rejected_models(fl: FrequencyLaw | None) -> list[tuple[str, ...]]:
    """(model, held-out error, BIC, why) of every frequency model not chosen."""
    if fl is None:
        return []
    errors = [float(r["held_out"]) for r in fl.candidates
              if "skipped" not in r and r.get("held_out") is not None]
    return [(f"frequency model '{r.get('model', NONE)}'", "3", pct(r.get("held_out")),
             _why_model(r, fl, errors))
            for r in fl.candidates if r.get("model") != fl.model]


def validity_domain(result: CampaignResult) -> dict[str, Any]:
    """The certificate's "Validity domain" section.

    Parameters
    ----------
    result : CampaignResult

    Returns
    -------
    dict
        ``ranges`` and ``edges`` (:class:`~forcecal.report.cells.Grid`), ``rejected`` (a Grid,
        None when no candidate was set aside), ``unmatched`` (a Grid of the frequency steps
        the law over frequency does not match, None when it matches them all; ``matched`` its
        limit), ``edge_share`` (the edges' share of the samples, in %), ``law`` (the chosen
        law's name) and ``inputs`` (what it predicts from).
    """
    rows = [*_rejected_laws(result.selection), *_rejected_models(result.calibration.frequency_law)]
    rejected = None if not rows else Grid(
        caption="Candidates not chosen, and why",
        header=("candidate", "parameters", "held-out error", "why not chosen"), rows=tuple(rows))
    fl = result.calibration.frequency_law
    off = [] if fl is None else fl.departures()
    unmatched = None if fl is None or not off else Grid(
        caption=f"Frequency steps the {fl.model} law does not match within their uncertainties",
        header=("step", "K(f) / K: law less step", "lag: law less step", "chi-square"),
        rows=tuple((f"{st.frequency:.4g} Hz", pct(dg / st.gain, 3, sign=True),
                    f"{dl:+.3g}°", f"{chi2:.3g}") for st, dg, dl, chi2 in off))
    return {"ranges": _ranges(result), "edges": _edges(result), "rejected": rejected,
            "unmatched": unmatched, "matched": f"{MATCHED:g}",
            "edge_share": f"{100 * EDGE_FRACTION:g}", "law": result.law,
            "inputs": ("flux" if result.calibration.law_object.needs_flux
                       else "current and gaps")}
