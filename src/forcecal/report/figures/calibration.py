"""The actuator calibration (the paper's fig. 9): the law against the campaign's forces.

:class:`CalibrationPoints` holds one point per run of a campaign; :func:`law_harmonics` gives a
law's mean and fundamental force over one run; :func:`fig_calibration` draws the measured
forces against the law evaluated at their own current and gaps (the collapse), their relative
difference with the law's uncertainty, and the runs' mean and fundamental force against the DC
current.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ...actuator import Calibration, ExtrapolationWarning, Selection, predict
from ...errors import DimensionError, InputError
from ...forces.steady import ForceEstimate, channels_si
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import fit_harmonics
from ..cells import lab_unit, plus_minus
from ._common import (
    MARKERS,
    law_at,
    law_cycle,
    law_harmonics,
    math_unit,
    panel_title,
    running_max,
)

if TYPE_CHECKING:
    from ...campaign import CampaignResult

__all__ = ["CalibrationPoints", "fig_calibration", "law_harmonics"]

_DASHES = ("-", "--", "-.", ":")


# --------------------------------------------------------------------------------------------
# the data drawn


@dataclass(frozen=True)
class CampaignSamples:
    """The calibration samples of a campaign's runs, pooled (``n`` samples).

    Attributes
    ----------
    current : numpy.ndarray
        ``(n,)`` [A] coil current.
    gaps : numpy.ndarray
        ``(n, n_poles)`` [m] instantaneous air gap at every pole.
    force : numpy.ndarray
        ``(n,)`` [N] reconstructed total force (reactions and inertia).
    static_force : numpy.ndarray
        ``(n,)`` [N] reactions-only total force.
    run : numpy.ndarray
        ``(n,)`` int: the run (index into the points) of every sample.
    static_label : str
        The legend of the reactions-only samples.
    flux : numpy.ndarray or None
        ``(n,)`` [Wb] the flux through one pole, where the runs carry it (for the flux law).
    """

    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    static_force: np.ndarray
    run: np.ndarray
    static_label: str = "reactions only (inertia ignored)"
    flux: np.ndarray | None = None


@dataclass(frozen=True)
class CalibrationPoints:
    """One point per run of a calibration campaign, for :func:`fig_calibration`.

    Attributes
    ----------
    gap : numpy.ndarray
        ``(n_runs,)`` [m] static air gap of the run (every pole).
    dc : numpy.ndarray
        ``(n_runs,)`` [A] mean coil current I_0.
    ac : numpy.ndarray
        ``(n_runs,)`` [A] amplitude of the current's fundamental |I_1|.
    force_dc : numpy.ndarray
        ``(n_runs,)`` [N] mean total actuator force F_0 (the estimate's ``total[0]``).
    force_ac : numpy.ndarray
        ``(n_runs,)`` [N] amplitude of the total force's fundamental |F_1|.
    force_dc_std : numpy.ndarray or None
        ``(n_runs,)`` [N] standard uncertainty of F_0 (error bars).
    force_ac_std : numpy.ndarray or None
        ``(n_runs,)`` [N] standard uncertainty of |F_1| (error bars).
    law_dc : numpy.ndarray or None
        ``(n_runs,)`` [N] the calibrated law's mean total force for each run's own
        instantaneous current and gaps (see :func:`law_harmonics`). It includes the
        structure's motion, which closes the gap during a run; without it the law can only be
        drawn at the static gap. Given together with ``law_ac``.
    law_ac : numpy.ndarray or None
        ``(n_runs,)`` [N] the law's fundamental amplitude of the total force, alike.
    names : tuple of str
        Run names (one per run) or empty.
    samples : CampaignSamples or None
        The calibration samples of every run (:meth:`from_campaign`), for the collapse panel.
    """

    gap: np.ndarray
    dc: np.ndarray
    ac: np.ndarray
    force_dc: np.ndarray
    force_ac: np.ndarray
    force_dc_std: np.ndarray | None = None
    force_ac_std: np.ndarray | None = None
    law_dc: np.ndarray | None = None
    law_ac: np.ndarray | None = None
    names: tuple[str, ...] = ()
    samples: CampaignSamples | None = None

    def __post_init__(self) -> None:
        n = None
        for key in ("gap", "dc", "ac", "force_dc", "force_ac", "force_dc_std", "force_ac_std",
                    "law_dc", "law_ac"):
            value = getattr(self, key)
            if value is None:
                continue
            arr = np.atleast_1d(np.asarray(value, dtype=float))
            n = arr.shape[0] if n is None else n
            if arr.shape != (n,):
                raise DimensionError(f"calibration points: '{key}' has shape {arr.shape}; "
                                     f"expected ({n},), one value per run")
            object.__setattr__(self, key, arr)
        if n == 0:
            raise InputError("calibration points: no runs")
        if not np.all(self.gap > 0):
            raise InputError("calibration points: every 'gap' must be a positive length [m]")
        if (self.law_dc is None) != (self.law_ac is None):
            raise InputError("calibration points: give both 'law_dc' and 'law_ac' or neither")
        names = tuple(str(s) for s in self.names)
        if names and len(names) != n:
            raise DimensionError(f"calibration points: {len(names)} names for {n} runs")
        object.__setattr__(self, "names", names)
        if self.samples is not None and int(self.samples.run.max()) >= self.gap.size:
            raise DimensionError("calibration points: samples of run "
                                 f"{self.samples.run.max()} but {self.gap.size} runs")

    @classmethod
    def from_campaign(cls, result: CampaignResult) -> CalibrationPoints:
        """Points of a campaign's runs, with the law at each run's own current and gaps and
        every run's calibration samples (for the collapse panel).

        Parameters
        ----------
        result : CampaignResult
            The campaign's calibration.

        Returns
        -------
        CalibrationPoints
            One point per run, in manifest order.
        """
        dc, ac, law_dc, law_ac = [], [], [], []
        for r in result.runs:
            smp, f0 = r.samples, r.estimate.f0
            fs = smp.n * f0                             # the samples span one period evenly
            current = fit_harmonics(smp.current, fs, f0, 1, t0=smp.time[0]).phasors
            dc.append(current[0].real)
            ac.append(abs(current[1]))
            a, b = law_harmonics(result.calibration, smp.current, smp.gaps, fs, f0,
                                 t0=smp.time[0], flux=smp.flux)
            law_dc.append(a)
            law_ac.append(b)
        est = [r.estimate for r in result.runs]
        ro, label = result.reactions_only, "reactions only (inertia ignored)"
        if ro.k_total_error is not None:
            label += f": K off by {100 * ro.k_total_error:+.1f} %"
        samples = CampaignSamples(
            current=np.concatenate([r.samples.current for r in result.runs]),
            gaps=np.vstack([r.samples.gaps for r in result.runs]),
            force=np.concatenate([r.samples.force for r in result.runs]),
            static_force=np.concatenate([r.samples.static_force for r in result.runs]),
            run=np.concatenate([np.full(r.samples.n, k) for k, r in enumerate(result.runs)]),
            static_label=label,
            flux=(np.concatenate([r.samples.flux for r in result.runs])
                  if all(r.samples.flux is not None for r in result.runs) else None))
        return cls(
            gap=np.array([r.samples.static_gap for r in result.runs]), dc=np.array(dc),
            ac=np.array(ac), force_dc=np.array([e.total[0].real for e in est]),
            force_ac=np.array([abs(e.total[1]) for e in est]),
            force_dc_std=np.array([e.total_std[0] for e in est]),
            force_ac_std=np.array([e.total_std[1] for e in est]), law_dc=np.array(law_dc),
            law_ac=np.array(law_ac), names=tuple(r.name for r in result.runs), samples=samples)

    @property
    def n_runs(self) -> int:
        """The number of runs."""
        return int(self.gap.shape[0])

    @classmethod
    def from_estimates(cls, rig: Rig, runs: Sequence[Run], estimates: Sequence[ForceEstimate],
                       gaps: Sequence[float] | None = None) -> CalibrationPoints:
        """Points from runs and their force estimates.

        The current's mean and fundamental amplitude are fitted from each run's current channel
        (the rig's scale applied) at the estimate's fundamental; the force's are the estimate's
        total phasors. Add the law's values per run with
        ``dataclasses.replace(points, law_dc=..., law_ac=...)`` (see :func:`law_harmonics`).

        Parameters
        ----------
        rig : Rig
            The rig of the campaign (current channel and scale, the force points' gap).
        runs : Sequence of Run
            The runs.
        estimates : Sequence of ForceEstimate
            Their forces, one per run.
        gaps : Sequence of float, optional
            [m] each run's static gap (e.g. the manifest's ``gap``); None takes the rig's
            first force point's gap.

        Returns
        -------
        CalibrationPoints
            One point per run.
        """
        if len(runs) != len(estimates):
            raise DimensionError(f"{len(runs)} runs but {len(estimates)} estimates")
        if gaps is None:
            gap0 = rig.forces[0].gap if rig.forces else None
            if gap0 is None:
                raise InputError(f"rig '{rig.source}': no static gap for the calibration points; "
                                 "give 'gap' in [[forces]] or pass gaps")
            gaps = [gap0] * len(runs)
        if len(gaps) != len(runs):
            raise DimensionError(f"{len(gaps)} gaps for {len(runs)} runs")
        dc, ac = [], []
        for run, est in zip(runs, estimates, strict=True):
            current = channels_si(rig, run)[rig.actuator.current]
            fit = fit_harmonics(current, run.fs, est.f0, 1, t0=run.t0)
            dc.append(fit.phasors[0].real)
            ac.append(abs(fit.phasors[1]))
        return cls(
            gap=np.asarray(gaps, dtype=float), dc=np.array(dc), ac=np.array(ac),
            force_dc=np.array([e.total[0].real for e in estimates]),
            force_ac=np.array([abs(e.total[1]) for e in estimates]),
            force_dc_std=np.array([e.total_std[0] for e in estimates]),
            force_ac_std=np.array([e.total_std[1] for e in estimates]),
            names=tuple(e.run_name for e in estimates),
        )


@dataclass(frozen=True)
class _Law:
    """A (current, gap) law as drawn: the calibration and its (F_0, |F_1|) [N] at every run.

    ``at_runs``: the values are at each run's own instantaneous current and gaps; otherwise at
    the static gap, the structure's motion neglected.
    """

    cal: Calibration
    dc: np.ndarray
    ac: np.ndarray
    at_runs: bool


def _drawn_law(cal: Calibration | None, pts: CalibrationPoints) -> _Law | None:
    """The law drawn against current, or None (no law; a law that predicts from flux without
    its values at the runs' own flux)."""
    if cal is None:
        return None
    if pts.law_dc is not None and pts.law_ac is not None:
        return _Law(cal, pts.law_dc, pts.law_ac, at_runs=True)
    if cal.law_object.needs_flux:
        return None
    dc, ac = np.empty(pts.n_runs), np.empty(pts.n_runs)
    for k in range(pts.n_runs):
        mean, fund = law_cycle(cal, pts.dc[k:k + 1], float(pts.ac[k]), float(pts.gap[k]))
        dc[k], ac[k] = mean[0], fund[0]
    return _Law(cal, dc, ac, at_runs=False)


def _clusters(values: np.ndarray, tol: float) -> np.ndarray:
    """Cluster label per value; neighbours (sorted) closer than ``tol`` share a label."""
    order = np.argsort(values)
    labels = np.empty(len(values), dtype=int)
    current = 0
    for j, i in enumerate(order):
        if j and values[i] - values[order[j - 1]] > tol:
            current += 1
        labels[i] = current
    return labels


@dataclass(frozen=True)
class _Group:
    """The runs of one static gap (one colour) and one AC amplitude (one marker and dash)."""

    sel: np.ndarray     # (n_runs,) bool: the group's runs
    gap: float          # [m] mean static gap of every run at this gap
    amp: float          # [A] mean AC amplitude of the group's runs
    gap_index: int
    ac_index: int

    @property
    def color(self) -> str:
        return f"C{self.gap_index % 10}"

    @property
    def marker(self) -> str:
        return MARKERS[self.ac_index % len(MARKERS)]

    @property
    def dash(self) -> str:
        return _DASHES[self.ac_index % len(_DASHES)]

    @property
    def tag(self) -> str:
        return f"gap {self.gap * 1e3:.2f} mm, AC {self.amp:.3g} A"


def _setpoints(pts: CalibrationPoints) -> tuple[np.ndarray, np.ndarray]:
    """Cluster labels of the runs' static gaps and of their AC amplitudes, (n_runs,) each."""
    gap_id = _clusters(pts.gap, 1e-3 * float(np.median(pts.gap)))
    ac_id = _clusters(pts.ac, 0.05 * max(float(np.max(pts.ac)), 1e-12))
    return gap_id, ac_id


def _groups(pts: CalibrationPoints, gap_id: np.ndarray, ac_id: np.ndarray) -> list[_Group]:
    """The non-empty groups of runs, by gap then by AC amplitude."""
    groups = []
    for g in range(gap_id.max() + 1):
        in_gap = gap_id == g
        gap = float(np.mean(pts.gap[in_gap]))
        for a in range(ac_id.max() + 1):
            sel = in_gap & (ac_id == a)
            if sel.any():
                groups.append(_Group(sel, gap, float(np.mean(pts.ac[sel])), g, a))
    return groups


# --------------------------------------------------------------------------------------------
# the figure


def fig_calibration(points: CalibrationPoints | Mapping[str, Any],
                    law: Calibration | Selection | None = None) -> Figure:
    """The calibrated law against the campaign's forces, each at its own conditions (fig. 9).

    With a (current, gap) law, the top row is the collapse: left, the measured total force of
    every calibration sample against the law evaluated at that sample's own current and
    instantaneous gaps (:func:`forcecal.actuator.predict`), on the line measured = law; right,
    their relative difference against the law with the law's +-2 sigma band (its parameters'
    uncertainty) on that scale. Without the campaign's samples, each run's mean force F_0
    stands for its samples.

    Below, as the paper draws it: the mean total force F_0 (left) and the amplitude of its
    fundamental |F_1| (right) against the DC current I_0, one colour per static gap, one
    marker per AC amplitude, one open marker per run with +-2 sigma bars (a count beside
    repeated runs); the law as a small filled marker per run, joined per gap and AC amplitude:

    - at each run's own instantaneous current and gaps when ``points`` carries ``law_dc`` and
      ``law_ac`` (:func:`law_harmonics`), as it does from a campaign;
    - otherwise as curves over one cycle of i = I_0 + I_1 cos(theta) at the static gap (the
      structure's motion, which closes the gap during a run, neglected, as the legend says).

    Parameters
    ----------
    points : CalibrationPoints or Mapping of str to array_like
        The runs' points (e.g. from :meth:`CalibrationPoints.from_campaign`), or a mapping
        with its field names (gap, dc, ac, force_dc, force_ac, ...).
    law : Calibration or Selection, optional
        The calibration (or the selection whose chosen law is drawn); None draws the F_0 and
        |F_1| points only. A flux law cannot be drawn against current: it is named in a note.

    Returns
    -------
    matplotlib.figure.Figure
        4 axes (collapse, relative difference [%], F_0, |F_1|) with a (current, gap) law, else 2
        (F_0, |F_1|). The runs' error bars are labelled "gap G mm, AC A A" (x: A, y: N); the
        law's lines "law at gap G mm, AC A A" (at each run's own conditions) or "law gap G mm,
        AC A A" (at the static gap); in the collapse, the law "law (measured = law)", the
        runs' samples "measured, run NAME" (x: the law [N], y: measured [N]); in the
        difference panel the band "law ±2σ" and the runs' "run NAME" (y: %).
    """
    pts = points if isinstance(points, CalibrationPoints) else CalibrationPoints(**points)
    cal = law.calibration() if isinstance(law, Selection) else law
    drawn = _drawn_law(cal, pts)
    gap_id, ac_id = _setpoints(pts)
    fig = Figure(figsize=(12.0, 5.6) if drawn is None else (12.0, 10.5), layout="constrained")
    grid = fig.add_gridspec(1 if drawn is None else 2, 2)
    row = 0 if drawn is None else 1
    ax0 = fig.add_subplot(grid[row, 0])
    ax1 = fig.add_subplot(grid[row, 1], sharex=ax0)
    fig.suptitle(_calibration_title(pts, cal, int(gap_id.max()) + 1))
    for group in _groups(pts, gap_id, ac_id):
        _draw_group(ax0, ax1, pts, group, drawn)
    _label_runs(ax0, ax1, cal, drawn)
    if drawn is not None:
        col = _collapse(pts, drawn)
        _draw_collapse(fig.add_subplot(grid[0, 0]), col, gap_id, ac_id, pts)
        _draw_difference(fig.add_subplot(grid[0, 1]), col, gap_id, ac_id, pts)
    for ax in fig.axes:
        ax.grid(alpha=0.3)
    handles = _legend_handles(pts, gap_id, ac_id, drawn)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 4),
               fontsize="small")
    return fig


def _draw_group(ax0: Axes, ax1: Axes, pts: CalibrationPoints, group: _Group,
                law: _Law | None) -> None:
    """A group's runs as open markers on F_0 (``ax0``) and |F_1| (``ax1``), and the law."""
    sel = group.sel
    for ax, force, std in ((ax0, pts.force_dc, pts.force_dc_std),
                           (ax1, pts.force_ac, pts.force_ac_std)):
        ax.errorbar(pts.dc[sel], force[sel], yerr=_err(std, sel), fmt=group.marker,
                    color=group.color, ms=8, mfc="none", mew=1.4, capsize=2, label=group.tag)
    _mark_repeats(ax0, pts.dc[sel], pts.force_dc[sel])
    _mark_repeats(ax1, pts.dc[sel], pts.force_ac[sel])
    if law is not None:
        _draw_group_law(ax0, ax1, pts, group, law)


def _draw_group_law(ax0: Axes, ax1: Axes, pts: CalibrationPoints, group: _Group,
                    law: _Law) -> None:
    """The law at each of the group's runs' own conditions (small filled markers, joined), or
    else its curves at the group's static gap."""
    if law.at_runs:
        order = np.argsort(pts.dc[group.sel])
        for ax, values in ((ax0, law.dc), (ax1, law.ac)):
            ax.plot(pts.dc[group.sel][order], values[group.sel][order], "-", lw=0.9,
                    color=group.color, marker=group.marker, ms=3.5, zorder=3,
                    label=f"law at {group.tag}")
        return
    lo = max(law.cal.current_range[0] + group.amp, 0.0)
    hi = law.cal.current_range[1] - group.amp
    if hi > lo:
        grid = np.linspace(lo, hi, 60)
        mean, fund = law_cycle(law.cal, grid, group.amp, group.gap)
        ax0.plot(grid, mean, group.dash, color=group.color, lw=1.2, label=f"law {group.tag}")
        ax1.plot(grid, fund, group.dash, color=group.color, lw=1.2, label=f"law {group.tag}")


def _label_runs(ax0: Axes, ax1: Axes, cal: Calibration | None, law: _Law | None) -> None:
    """Labels and titles of the F_0 and |F_1| panels; a note for a law drawn from flux."""
    if cal is not None and law is None:
        ax0.text(0.02, 0.98, f"law '{cal.law}' predicts from flux:\nno curve against current",
                 transform=ax0.transAxes, va="top", fontsize="small")
    where = ("" if law is None else f" (law: at each run's own {_inputs(law.cal)})"
             if law.at_runs else " (law: at the static gap, motion neglected)")
    ax0.set_ylabel("mean force $F_0$ [N]")
    panel_title(ax0, "Mean total force vs DC current" + where)
    ax1.set_ylabel("fundamental amplitude $|F_1|$ [N]")
    panel_title(ax1, "Fundamental of the total force vs DC current")
    for ax in (ax0, ax1):
        ax.set_xlabel("DC current $I_0$ [A]")


def _legend_handles(pts: CalibrationPoints, gap_id: np.ndarray, ac_id: np.ndarray,
                    law: _Law | None) -> list[Line2D | Patch]:
    """The figure legend: every colour, marker and line the panels draw."""
    handles: list[Line2D | Patch] = []
    for g in range(gap_id.max() + 1):
        gap = float(np.mean(pts.gap[gap_id == g]))
        handles.append(Line2D([], [], color=f"C{g % 10}", lw=6, alpha=0.6,
                              label=f"static gap {gap * 1e3:.2f} mm"))
    fallback = law is not None and not law.at_runs
    for a in range(ac_id.max() + 1):
        amp = float(np.mean(pts.ac[ac_id == a]))
        handles.append(Line2D([], [], color="0.3", marker=MARKERS[a % len(MARKERS)],
                              mfc="none", ls=_DASHES[a % len(_DASHES)] if fallback else "none",
                              label=f"AC {amp:.3g} A" + (" (law's dash)" if fallback else "")))
    handles.append(Line2D([], [], color="0.3", marker="o", mfc="none", ms=8, ls="none",
                          label="run, measured (±2σ bars)"))
    if law is None:
        return handles
    handles.append(Line2D([], [], color="0.3", marker="o" if law.at_runs else "none", ms=3.5,
                          lw=0.9, label=f"law at each run's own {_inputs(law.cal)}" if law.at_runs
                          else "law at the static gap (the structure's motion neglected)"))
    handles.append(Line2D([], [], color="k", lw=1.2, label="law (measured = law)"))
    handles.append(Patch(color="0.5", alpha=0.3, label="law ±2σ (its parameters' uncertainty)"))
    if pts.samples is not None:
        handles.append(Line2D([], [], color="0.45", marker="x", ls="none", ms=4,
                              label=pts.samples.static_label))
    return handles


def _calibration_title(pts: CalibrationPoints, cal: Calibration | None, n_gaps: int) -> str:
    """The figure title: runs and gaps, and the law's formula and parameters."""
    title = f"Actuator calibration: {pts.n_runs} runs at {n_gaps} gaps"
    if cal is None:
        return title
    law = cal.law_object
    params = [f"{n} = {_param(v, e, u)}" for n, v, e, u in
              zip(law.param_names, cal.params, cal.stderr, law.param_units, strict=True)]
    lines = [title, f"law '{cal.law}': {math_unit(law.formula)}"]
    for start in range(0, len(params), 3):
        lines.append("; ".join(params[start:start + 3]))
    return "\n".join(lines)


def _param(value: float, std: float, unit: str) -> str:
    """A parameter ± its standard uncertainty, in the unit a laboratory writes (math text)."""
    factor, shown = lab_unit(value, unit)
    return f"{plus_minus(value * factor, std * factor)} {math_unit(shown)}".strip()


def _err(std: np.ndarray | None, sel: np.ndarray) -> np.ndarray | None:
    """The selected +-2 sigma error bars, or None without uncertainties."""
    return None if std is None else 2 * std[sel]


def _mark_repeats(ax: Axes, x: np.ndarray, y: np.ndarray) -> None:
    """Write the count beside markers of runs with the same setpoint (x within 2 %)."""
    ids = _clusters(x, 0.02 * max(float(np.max(np.abs(x))), 1e-12))
    for c in range(ids.max() + 1 if len(ids) else 0):
        sel = ids == c
        if sel.sum() > 1:
            ax.annotate(f"×{int(sel.sum())}", (float(np.mean(x[sel])), float(np.mean(y[sel]))),
                        textcoords="offset points", xytext=(7, -3), fontsize="small")


# --------------------------------------------------------------------------------------------
# the collapse: measured against the law at its own conditions


@dataclass(frozen=True)
class _Collapse:
    """The points of the collapse: the law at each point's own conditions and its standard
    uncertainty, the measured force, the reactions-only force, all [N], the run of each.

    ``samples``: the points are the campaign's samples; otherwise each run's mean force F_0,
    with the law at the run's own conditions when ``own`` (else at its static gap).
    """

    law: np.ndarray
    law_std: np.ndarray
    force: np.ndarray
    static: np.ndarray | None
    run: np.ndarray
    samples: bool
    own: bool
    inputs: str = "current and gaps"


def _inputs(cal: Calibration) -> str:
    """What the law predicts from, for the labels."""
    return "flux" if cal.law_object.needs_flux else "current and gaps"


def _collapse(pts: CalibrationPoints, law: _Law) -> _Collapse:
    """The collapse's points: the campaign's samples, else each run's F_0."""
    if pts.samples is not None and (pts.samples.flux is not None
                                    or not law.cal.law_object.needs_flux):
        smp = pts.samples
        pred = law_at(law.cal, smp.current, smp.gaps, smp.flux)
        return _Collapse(pred.total, pred.std, smp.force, smp.static_force, smp.run,
                         samples=True, own=True, inputs=_inputs(law.cal))
    with warnings.catch_warnings():
        # the samples the law was fitted to may reach a little past the calibrated range
        warnings.simplefilter("ignore", ExtrapolationWarning)
        theta = 2 * np.pi * np.arange(64) / 64
        std = np.array([np.mean(predict(law.cal, pts.dc[k] + pts.ac[k] * np.cos(theta),
                                        float(pts.gap[k])).std) for k in range(pts.n_runs)])
    return _Collapse(law.dc, std, pts.force_dc, None, np.arange(pts.n_runs), samples=False,
                     own=law.at_runs)


def _run_style(k: int, gap_id: np.ndarray, ac_id: np.ndarray) -> dict[str, Any]:
    """The marker and colour of run k's points."""
    return {"marker": MARKERS[ac_id[k] % len(MARKERS)], "color": f"C{gap_id[k] % 10}",
            "mfc": "none", "ls": "none"}


def _draw_collapse(ax: Axes, col: _Collapse, gap_id: np.ndarray, ac_id: np.ndarray,
                   pts: CalibrationPoints) -> None:
    """Measured force against the law at each point's own conditions, on measured = law."""
    top = float(max(col.law.max(), col.force.max()))
    bottom = float(min(col.law.min(), col.force.min(), 0.0))
    ax.plot([bottom, top], [bottom, top], "-", color="k", lw=1.2, zorder=4,
            label="law (measured = law)")
    if col.static is not None:
        ax.plot(col.law, col.static, "x", color="0.45", ms=3.5, mew=0.8,
                label="reactions only (inertia ignored)")
    names = pts.names or tuple(str(k) for k in range(pts.n_runs))
    for k in range(pts.n_runs):
        sel = col.run == k
        ax.plot(col.law[sel], col.force[sel], ms=4 if col.samples else 7, mew=0.9, alpha=0.8,
                label=f"measured, run {names[k]}", **_run_style(k, gap_id, ac_id))
    ax.set_xlabel(_law_axis(col))
    ax.set_ylabel("measured total force [N]" if col.samples else "measured $F_0$ [N]")
    panel_title(ax, "Collapse: measured against the law at "
                + ("its own conditions" if col.own else "the static gap"))


def _law_axis(col: _Collapse) -> str:
    """The label of the law's axis: where the law is evaluated."""
    if col.samples:
        return f"law at each sample's own {col.inputs} [N]"
    return ("law's $F_0$ at each run's " + (f"own {col.inputs}" if col.own
                                            else "static gap (motion neglected)") + " [N]")


def _draw_difference(ax: Axes, col: _Collapse, gap_id: np.ndarray, ac_id: np.ndarray,
                     pts: CalibrationPoints) -> None:
    """(measured - law) / law [%] against the law, with the law's +-2 sigma band."""
    floor = 0.01 * max(float(np.median(np.abs(col.law))), 1e-12)
    scale = np.maximum(np.abs(col.law), floor)
    rel = 100 * (col.force - col.law) / scale
    order = np.argsort(col.law)
    band = 100 * 2 * running_max((col.law_std / scale)[order], max(len(order) // 40, 1))
    ax.fill_between(col.law[order], -band, band, color="0.5", alpha=0.3, lw=0,
                    label="law ±2σ")
    for edge in (-band, band):          # its edges drawn: visible however thin the band is
        ax.plot(col.law[order], edge, "-", color="0.25", lw=0.8, label="_nolegend_")
    ax.axhline(0.0, color="k", lw=1.0)
    names = pts.names or tuple(str(k) for k in range(pts.n_runs))
    for k in range(pts.n_runs):
        sel = col.run == k
        ax.plot(col.law[sel], rel[sel], ms=4 if col.samples else 7, mew=0.9, alpha=0.8,
                label=f"run {names[k]}", **_run_style(k, gap_id, ac_id))
    span = 1.15 * max(float(np.quantile(np.abs(rel), 0.99)), 2 * float(band.max()))
    ax.set_ylim(-span, span)
    beyond = int(np.sum(np.abs(rel) > span))
    note = f"RMS {np.sqrt(np.mean(rel**2)):.2g} %" + (f"; {beyond} beyond this scale"
                                                      if beyond else "")
    if col.static is not None:
        off = 100 * np.sqrt(np.mean(((col.static - col.law) / scale) ** 2))
        note += f"; reactions only: RMS {off:.2g} % (off this scale)"
    ax.text(0.01, 0.02, note, transform=ax.transAxes, fontsize="small", zorder=5,
            bbox={"facecolor": "white", "alpha": 0.85, "lw": 0})
    ax.set_xlabel(_law_axis(col))
    ax.set_ylabel("(measured − law) / law [%]")
    panel_title(ax, "Relative difference, beside the law's own uncertainty")
