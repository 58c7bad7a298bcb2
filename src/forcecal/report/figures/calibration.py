"""The actuator calibration (the paper's fig. 9): force against current for every gap.

:class:`CalibrationPoints` holds one point per run of a campaign; :func:`law_harmonics` gives a
law's mean and fundamental force over one run; :func:`fig_calibration` draws the points with
the calibrated law and their residuals against it.
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

from ...actuator import Calibration, ExtrapolationWarning, Selection, predict
from ...errors import DimensionError, InputError
from ...forces.steady import ForceEstimate, channels_si
from ...records import Run
from ...rig import Rig
from ...signals.harmonics import fit_harmonics
from ._common import MARKERS, law_argument, law_cycle, law_harmonics, panel_title, running_max

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
    """

    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    static_force: np.ndarray
    run: np.ndarray
    static_label: str = "reactions only (inertia ignored)"


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
                                 t0=smp.time[0])
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
            static_label=label)
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
    """The law drawn against current, or None (no law, or a law that predicts from flux)."""
    if cal is None or cal.law_object.needs_flux:
        return None
    if pts.law_dc is not None and pts.law_ac is not None:
        return _Law(cal, pts.law_dc, pts.law_ac, at_runs=True)
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
    """Force against DC current and AC amplitude for every gap, with the calibrated law (fig. 9).

    Top left: the mean total force F_0 against the DC current I_0; top right: the amplitude of
    the force's fundamental |F_1| against I_0. One colour per static gap, one marker (and line
    style) per AC amplitude, one open marker per run, so that repeated runs show as overlapping
    markers (their count is written beside them).

    With a (current, gap) law, the bottom panels show each run's relative residual against the
    law, and the law is drawn in one of two ways:

    - when ``points`` carries ``law_dc`` and ``law_ac`` (the law at each run's own
      instantaneous current and gaps, :func:`law_harmonics`): as a small filled marker per run,
      joined by thin lines per gap and AC amplitude; the residuals are taken against them;
    - otherwise: as smooth curves of the law's total force (:func:`forcecal.actuator.predict`)
      over one cycle of i = I_0 + I_1 cos(theta) at the static gap, its mean and fundamental
      amplitude, over the calibrated current range. The structure's motion, which closes the
      gap during a run, is neglected there, which the legend and the residual panel say.

    Parameters
    ----------
    points : CalibrationPoints or Mapping of str to array_like
        The runs' points (e.g. from :meth:`CalibrationPoints.from_estimates`), or a mapping
        with its field names (gap, dc, ac, force_dc, force_ac, ...).
    law : Calibration or Selection, optional
        The calibration (or the selection whose chosen law is drawn); None draws the points
        only. A flux law cannot be drawn against current: it is named in a note, without
        curves.

    Returns
    -------
    matplotlib.figure.Figure
        4 axes (F_0, |F_1|, and their residuals in %) when a (current, gap) law is given,
        else 2. The runs' lines are labelled "gap G mm, AC A A" (x: A, y: N); the law's
        "law gap G mm, AC A A"; the residuals' lines carry the runs' labels (y: %).
    """
    pts = points if isinstance(points, CalibrationPoints) else CalibrationPoints(**points)
    cal = law.calibration() if isinstance(law, Selection) else law
    drawn = _drawn_law(cal, pts)
    gap_id, ac_id = _setpoints(pts)
    fig = Figure(figsize=(12.0, 5.5) if drawn is None else (17.0, 9.5), layout="constrained")
    # the F_0 and |F_1| panels, below them their residuals against a drawn law, and beside
    # them the collapse panel
    grid = fig.add_gridspec(1 if drawn is None else 2, 2 if drawn is None else 3,
                            height_ratios=None if drawn is None else (2.0, 1.0),
                            width_ratios=None if drawn is None else (1.0, 1.0, 1.25))
    axes = np.empty((grid.nrows, 2), dtype=object)
    for r, c in np.ndindex(axes.shape):
        axes[r, c] = fig.add_subplot(grid[r, c], sharex=None if r == 0 else axes[0, c])
    fig.suptitle(_calibration_title(pts, cal, int(gap_id.max()) + 1))
    for group in _groups(pts, gap_id, ac_id):
        _draw_group(axes[0, 0], axes[0, 1], pts, group, drawn)
        if drawn is not None:
            _draw_group_residuals(axes[1, 0], axes[1, 1], pts, group, drawn)
    _label_top(axes[0, 0], axes[0, 1], cal, drawn)
    if drawn is not None:
        _label_residuals(axes[1, 0], axes[1, 1], drawn.at_runs)
        for ax in axes[0]:
            ax.tick_params(labelbottom=False)
        _draw_collapse(fig.add_subplot(grid[:, 2]), pts, drawn.cal, gap_id, ac_id)
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
                    color=group.color, ms=7, mfc="none", mew=1.4, capsize=2, label=group.tag)
    _mark_repeats(ax0, pts.dc[sel], pts.force_dc[sel])
    _mark_repeats(ax1, pts.dc[sel], pts.force_ac[sel])
    if law is not None:
        _draw_group_law(ax0, ax1, pts, group, law)


