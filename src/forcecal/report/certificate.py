"""The calibration certificate of a campaign (METHOD.md section 5): the page a calibration
laboratory signs.

:func:`calibration_certificate` is a pure ``(rig, result, provenance) -> str``: it formats every
number of a :class:`~forcecal.campaign.CampaignResult` here, and the package's Jinja2 template
``templates/calibration.html.j2`` (autoescaped, with the style sheet every report shares) only
lays them out. The certificate states

- the law, as a formula and in words, its parameters with their combined standard uncertainty
  u (statistical and type B), the expanded uncertainty U = k u and the coverage factor k
  (GUM 7.2), ``K_total = n_poles K`` beside the ideal ``mu0 N^2 A / 4``, their correlations;
- the calibrated range (current, static and instantaneous gap, frequency, flux, force) over the
  campaign's runs, and the conditions (drive frequency, ambient temperature, gauges' coupling);
- the uncertainty budget, with the type-B inputs and whether the rig declares each;
- the candidate laws and why one was chosen, the validity domain (:mod:`.domain`), the
  reactions-only comparison, the repeatability and the runs; fig. 9, the provenance (version,
  date, command line, SHA-256 of every input, paths relative to one stated root), a sign-off.

Numbers are written as GUM 7.2.6 suggests (:mod:`forcecal.report.cells`), in the units a
laboratory writes (gaps in mm, a length parameter in µm); ranges with six significant digits.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..actuator import Candidate, Law, Selection
from ..campaign.statistics import COVERAGE_FACTOR, METHOD, TYPE_B_SOURCES
from ..rig import Rig, TypeB
from ._templates import render
from .cells import NONE, Grid, lab_unit, math_text, num, pct, rel, relative_paths, unc, value
from .domain import validity_domain

if TYPE_CHECKING:
    from ..campaign import CampaignResult
    from ..model.spatial import SpatialModel

__all__: list[str] = []

TEMPLATE = "calibration.html.j2"
"""The certificate's template under ``templates/``."""

FIGURE_CAPTION = (
    "Fig. 1 (after the paper's fig. 9): top, every calibration sample's measured total force "
    "against the law evaluated at that sample's own current and instantaneous gaps, and their "
    "relative difference beside the law's ±2σ band (its parameters' uncertainty), the "
    "reactions-only force (inertia ignored) as crosses; below, each run's mean force and the "
    "amplitude of its fundamental against the DC current, one colour per static gap and one "
    "marker per AC amplitude, with the law at each run's own current and gaps (small filled "
    "markers, joined).")
"""The caption of fig. 9 drawn with a (current, gap) law from a campaign's samples."""

_PARAMETER_MEANING = {
    "K": "force constant",
    "s_fe": "equivalent air gap of the iron path (with the probes' zero offset)",
    "i0": "current offset (remanence)",
    "a": "exponent of the current",
    "b": "exponent of the air gap",
    "A_eff": "effective pole area",
}
"""What each law parameter is, in words (a name not listed is shown as it is)."""

_SYMBOL_MEANING = {
    "f": "the force of one pole on the structure, N",
    "i": "the coil current, A",
    "s": "the instantaneous air gap at that pole, m",
    "phi": "the magnetic flux through one pole, Wb",
    "mu0": "the magnetic constant, 4π × 10⁻⁷ H/m",
}
"""The variables of the laws' formulas, in words."""

"""Plain-text formula -> math text."""

_TYPE_B_INPUT = {
    "current scale": ("current_scale", "relative"),
    "static gaps": ("gap", "m"),
    "gauge sensitivity": ("gauge_scale", "relative"),
    "probe sensitivity": ("probe_scale", "relative"),
    "positions": ("position", "m"),
    "masses": ("mass", "relative"),
}
"""The rig's ``[uncertainty]`` key behind each type-B source of the budget, and its kind."""

# --------------------------------------------------------------------------------------------
# the law and its parameters


