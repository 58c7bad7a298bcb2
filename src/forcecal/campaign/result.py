"""The calibration of a campaign (:class:`CampaignResult`), its file and its text report.

``calibration.json`` holds the chosen law's :class:`forcecal.actuator.Calibration` at the top
level (so :meth:`forcecal.actuator.Calibration.load` reads it; its covariance and ``stderr`` are
the combined standard uncertainties, statistical plus type B) and beside it the parameters'
uncertainty budget (``uncertainty``, :mod:`forcecal.campaign.statistics`), the campaign's
scores, the reactions-only comparison, the repeatability and a summary of every run.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import write_text_atomic
from ..actuator import Calibration, Law, Selection
from ..actuator import report_text as selection_text
from .repeatability import Repeatability
from .runs import RunResult
from .statistics import ParameterUncertainty

__all__ = ["CampaignResult", "load_calibration", "report_text", "write_calibration"]


def k_total_of(law: Law, params: np.ndarray, n_poles: int) -> float | None:
    """``n_poles * K`` of a law [N m^2/A^2].

    Parameters
    ----------
    law : Law
        The law of one pole.
    params : (n_params,) array
        Its parameters.
    n_poles : int
        Number of poles.

    Returns
    -------
    float or None
        None when the law has no K in N m^2/A^2 (the flux and power laws).
    """
    if "K" not in law.param_names or law.param_units[0] != "N m^2/A^2":
        return None
    return n_poles * float(params[law.param_names.index("K")])


@dataclass(frozen=True)
class ReactionsOnly:
    """The same candidate laws fitted to the reactions-only force.

    Attributes
    ----------
    selection : Selection or None
        None when no law could be fitted (``error`` says why).
    error : str or None
        Why no law could be fitted.
    k_total : float or None [N m^2/A^2]
        ``n_poles * K`` of the law chosen for the corrected force, fitted to the reactions only.
    k_total_error : float or None [-]
        Its relative difference from the corrected calibration's ``k_total``.
    s_fe : float or None [m]
        That law's ``s_fe`` fitted to the reactions only, when it has one.
    force_error : float or None [-]
        RMS over the campaign's samples of (reactions-only prediction - corrected prediction) /
        corrected prediction, both with the chosen law.
    """

    selection: Selection | None
    error: str | None = None
    k_total: float | None = None
    k_total_error: float | None = None
    s_fe: float | None = None
    force_error: float | None = None


@dataclass(frozen=True)
class CampaignResult:
    """The calibration of a campaign.

    Attributes
    ----------
    runs : tuple of RunResult
        The reconstructed runs, in manifest order.
    selection : Selection
        The candidate laws fitted to the reconstructed force, and the one chosen.
    calibration : Calibration
        The chosen law's calibration (what ``forcecal predict`` reads).
    reactions_only : ReactionsOnly
        The candidate laws fitted to the reactions-only force.
    repeatability : Repeatability
        The spread over repeated setpoints.
    n_poles : int
        Number of poles.
    ideal_k : float or None [N m^2/A^2]
        ``mu0 N^2 A / 4`` from the rig, the ideal TOTAL K of ``f = K i^2 / s^2`` summed over the
        poles of a U-core.
    ac_only : bool
        The laws were fitted to the harmonics alone (AC-coupled gauges).
    samples_per_period : int
        Calibration samples per run.
    run_k_total : (n_runs,) array [N m^2/A^2]
        The chosen law's K_total refitted to each run alone (NaN for laws without K).
    run_residual : (n_runs,) array [-]
        RMS relative residual of the chosen law on each run.
    manifest : str
        The campaign manifest's path.
    tares : tuple of str
        Names of the tare records.
    uncertainty : ParameterUncertainty or None
        The chosen law's parameter uncertainties with their budget (the calibration's
        covariance is their combined covariance).
    """

    runs: tuple[RunResult, ...]
    selection: Selection
    calibration: Calibration
    reactions_only: ReactionsOnly
    repeatability: Repeatability
    n_poles: int
    ideal_k: float | None
    ac_only: bool
    samples_per_period: int
    run_k_total: np.ndarray
    run_residual: np.ndarray
    manifest: str = "<manifest>"
    tares: tuple[str, ...] = ()
    uncertainty: ParameterUncertainty | None = None

    @property
    def law(self) -> str:
        """Name of the chosen law."""
        return self.calibration.law

    @property
    def params(self) -> dict[str, float]:
        """Parameters of the chosen law by name."""
        law = self.calibration.law_object
        return {n: float(v) for n, v in zip(law.param_names, self.calibration.params, strict=True)}

    @property
    def k_total(self) -> float | None:
        """``n_poles * K`` of the chosen law [N m^2/A^2], None when its K is not of that unit."""
        return k_total_of(self.calibration.law_object, self.calibration.params, self.n_poles)

    @property
    def k_total_std(self) -> float | None:
        """Combined standard uncertainty of :attr:`k_total` [N m^2/A^2] (statistical and
        type B)."""
        law = self.calibration.law_object
        if k_total_of(law, self.calibration.params, self.n_poles) is None:
            return None
        return self.n_poles * float(self.calibration.stderr[law.param_names.index("K")])

    @property
    def s_fe(self) -> float | None:
        """The chosen law's iron-path offset ``s_fe`` [m], when it has one."""
        return self.params.get("s_fe")

    def note_kinds(self) -> list[tuple[str, tuple[str, ...]]]:
        """The runs' notes once per kind (the same text but for its numbers and its run's
        path), the kinds the most runs carry first (else in the order met): the first note of
        each kind, without its run's path, and the runs that carry it."""
        kinds: dict[str, tuple[str, list[str]]] = {}
        for run in self.runs:
            for note in run.estimate.notes:
                text = re.sub(r"^run '[^']*': ", "", note)
                key = re.sub(r"[-+]?\d[\d.]*(e[-+]?\d+)?", "#", text)
                kinds.setdefault(key, (text, []))[1].append(run.name)
        ranked = sorted(kinds.values(), key=lambda kind: -len(kind[1]))   # stable: first first
        return [(text, tuple(names)) for text, names in ranked]

    def __repr__(self) -> str:
        """One line: the law, its parameters with standard uncertainties, the runs."""
        std = self.calibration.stderr
        params = ", ".join(f"{n} = {v:.6g} ± {s:.2g}" for (n, v), s
                           in zip(self.params.items(), std, strict=True))
        return (f"CampaignResult(law '{self.law}': {params}; {len(self.runs)} runs from "
                f"'{self.manifest}')")

    def _repr_html_(self) -> str:
        """The same line for notebooks."""
        from html import escape

        return f"<p>{escape(repr(self))}</p>"

    def to_json(self) -> dict[str, Any]:
        """The calibration file's content.

        :meth:`forcecal.actuator.Calibration.to_json` at the top level (so
        :meth:`forcecal.actuator.Calibration.load` reads it) plus the campaign's scores,
        comparison and runs.

        Returns
        -------
        dict
            JSON-ready: non-finite numbers are None.
        """
        doc = self.calibration.to_json()
        doc["chosen"] = _chosen_json(self.selection)
        doc["k_total"] = _k_total_json(self)
        doc["reactions_only"] = _reactions_json(self.reactions_only)
        doc["repeatability"] = {
            "k_total_rel_std": self.repeatability.k_total_rel_std,
            "mean_force_rel_std": self.repeatability.mean_force_rel_std,
            "amplitude_rel_std": self.repeatability.amplitude_rel_std,
            "groups": [dict(g) for g in self.repeatability.groups],
        }
        if self.uncertainty is not None:
            doc["uncertainty"] = self.uncertainty.to_json(
                self.n_poles if self.k_total is not None else None)
        doc["campaign"] = _campaign_json(self)
        doc["runs"] = [_run_json(r, k, self.run_residual[k]) for k, r in enumerate(self.runs)]
        return _json_ready(doc)