def _draw_group_law(ax0: Axes, ax1: Axes, pts: CalibrationPoints, group: _Group,
                    law: _Law) -> None:
    """The law's smooth curve at the group's static gap and, when known, its value at each of
    the group's runs (small filled markers)."""
    if law.at_runs:
        order = np.argsort(pts.dc[group.sel])
        for ax, values in ((ax0, law.dc), (ax1, law.ac)):
            ax.plot(pts.dc[group.sel][order], values[group.sel][order], ls="none",
                    color=group.color, marker=group.marker, ms=3.5, label=f"law at {group.tag}")
    lo = max(law.cal.current_range[0] + group.amp, 0.0)
    hi = law.cal.current_range[1] - group.amp
    if hi > lo:
        grid = np.linspace(lo, hi, 60)
        mean, fund = law_cycle(law.cal, grid, group.amp, group.gap)
        ax0.plot(grid, mean, group.dash, color=group.color, lw=1.2, label=f"law {group.tag}")
        ax1.plot(grid, fund, group.dash, color=group.color, lw=1.2, label=f"law {group.tag}")


def _draw_group_residuals(rx0: Axes, rx1: Axes, pts: CalibrationPoints, group: _Group,
                          law: _Law) -> None:
    """A group's relative residuals [%] of F_0 (``rx0``) and |F_1| (``rx1``) against the law."""
    sel = group.sel
    for rx, measured, model in ((rx0, pts.force_dc, law.dc), (rx1, pts.force_ac, law.ac)):
        floor = 0.01 * max(float(np.median(np.abs(measured))), 1e-12)
        rel = (measured[sel] - model[sel]) / np.maximum(np.abs(model[sel]), floor)
        rx.plot(pts.dc[sel], 100 * rel, group.marker, color=group.color, ms=7, mfc="none",
                mew=1.4, label=group.tag)


def _label_top(ax0: Axes, ax1: Axes, cal: Calibration | None, law: _Law | None) -> None:
    """Labels and titles of the F_0 and |F_1| panels; a note for a law drawn from flux."""
    if cal is not None and law is None:
        ax0.text(0.02, 0.98, f"law '{cal.law}' predicts from flux:\nno curve against current",
                 transform=ax0.transAxes, va="top", fontsize="small")
    ax0.set_ylabel("mean force $F_0$ [N]")
    panel_title(ax0, "Mean total force vs DC current")
    ax1.set_ylabel("fundamental amplitude $|F_1|$ [N]")
    panel_title(ax1, "Fundamental of the total force vs DC current")
    if law is None:
        ax0.set_xlabel("DC current $I_0$ [A]")
        ax1.set_xlabel("DC current $I_0$ [A]")


def _label_residuals(rx0: Axes, rx1: Axes, at_runs: bool) -> None:
    """Zero lines, labels and the title of the residual panels."""
    for rx, what in ((rx0, "$F_0$"), (rx1, "$|F_1|$")):
        rx.axhline(0.0, color="0.5", lw=0.8)
        rx.set_ylabel(f"{what}: (run − law) / law [%]")
        rx.set_xlabel("DC current $I_0$ [A]")
    where = ("at each run's current and gap" if at_runs
             else "at the static gap (the structure's motion neglected)")
    panel_title(rx0, f"Residuals against the law {where}")


def _legend_handles(pts: CalibrationPoints, gap_id: np.ndarray, ac_id: np.ndarray,
                    law: _Law | None) -> list[Line2D]:
    """The figure legend: one colour per gap, one marker (and dash) per AC amplitude, the law."""
    handles = []
    for g in range(gap_id.max() + 1):
        gap = float(np.mean(pts.gap[gap_id == g]))
        handles.append(Line2D([], [], color=f"C{g % 10}", lw=2, label=f"gap {gap * 1e3:.2f} mm"))
    for a in range(ac_id.max() + 1):
        amp = float(np.mean(pts.ac[ac_id == a]))
        dash = _DASHES[a % len(_DASHES)] if law is not None else "none"
        handles.append(Line2D([], [], color="0.3", marker=MARKERS[a % len(MARKERS)],
                              mfc="none", ls=dash, label=f"AC {amp:.3g} A"))
    if law is not None:
        handles.append(Line2D([], [], color="0.3", ls="-", lw=1.2,
                              label="law at the static gap (motion neglected)"))
    if law is not None and law.at_runs:
        handles.append(Line2D([], [], color="0.3", marker="o", ms=3.5, ls="none",
                              label="law at each run's current and gap"))
    return handles


def _calibration_title(pts: CalibrationPoints, cal: Calibration | None, n_gaps: int) -> str:
    """The figure title: runs and gaps, and the law's formula and parameters."""
    title = f"Actuator calibration: {pts.n_runs} runs at {n_gaps} gaps"
    if cal is None:
        return title
    law = cal.law_object
    params = [f"{n} = {_param(v, e, u)}" for n, v, e, u in
              zip(law.param_names, cal.params, cal.stderr, law.param_units, strict=True)]
    lines = [title, f"law '{cal.law}': {law.formula}"]
    for start in range(0, len(params), 3):
        lines.append("; ".join(params[start:start + 3]))
    return "\n".join(lines)