def _law(result: CampaignResult) -> dict[str, Any]:
    """The chosen law: name, formula, math text, the variables and parameters in words."""
    law = result.calibration.law_object
    params = set(law.param_names)
    symbols = [s for s in dict.fromkeys(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", law.formula))
               if s not in params and s in _SYMBOL_MEANING]
    return {
        "name": law.name,
        "formula": law.formula,
        "math": math_text(law.formula),
        "symbols": [(math_text(s), _SYMBOL_MEANING[s]) for s in symbols],
        "parameters": [(n, _PARAMETER_MEANING.get(n, n), math_text(u))
                       for n, u in zip(law.param_names, law.param_units, strict=True)],
        "n_poles": result.n_poles,
        "ac_only": result.ac_only,
        "reason": result.selection.reason,
    }


def _std_parts(result: CampaignResult) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Combined, statistical and type-B standard uncertainties of the parameters (the parts
    None without a budget)."""
    pu = result.uncertainty
    if pu is None:
        return result.calibration.stderr, None, None
    stat = np.sqrt(np.maximum(np.diag(pu.statistical), 0.0))
    tb = np.sqrt(np.maximum(np.diag(pu.type_b), 0.0))
    return pu.stderr, stat, tb


def coverage_factor(result: CampaignResult) -> float:
    """k of the certificate's expanded uncertainties (the budget's, else the default).

    Parameters
    ----------
    result : CampaignResult

    Returns
    -------
    float
    """
    return result.uncertainty.coverage_factor if result.uncertainty else COVERAGE_FACTOR


def _units(result: CampaignResult) -> list[tuple[float, str]]:
    """(factor, unit) each parameter is written in (:func:`forcecal.report.cells.lab_unit`)."""
    law = result.calibration.law_object
    return [lab_unit(float(x), unit)
            for x, unit in zip(result.calibration.params, law.param_units, strict=True)]


def _parameters(result: CampaignResult) -> Grid:
    """The parameters with u (and its parts), U = k u and U relative; K_total after them."""
    law = result.calibration.law_object
    k = coverage_factor(result)
    u, stat, tb = _std_parts(result)
    rows: list[tuple[str | tuple[str, ...], ...]] = []
    for j, (name, (f, unit)) in enumerate(zip(law.param_names, _units(result), strict=True)):
        x = float(result.calibration.params[j])
        rows.append((name, value(f * x, f * u[j]), math_text(unit), unc(f * u[j]),
                     NONE if stat is None else unc(f * stat[j]),
                     NONE if tb is None else unc(f * tb[j]), unc(f * k * u[j]),
                     rel(k * u[j] / abs(x)) if x else NONE))
    marks = [""] * len(rows)
    if result.k_total is not None and result.k_total_std is not None:
        kt, ukt = result.k_total, result.k_total_std
        j = law.param_names.index("K")
        n = result.n_poles
        rows.append((f"K_total = {n} K", value(kt, ukt), "N m²/A²", unc(ukt),
                     NONE if stat is None else unc(n * stat[j]),
                     NONE if tb is None else unc(n * tb[j]), unc(k * ukt),
                     rel(k * ukt / abs(kt)) if kt else NONE))
        marks.append("subtotal")
    return Grid(
        caption="Calibrated parameters",
        header=("parameter", "value", "unit", "std. uncertainty u", "u statistical",
                "u type B", f"expanded U (k = {k:g})", "U relative"),
        rows=tuple(rows), marks=tuple(marks))


def _correlation(result: CampaignResult) -> Grid | None:
    """The parameters' correlation matrix (of the combined covariance); None for one
    parameter."""
    names = result.calibration.law_object.param_names
    if len(names) < 2:
        return None
    if result.uncertainty is not None:
        corr = result.uncertainty.correlation
    else:
        std = result.calibration.stderr
        corr = result.calibration.covariance / np.outer(std, std)
    rows = tuple((a, *(f"{corr[i, j]:+.4f}" for j in range(len(names))))
                 for i, a in enumerate(names))
    return Grid(caption="Correlation matrix of the parameters (combined covariance)",
                header=("", *names), rows=rows)


# --------------------------------------------------------------------------------------------
# range and conditions


def calibrated_range(result: CampaignResult) -> dict[str, tuple[float, float]]:
    """The minima and maxima over the campaign's runs (tare records excluded).

    Parameters
    ----------
    result : CampaignResult

    Returns
    -------
    dict
        ``current`` [A] (the fitted current over one period of every run), ``static_gap`` [m]
        (every pole's), ``gap`` [m] (the instantaneous one), ``frequency`` [Hz] (every run's
        refined fundamental), ``force`` [N] (the reconstructed total), and ``flux`` [Wb] when
        measured: each ``(min, max)``.
    """
    runs = result.runs

    def span(values: Sequence[np.ndarray]) -> tuple[float, float]:
        return (float(min(np.min(v) for v in values)), float(max(np.max(v) for v in values)))

    out = {
        "current": span([r.samples.current for r in runs]),
        "static_gap": span([r.samples.motion.static_gap for r in runs]),
        "gap": span([r.samples.gaps for r in runs]),
        "frequency": span([np.array([r.estimate.f0]) for r in runs]),
        "force": span([r.samples.force for r in runs]),
    }
    fluxes = [r.samples.flux for r in runs if r.samples.flux is not None]
    if fluxes:
        out["flux"] = span(fluxes)
    return out


_RANGE_ROWS = (
    ("current", "coil current i", "A", 1.0, 6),
    ("static_gap", "static air gap (every pole)", "mm", 1e3, 6),
    ("gap", "instantaneous air gap s", "mm", 1e3, 6),
    ("frequency", "drive frequency (refined, every run)", "Hz", 1.0, 8),
    ("flux", "flux through one pole", "Wb", 1.0, 6),
    ("force", "total actuator force", "N", 1.0, 6),
)
"""(key of :func:`calibrated_range`, quantity, unit shown, its factor from SI, significant
digits shown); the flux in the prefix that suits its largest value."""


def _range(result: CampaignResult) -> Grid:
    """:func:`calibrated_range` as a table, in the units a laboratory writes."""
    ranges = calibrated_range(result)
    rows = []
    for key, label, unit, factor, digits in _RANGE_ROWS:
        if key not in ranges:
            continue
        lo, hi = ranges[key]
        if key == "flux":
            factor, unit = lab_unit(max(abs(lo), abs(hi)), unit)
        rows.append((label, num(factor * lo, digits), num(factor * hi, digits), unit))
    return Grid(caption="Calibrated range (minimum and maximum over the campaign's runs)",
                header=("quantity", "minimum", "maximum", "unit"), rows=tuple(rows))


def _conditions(rig: Rig, result: CampaignResult, model: SpatialModel | None
                ) -> list[tuple[str, str]]:
    """(condition, value) pairs: drive frequency, temperature when given, gauges, runs."""
    f_lo, f_hi = calibrated_range(result)["frequency"]
    rows = []
    if rig.frequency is not None:
        rows.append(("nominal drive frequency", f"{rig.frequency:g} Hz (rig, "
                                                "acquisition.frequency)"))
    rows.append(("refined drive frequency", f"{f_lo:.8g} Hz to {f_hi:.8g} Hz over the runs"))
    if rig.temperature is not None:
        rows.append(("ambient temperature", f"{rig.temperature:g} °C (rig, "
                                            "acquisition.temperature)"))
    rows.append(("force gauges", "AC-coupled: the laws are fitted to the harmonics alone and "
                 "predict the whole force, DC included" if result.ac_only else
                 "DC-coupled: the mean force and the harmonics are both fitted"))
    rows.append(("runs", f"{len(result.runs)} runs, {result.samples_per_period} samples over "
                 f"one period of each ({len(result.runs) * result.samples_per_period} "
                 "observations)"))
    tares = result.tares or tuple(dict.fromkeys(r.tare for r in result.runs if r.tare))
    rows.append(("tare records", ", ".join(tares) or "none"))
    if model is not None:
        rows.append(("spatial model", f"fundamental {model.f0:.6g} Hz, harmonics "
                     + ", ".join(str(int(n)) for n in model.harmonics)
                     + f", from {len(model.scans) or 1} scan(s)"))
    return rows


# --------------------------------------------------------------------------------------------
# the budget


def declared_type_b(rig: Rig, used: TypeB) -> frozenset[str]:
    """The ``[uncertainty]`` keys the rig declares (the others are the documented defaults).

    Without an ``[uncertainty]`` table, none. With one, the keys its table gives, read again
    from the rig file; when the file cannot be read again, every key (the table is there).

    Parameters
    ----------
    rig : Rig
        The rig, whose ``source`` is its file.
    used : TypeB
        The type-B uncertainties the calibration used.

    Returns
    -------
    frozenset of str
        Keys of :attr:`forcecal.rig.TypeB.KEYS`.
    """
    if not used.declared:
        return frozenset()
    try:
        table = tomllib.loads(Path(rig.source).read_text(encoding="utf-8")).get("uncertainty")
    except (OSError, ValueError):
        table = None
    if isinstance(table, dict) and rig.type_b == used:
        return frozenset(k for k in TypeB.KEYS if k in table)
    return frozenset(TypeB.KEYS)


def _type_b_input(key: str, measure: str, used: TypeB) -> str:
    """A type-B input standard uncertainty, in its unit."""
    v = float(getattr(used, key))
    if measure == "relative":
        return f"{100 * v:.3g} % (relative)"
    return f"{v * 1e6:.3g} µm" if key == "gap" else f"{v * 1e3:.3g} mm"


def _budget(rig: Rig, result: CampaignResult) -> tuple[Grid | None, str]:
    """Every source's standard uncertainty of each parameter, the totals, and the sentence on
    the type-B inputs' origin."""
    pu = result.uncertainty
    if pu is None:
        return None, ("No uncertainty budget: the standard uncertainties are those of the fit's "
                      "residuals.")
    law = result.calibration.law_object
    units = _units(result)

    def u_cells(std: np.ndarray) -> tuple[str, ...]:
        return tuple(unc(f * v) for (f, _), v in zip(units, std, strict=True))

    used = pu.type_b_used
    declared = declared_type_b(rig, used)
    zero = ("0",) * len(law.param_names)
    rows: list[tuple[str | tuple[str, ...], ...]] = []
    for source, std in pu.budget.items():
        if pu.kinds.get(source) == "statistical":
            rows.append((source, "statistical (type A)", "this campaign's records", NONE,
                         *u_cells(std)))
    for source in TYPE_B_SOURCES:
        key, kind = _TYPE_B_INPUT.get(source, ("", ""))
        given = _type_b_input(key, kind, used) if key else NONE
        origin = (NONE if not key else "declared by the rig" if key in declared
                  else "documented default")
        cells = (u_cells(pu.budget[source]) if source in pu.budget
                 else zero if key and getattr(used, key) == 0 else (NONE,) * len(zero))
        rows.append((source, "type B", given, origin, *cells))
    u, stat, tb = _std_parts(result)
    assert stat is not None and tb is not None  # with a budget
    k = pu.coverage_factor
    totals = (("statistical, combined", stat, "subtotal"), ("type B, combined", tb, ""),
              ("combined standard uncertainty u", u, "total"),
              (f"expanded uncertainty U = k u (k = {k:g})", k * u, "total"))
    marks = [""] * len(rows)
    for label, values, mark in totals:
        rows.append((label, "", "", "", *u_cells(values)))
        marks.append(mark)
    header = ("source", "evaluation", "input standard uncertainty", "origin",
              *(f"u({n}) [{math_text(unit)}]" for n, (_, unit) in zip(law.param_names, units,
                                                                   strict=True)))
    grid = Grid(caption="Uncertainty budget: each source's standard uncertainty of each "
                        "parameter", header=header, rows=tuple(rows), marks=tuple(marks))
    return grid, _origin_sentence(used, declared)