# --------------------------------------------------------------------------------------------
# JSON


def _chosen_json(selection: Selection) -> dict[str, Any]:
    """The chosen law and why."""
    return {
        "law": selection.chosen,
        "reason": selection.reason,
        "held_out_tolerance": selection.tolerance,
        "held_out_scheme": selection.best.held_out.scheme,
    }


def _k_total_json(result: CampaignResult) -> dict[str, Any]:
    """K_total with its uncertainty, beside the ideal value."""
    unc = result.uncertainty
    extra: dict[str, Any] = {}
    if unc is not None and result.k_total is not None:
        k = unc.param_names.index("K")
        extra = {"stderr_statistical": result.n_poles * float(np.sqrt(unc.statistical[k, k])),
                 "expanded": result.n_poles * float(unc.expanded[k]),
                 "coverage_factor": unc.coverage_factor}
    return {
        "value": result.k_total,
        "stderr": result.k_total_std,
        **extra,
        "ideal": result.ideal_k,
        "ratio_to_ideal": (
            None
            if result.k_total is None or not result.ideal_k
            else result.k_total / result.ideal_k
        ),
        "n_poles": result.n_poles,
        "note": "K_total = n_poles * K (K is per pole); ideal = mu0 N^2 A / 4 from the rig; "
        "stderr is the combined standard uncertainty (statistical and type B), expanded = k u",
    }