def _param(value: float, std: float, unit: str) -> str:
    """A parameter with its standard uncertainty and unit."""
    unit = "" if unit in ("-", "1") else unit
    return f"{value:.5g} ± {std:.2g} {unit}".strip()


def _err(std: np.ndarray | None, sel: np.ndarray) -> np.ndarray | None:
    """The selected error bars, or None without uncertainties."""
    return None if std is None else std[sel]


def _mark_repeats(ax: Axes, x: np.ndarray, y: np.ndarray) -> None:
    """Write the count beside markers of runs with the same setpoint (x within 2 %)."""
    ids = _clusters(x, 0.02 * max(float(np.max(np.abs(x))), 1e-12))
    for c in range(ids.max() + 1 if len(ids) else 0):
        sel = ids == c
        if sel.sum() > 1:
            ax.annotate(f"×{int(sel.sum())}", (float(np.mean(x[sel])), float(np.mean(y[sel]))),
                        textcoords="offset points", xytext=(7, -3), fontsize="small")


# --------------------------------------------------------------------------------------------
# the collapse panel


def _collapse_samples(pts: CalibrationPoints) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                       np.ndarray | None, np.ndarray]:
    """Current (n,), gaps (n, 1 or n_poles), measured and reactions-only force (n,) [N], and
    the run of every sample: the campaign's samples, or else each run's cycle
    i = I_0 + I_1 cos(theta) at its static gap (64 phases) with its F_0."""
    if pts.samples is not None:
        smp = pts.samples
        return smp.current, smp.gaps, smp.force, smp.static_force, smp.run
    theta = 2 * np.pi * np.arange(64) / 64
    current = (pts.dc[:, None] + pts.ac[:, None] * np.cos(theta)).ravel()
    run = np.repeat(np.arange(pts.n_runs), theta.size)
    return current, pts.gap[run][:, None], pts.force_dc[run], None, run


def _draw_collapse(ax: Axes, pts: CalibrationPoints, cal: Calibration, gap_id: np.ndarray,
                   ac_id: np.ndarray) -> None:
    """Measured force against the law's argument x: every run on the law's straight line.

    With the campaign's samples, every sample (and its reactions-only force); otherwise each
    run's F_0 against the mean of x over its cycle: at the run's own current and gaps when
    ``law_dc`` is given (law_dc / K), else at the static gap."""
    current, gaps, force, static, run = _collapse_samples(pts)
    gaps = np.broadcast_to(gaps, (current.size, cal.n_poles))
    x = law_argument(cal, current, gaps)
    law = cal.law_object
    if x is None:
        ax.text(0.02, 0.98, f"law '{cal.law}' is not linear in {law.param_names[0]}:\nno "
                "collapse", transform=ax.transAxes, va="top", fontsize="small")
        return
    si = law.param_units[0] == "N m^2/A^2"
    scale, unit = (1e-6, "A²/mm²") if si else (1.0, f"N / ({law.param_units[0]})")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)
        pred = predict(cal, current, gaps)
    order = np.argsort(x)
    half = 2 * running_max(pred.std[order], max(len(x) // 40, 1))
    ax.fill_between(x[order] * scale, pred.total[order] - half, pred.total[order] + half,
                    color="0.5", alpha=0.3, lw=0, label="law ±2σ of the prediction")
    ax.plot(x[order] * scale, pred.total[order], "-", color="k", lw=1.2,
            label=f"law: total force = {law.param_names[0]} x")
    if static is not None and pts.samples is not None:
        ax.plot(x * scale, static, "x", color="0.45", ms=3.5, mew=0.8,
                label=pts.samples.static_label)
    for k in range(pts.n_runs):
        sel = run == k
        xs, ys = (x[sel], force[sel]) if pts.samples is not None else \
            (np.mean(x[sel], keepdims=True), pts.force_dc[k:k + 1])
        if pts.samples is None and pts.law_dc is not None:     # x at the run's own gaps
            xs = pts.law_dc[k:k + 1] / cal.params[0]
        ax.plot(xs * scale, ys, MARKERS[ac_id[k] % len(MARKERS)], mfc="none",
                color=f"C{gap_id[k] % 10}", ms=4 if pts.samples is not None else 7, mew=0.9,
                alpha=0.8, label="measured (reactions and inertia)" if k == 0 else "_nolegend_")
    arg = law.formula.split("=", 1)[1].strip().removeprefix(law.param_names[0]).strip()
    arg = arg.replace("^2", "²").replace("s + s_fe", "s_p + s_fe").replace(" s²", " s_p²")
    ax.set_xlabel(f"law argument x = Σ over the poles p of {arg} [{unit}]")
    ax.set_ylabel("total force [N]")
    what = "samples" if pts.samples is not None else "mean force $F_0$ of every run (x: mean)"
    if pts.samples is None and pts.law_dc is None:
        what += ",\nat the static gap (motion neglected)"
    panel_title(ax, f"Collapse: the {what} against the law's argument")
    ax.legend(loc="upper left", fontsize="small")