def _origin_sentence(used: TypeB, declared: frozenset[str]) -> str:
    """Which type-B inputs the rig declares and which are the documented defaults."""
    defaults = [k for k in TypeB.KEYS if k not in declared]
    if not used.declared:
        return ("The rig declares no type-B standard uncertainties (it has no [uncertainty] "
                "table): every type-B input above is forcecal's documented default, not a "
                "value of this rig.")
    if not defaults:
        return "Every type-B input above is declared by the rig's [uncertainty] table."
    return ("The rig's [uncertainty] table declares "
            + (", ".join(sorted(declared)) or "no key")
            + "; forcecal's documented defaults are used for " + ", ".join(defaults) + ".")


def _cross_check(result: CampaignResult) -> Grid | None:
    """The combined u beside the fit's residual one and the run-clustered scatter."""
    pu = result.uncertainty
    if pu is None:
        return None
    names = result.calibration.law_object.param_names
    res = np.sqrt(np.maximum(np.diag(pu.residual), 0.0))
    scatter = (None if pu.run_scatter is None
               else np.sqrt(np.maximum(np.diag(pu.run_scatter), 0.0)))
    rows = tuple((n, math_text(unit), unc(f * pu.stderr[j]), unc(f * res[j]),
                  NONE if scatter is None else unc(f * scatter[j]))
                 for j, (n, (f, unit)) in enumerate(zip(names, _units(result), strict=True)))
    return Grid(caption="Cross-check of the standard uncertainties",
                header=("parameter", "unit", "u (this budget)",
                        "fit residuals (samples independent)", "scatter between runs"),
                rows=rows)