def _campaign_json(result: CampaignResult) -> dict[str, Any]:
    """What the campaign was made of."""
    return {
        "manifest": result.manifest,
        "n_runs": len(result.runs),
        "tares": list(result.tares),
        "ac_only": result.ac_only,
        "samples_per_period": result.samples_per_period,
        "n_observations": len(result.runs) * result.samples_per_period,
        "dc_deflection": "probes' DC (minus the tare's) fitted with Re of the fundamental's "
        "shape as a quasi-static shape",
    }


def _reactions_json(ro: ReactionsOnly) -> dict[str, Any]:
    """The reactions-only comparison."""
    if ro.selection is None:
        return {"error": ro.error}
    rows = [c.row() for c in ro.selection.candidates]
    rows += [{"law": name, "skipped": why} for name, why in ro.selection.skipped]
    return {
        "chosen": ro.selection.chosen,
        "candidates": rows,
        "k_total": ro.k_total,
        "k_total_error": ro.k_total_error,
        "s_fe": ro.s_fe,
        "force_error_rms": ro.force_error,
        "note": "the candidate laws fitted to the reactions-only force (inertia ignored); "
        "k_total, s_fe and force_error_rms are those of the law chosen for the corrected force",
    }


def _run_json(r: RunResult, k: int, residual: float) -> dict[str, Any]:
    """The summary of one run."""
    est, smp = r.estimate, r.samples
    total = smp.force
    return {
        "run": r.name,
        "file": str(r.entry.run),
        "group": k,
        "static_gap": smp.motion.static_gap.tolist(),
        "labels": dict(r.entry.labels),
        "tare": r.tare,
        "f0_hz": est.f0,
        "mean_force": float(est.total[0].real),
        "fundamental_amplitude": float(abs(est.total[1])) if est.total.size > 1 else 0.0,
        "force_range": [float(total.min()), float(total.max())],
        "inertia_share": est.inertia_share if est.total.size > 1 else 0.0,
        "current_range": [float(smp.current.min()), float(smp.current.max())],
        "gap_range": [float(smp.gaps.min()), float(smp.gaps.max())],
        "dc_deflection": smp.motion.dc.tolist(),
        "dc_misfit": smp.motion.dc_misfit,
        "residual_rms": float(residual),
        "notes": list(est.notes),
    }