# --------------------------------------------------------------------------------------------
# selection, reactions only, repeatability, runs


def _param_lines(law: Law, params: np.ndarray, std: np.ndarray) -> tuple[str, ...]:
    """Each parameter as ``name = value ± u unit``, in the unit a laboratory writes."""
    lines = []
    for n, v, e, unit in zip(law.param_names, params, std, law.param_units, strict=True):
        f, shown = lab_unit(float(v), unit)
        lines.append(f"{n} = {value(f * float(v), f * float(e))} ± {unc(f * float(e))}"
                     + ("" if shown == "-" else f" {math_text(shown)}"))
    return tuple(lines)


def _candidates(selection: Selection, caption: str) -> tuple[Grid, list[tuple[str, str]]]:
    """Every candidate law with its scores, the chosen one marked; the laws skipped."""
    def row(c: Candidate) -> tuple[str | tuple[str, ...], ...]:
        fit = c.fit
        return (c.name, math_text(fit.law.formula), _param_lines(fit.law, fit.params, fit.stderr),
                str(c.n_params), pct(fit.rms_residual, 4), pct(c.held_out.rms, 4),
                f"{fit.aic:.1f}", f"{fit.bic:.1f}",
                "chosen" if c.name == selection.chosen else "")

    grid = Grid(caption=caption,
                header=("law", "formula", "parameters (± u of the fit's residuals)",
                        "parameters", "RMS residual", "held-out error", "AIC", "BIC", ""),
                rows=tuple(row(c) for c in selection.candidates),
                marks=tuple("chosen" if c.name == selection.chosen else ""
                            for c in selection.candidates))
    return grid, list(selection.skipped)


def _reactions(result: CampaignResult) -> dict[str, Any]:
    """The same laws fitted to the reactions-only force, against the certified calibration."""
    ro = result.reactions_only
    if ro.selection is None:
        return {"error": ro.error or "no law could be fitted", "summary": None,
                "candidates": None, "skipped": []}
    rows: list[tuple[str | tuple[str, ...], ...]] = [
        ("law chosen", result.law, ro.selection.chosen, ""),
    ]
    if result.k_total is not None:
        ukt = result.k_total_std or float("nan")     # the reactions-only value to its digits
        rows.append(("K_total [N m²/A²]", value(result.k_total, ukt),
                     NONE if ro.k_total is None else value(ro.k_total, ukt),
                     pct(ro.k_total_error, 2, sign=True)))
    if result.s_fe is not None:
        rows.append(_s_fe_row(result))
    rows.append(("force predicted with the chosen law: RMS relative difference", "", "",
                 pct(ro.force_error, 2)))
    summary = Grid(caption="Reactions only (inertia ignored) against this calibration",
                   header=("", "this calibration", "reactions only", "difference"),
                   rows=tuple(rows))
    candidates, skipped = _candidates(ro.selection, "Candidate laws fitted to the "
                                                    "reactions-only force")
    return {"error": None, "summary": summary, "candidates": candidates, "skipped": skipped}