def _json_ready(obj: Any) -> Any:
    """Replace non-finite floats by None and NumPy scalars by Python ones."""
    if isinstance(obj, dict):
        return {str(k): _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _json_ready(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        x = float(obj)
        return x if math.isfinite(x) else None
    return obj


# --------------------------------------------------------------------------------------------
# Output


def write_calibration(result: CampaignResult, out_dir: str | Path) -> Path:
    """Write ``OUT/calibration.json`` atomically.

    The file is readable by :meth:`forcecal.actuator.Calibration.load` (and
    :func:`load_calibration`): the chosen law's calibration sits at the top level, the
    campaign's scores, reactions-only comparison, repeatability and per-run summary beside it.

    Parameters
    ----------
    result : CampaignResult
        The campaign's calibration.
    out_dir : str or Path
        The folder to write in.

    Returns
    -------
    Path
        The path written.
    """
    path = Path(out_dir) / "calibration.json"
    text = json.dumps(result.to_json(), indent=2, allow_nan=False)
    return write_text_atomic(path, text + "\n")


def load_calibration(path: str | Path) -> Calibration:
    """The calibration of a ``calibration.json``.

    Parameters
    ----------
    path : str or Path
        A file written by :func:`write_calibration` (or by
        :meth:`forcecal.actuator.Calibration.save`).

    Returns
    -------
    Calibration
        The chosen law's calibration.

    Raises
    ------
    InputError
        Naming the file, when it is missing, not JSON, or lacks a key.
    """
    return Calibration.load(path)


def _k_total_line(result: CampaignResult) -> str | None:
    """K_total beside the ideal, when the chosen law has a K."""
    if result.k_total is None:
        return None
    kt = f"K_total = n_poles * K = {result.k_total:.6g} +/- {result.k_total_std:.2g} N m^2/A^2"
    if result.ideal_k:
        kt += (
            f"; ideal mu0 N^2 A / 4 = {result.ideal_k:.6g} "
            f"(ratio {result.k_total / result.ideal_k:.4f})"
        )
    return kt


def _uncertainty_lines(result: CampaignResult) -> list[str]:
    """The parameters' combined and expanded uncertainties and their budget."""
    unc = result.uncertainty
    if unc is None:
        return []
    law = result.calibration.law_object
    k = unc.coverage_factor
    lines = ["parameter uncertainties (statistical: the runs' phasor noise, the runs' samples "
             "not independent; type B: the rig's, systematic over the runs):"]
    for j, (name, unit) in enumerate(zip(law.param_names, law.param_units, strict=True)):
        stat = float(np.sqrt(unc.statistical[j, j]))
        tb = float(np.sqrt(unc.type_b[j, j]))
        lines.append(f"  {name} = {result.calibration.params[j]:.6g} {unit}: u = "
                     f"{unc.stderr[j]:.2g} (statistical {stat:.2g}, type B {tb:.2g}), "
                     f"U (k = {k:g}) = {unc.expanded[j]:.2g}")
    for source, std in unc.budget.items():
        parts = ", ".join(f"{n} {v:.2g}" for n, v in zip(law.param_names, std, strict=True))
        lines.append(f"    {source} ({unc.kinds.get(source, '')}): {parts}")
    if len(law.param_names) > 1:
        corr = unc.correlation
        pairs = [f"{a}-{b} {corr[i, j]:+.3f}" for i, a in enumerate(law.param_names)
                 for j, b in enumerate(law.param_names) if j > i]
        lines.append("  correlation: " + ", ".join(pairs))
    return lines


def _reactions_line(ro: ReactionsOnly) -> str:
    """How far a calibration ignoring the inertia is."""
    if ro.selection is None:
        return f"reactions-only: no law could be fitted ({ro.error})"
    text = f"reactions-only (inertia ignored): chooses '{ro.selection.chosen}'"
    if ro.k_total_error is not None:
        text += f"; K_total off by {100 * ro.k_total_error:+.2f} %"
    if ro.s_fe is not None:
        text += f"; s_fe = {1e6 * ro.s_fe:.2f} um"
    if ro.force_error is not None:
        text += f"; force off by {100 * ro.force_error:.2f} % RMS"
    return text


def _repeatability_line(rep: Repeatability) -> str:
    """The pooled spreads over the repeated setpoints."""
    if not rep.groups:
        return "repeatability: no setpoint was repeated"
    parts = []
    if rep.k_total_rel_std is not None:
        parts.append(f"K {100 * rep.k_total_rel_std:.3f} %")
    if rep.mean_force_rel_std is not None:
        parts.append(f"mean force {100 * rep.mean_force_rel_std:.3f} %")
    if rep.amplitude_rel_std is not None:
        parts.append(f"amplitude {100 * rep.amplitude_rel_std:.3f} %")
    return f"repeatability over {len(rep.groups)} repeated setpoint(s): " + ", ".join(parts)


def report_text(result: CampaignResult) -> str:
    """A plain-text summary of a campaign's calibration.

    Parameters
    ----------
    result : CampaignResult
        The campaign's calibration.

    Returns
    -------
    str
        Lines separated by newlines, ending with a newline.
    """
    lines = [selection_text(result.selection).rstrip("\n")]
    kt = _k_total_line(result)
    if kt is not None:
        lines.append(kt)
    if result.s_fe is not None:
        lines.append(f"s_fe = {1e6 * result.s_fe:.2f} um")
    lines += _uncertainty_lines(result)
    lines.append(_reactions_line(result.reactions_only))
    lines.append(_repeatability_line(result.repeatability))
    return "\n".join(lines) + "\n"