def _s_fe_row(result: CampaignResult) -> tuple[str, ...]:
    """s_fe of this calibration and of the reactions only, and their difference, in µm or mm
    to the digits of this calibration's uncertainty."""
    ro, s_fe = result.reactions_only, float(result.s_fe or 0.0)
    names = result.calibration.law_object.param_names
    u = float(_std_parts(result)[0][names.index("s_fe")]) if "s_fe" in names else float("nan")
    f, unit = lab_unit(s_fe, "m")
    return (f"s_fe [{unit}]", value(f * s_fe, f * u),
            NONE if ro.s_fe is None else value(f * ro.s_fe, f * u),
            NONE if ro.s_fe is None else f"{value(f * (ro.s_fe - s_fe), f * u)} {unit}")


def _setpoint(group: Mapping[str, Any]) -> str:
    """A repeated setpoint in words: its gap(s) in mm and labels."""
    parts = [] if group.get("gap") is None else [f"gap {1e3 * group['gap']:.3f} mm"]
    parts += [f"gap {name} {1e3 * v:.3f} mm" for name, v in group.get("gaps", {}).items()]
    parts += [f"{k} = {v}" for k, v in group.get("labels", {}).items()]
    return ", ".join(parts) or "(no labels)"


def _repeatability(result: CampaignResult) -> tuple[Grid | None, Grid | None]:
    """The pooled relative spreads and one row per repeated setpoint (None without one)."""
    rep = result.repeatability
    if not rep.groups:
        return None, None
    pooled = Grid(caption=f"Repeatability, pooled over {len(rep.groups)} repeated setpoint(s): "
                          "relative standard deviation",
                  header=("quantity", "relative standard deviation"),
                  rows=(("K_total refitted to each run", pct(rep.k_total_rel_std)),
                        ("mean force", pct(rep.mean_force_rel_std)),
                        ("amplitude of the fundamental", pct(rep.amplitude_rel_std))))
    groups = Grid(caption="Repeated setpoints",
                  header=("setpoint", "runs", "K_total", "mean force", "amplitude"),
                  rows=tuple((_setpoint(g), tuple(g["runs"]), pct(g.get("k_total_rel_std")),
                              pct(g.get("mean_force_rel_std")), pct(g.get("amplitude_rel_std")))
                             for g in rep.groups))
    return pooled, groups


def _runs(result: CampaignResult) -> Grid:
    """One row per run: its gaps [mm], current, frequency and forces to the digits of their
    uncertainty, and its residual against the law."""
    rows = []
    for k, r in enumerate(result.runs):
        smp, est = r.samples, r.estimate
        static = np.unique(np.round(smp.motion.static_gap, 12))
        u = est.total_std
        rows.append((r.name, " / ".join(f"{1e3 * g:.3f}" for g in static),
                     f"{smp.current.min():.3f}\u00a0to\u00a0{smp.current.max():.3f}",
                     value(est.f0, est.f0_std), value(float(est.total[0].real), float(u[0])),
                     value(float(abs(est.total[1])), float(u[1])) if est.total.size > 1
                     else NONE,
                     pct(float(result.run_residual[k]), 3),
                     ", ".join(f"{a} = {b}" for a, b in r.entry.labels.items()) or NONE))
    return Grid(caption="The campaign's runs",
                header=("run", "static gap [mm]", "current [A]", "f0 [Hz]", "mean force [N]",
                        "fundamental [N]", "residual (RMS)", "manifest labels"),
                rows=tuple(rows))


def _notes(result: CampaignResult) -> Grid | None:
    """The runs' notes once per kind (:meth:`CampaignResult.note_kinds`): the note, how many
    runs drew it, the first of them; None when no run drew one."""
    kinds = result.note_kinds()
    if not kinds:
        return None
    n = len(result.runs)
    return Grid(caption="Notes the runs drew", header=("note", "runs", "first run"),
                rows=tuple((text, f"{len(names)} of {n}", names[0]) for text, names in kinds))


# --------------------------------------------------------------------------------------------
# the page


def _provenance(prov: Mapping[str, Any], rig: Rig, manifest: str) -> dict[str, Any]:
    """The provenance's lines, and every input's path, the rig's and the manifest's relative to
    one root (:func:`forcecal.report.cells.relative_paths`)."""
    inputs = list(prov.get("inputs", ()))
    root, paths = relative_paths([str(f["path"]) for f in inputs] + [rig.source, manifest])
    rows = tuple((path, str(f.get("bytes", NONE)), str(f.get("sha256", "not a file")))
                 for path, f in zip(paths, inputs, strict=False))
    return {
        "version": str(prov.get("forcecal_version", NONE)),
        "created": str(prov.get("created_utc", NONE)),
        "command": str(prov.get("command", NONE)),
        "python": str(prov.get("python", NONE)),
        "root": root,
        "rig": paths[-2],
        "manifest": paths[-1],
        "inputs": Grid(caption="Input files", header=("input", "bytes", "SHA-256"), rows=rows),
    }


def calibration_certificate(rig: Rig, result: CampaignResult, provenance: Mapping[str, Any],
                            model: SpatialModel | None = None,
                            figure: str | Mapping[str, str] | None = None,
                            calibration_file: tuple[str, str] | None = None) -> str:
    """The calibration certificate of a campaign, one self-contained HTML page.

    Parameters
    ----------
    rig : Rig
        The campaign's rig: its name, drive frequency, ``acquisition.temperature`` and type-B
        inputs (whether declared or defaults).
    result : CampaignResult
        The campaign's calibration.
    provenance : mapping
        :func:`forcecal.provenance.provenance` of the inputs.
    model : SpatialModel, optional
        The spatial model the forces were reconstructed with, for the conditions.
    figure : str or mapping, optional
        Fig. 9: its ``src``, a ``data:`` URI (:func:`forcecal.report.html.data_uri`), and
        optionally its ``width`` [CSS px], ``link`` (a PDF it links to), ``file`` (the file's
        path beside the page) and ``caption`` (default :data:`FIGURE_CAPTION`); a str is the
        ``src`` alone.
    calibration_file : (str, str), optional
        The name and SHA-256 of the ``calibration.json`` the certificate states.

    Returns
    -------
    str
        The HTML5 document; every text escaped.
    """
    budget, origin = _budget(rig, result)
    candidates, skipped = _candidates(result.selection, "Candidate laws fitted to the "
                                                        "reconstructed force")
    pooled, groups = _repeatability(result)
    k = coverage_factor(result)
    context = {
        "title": f"Calibration certificate: {rig.name}",
        "rig": rig,
        "manifest": result.manifest,
        "calibration_file": calibration_file,
        "law": _law(result),
        "parameters": _parameters(result),
        "coverage": f"{k:g}",
        "ideal_k": None if result.ideal_k is None or result.k_total is None else {
            "value": num(result.ideal_k), "ratio": f"{result.k_total / result.ideal_k:.4f}"},
        "correlation": _correlation(result),
        "range": _range(result),
        "conditions": _conditions(rig, result, model),
        "budget": budget,
        "origin": origin,
        "method": METHOD if result.uncertainty and result.uncertainty.propagated else None,
        "cross_check": _cross_check(result),
        "candidates": candidates,
        "skipped": skipped,
        "held_out": result.selection.best.held_out.scheme,
        "domain": validity_domain(result),
        "reactions": _reactions(result),
        "pooled": pooled,
        "groups": groups,
        "runs": _runs(result),
        "notes": _notes(result),
        "figure": None if figure is None else {
            **dict.fromkeys(("width", "link", "file"), ""), "caption": FIGURE_CAPTION,
            **({"src": figure} if isinstance(figure, str) else figure)},
        "provenance": _provenance(provenance, rig, result.manifest),
    }
    return render(TEMPLATE, context)
